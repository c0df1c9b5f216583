//! Step 2, [`run_tile`]: one tile of a plan, its `.glb` and its manifest.

use crate::city::build::frame::finite_bbox;
use std::collections::{BTreeMap, HashMap, HashSet};
use std::path::{Path, PathBuf};
use std::time::Instant;

use blockwalk_importers::shp;
use geo_types::Polygon;
use serde::{Deserialize, Serialize};

use crate::blockmap::{build_city_maps, CityMapsOptions};
use crate::blocks::assign::assign;
use crate::blocks::{Block, BlockId, BlockKind, BlockLayout, BlockSource};
use crate::city::build::{build_city_in_frame, BuildOptions};
use crate::city::export::gltf::write_glb_with_terrain;
use crate::city::extrude::try_extrude_city;
use crate::city::{City, Mesh};
use crate::tiles::{build_tileset, TilesetOptions};

use super::input::{empty_like, metric_transform, read_err};
use super::pack::{
    hierarchy_path, write_pack, HierBlock, HierMap, TileHierarchy, HIERARCHY_FORMAT,
};
use super::*;
use crate::geom::Rect;

/// A file a tile wrote.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct TileFile {
    /// Path relative to the plan's folder.
    pub path: String,
    /// Size in bytes.
    pub bytes: u64,
    /// CRC-32, 8 hex digits.
    pub crc32: String,
}

/// A block of a finished tile.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TileBlock {
    /// The block's id (the one-job run's [`BlockId`]).
    pub id: u32,
    /// An outskirts group.
    pub outskirts: bool,
    /// Its buildings' source ids, in file order.
    pub buildings: Vec<String>,
    /// Triangles of its buildings' meshes.
    pub triangles: u64,
}

/// A tile's manifest, `tiles/tile_NNNNN.json`, written when the tile has finished.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TileManifest {
    /// [`TILE_FORMAT`].
    pub format: String,
    /// The plan's id.
    pub plan_id: String,
    /// The tile.
    pub tile: usize,
    /// Its quadtree key.
    pub key: u64,
    /// Its box, metres.
    pub bounds: [f64; 4],
    /// Footprint features read (those whose box meets the tile's).
    pub features_read: usize,
    /// Buildings read and built (some belong to neighbouring tiles).
    pub buildings_read: usize,
    /// Buildings of this tile.
    pub buildings: usize,
    /// Triangles of this tile.
    pub triangles: u64,
    /// Buildings whose extrusion failed (empty meshes), by source id.
    pub extrusion_failures: Vec<String>,
    /// Its blocks.
    pub blocks: Vec<TileBlock>,
    /// Its files (the `.glb` and the BlockMaps; none for a tile without buildings).
    pub files: Vec<TileFile>,
    /// The BlockMaps' figures (maps, K, bytes, measured ε, thin features, seconds), when built.
    #[serde(default)]
    pub blockmaps: Option<serde_json::Value>,
    /// The tile's 3D Tiles tileset, when built: what `merge` needs to reference it from the
    /// root `tileset.json`.
    #[serde(default)]
    pub tileset: Option<TileTileset>,
    /// Seconds the job took.
    pub seconds: f64,
    /// Peak resident memory of the job's process, bytes (`VmHWM`), where the system tells.
    pub peak_rss_bytes: Option<u64>,
}

/// A tile's own 3D Tiles tileset (`tiles/tile_NNNNN_tileset/`), as its manifest records it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TileTileset {
    /// Its `tileset.json`, relative to the plan's folder.
    pub path: String,
    /// The tileset's top-level geometric error, metres.
    pub geometric_error: f64,
    /// Its root's box in the local frame (the whole city's: every tile shares it), metres:
    /// `[min x, min y, min z, max x, max y, max z]`.
    pub aabb: [f64; 6],
    /// Its root transform (local → ECEF, column-major), or `None` for a city without a
    /// geodetic CRS.
    pub transform: Option<[f64; 16]>,
    /// Tiles in it.
    pub tiles: usize,
    /// Buildings in its leaves.
    pub buildings: usize,
    /// Bytes of its `tileset.json` and contents.
    pub bytes: u64,
    /// Seconds it took.
    pub seconds: f64,
}

/// What a tile job writes beyond its `.glb`, mesh pack and hierarchy.
#[derive(Clone, Debug, Default)]
pub struct TileOptions {
    /// Its BlockMaps, for streaming ([`build_city_maps`] over the tile's blocks, written as
    /// `tiles/tile_NNNNN_maps/node_KEY.png` + `.json`).
    pub maps: Option<CityMapsOptions>,
    /// Its 3D Tiles tileset ([`build_tileset`] over the tile's blocks, written as
    /// `tiles/tile_NNNNN_tileset/`), which [`merge`](super::merge) references from a root
    /// `tileset.json`. A terrain or an archive (`.3tz`) asked for here is refused: a tile's
    /// tileset holds buildings only, in a folder the root can reference.
    pub tileset: Option<TilesetOptions<'static>>,
}

/// The result of [`run_tile`].
#[derive(Debug)]
pub struct TileRun {
    /// What was written to the manifest.
    pub manifest: TileManifest,
    /// The manifest's path.
    pub manifest_path: PathBuf,
    /// The tile's city (its buildings only, in the whole city's frames).
    pub city: City,
    /// The tile's blocks, with ids of the one-job run and buildings indexing `city.buildings`.
    pub layout: BlockLayout,
    /// `meshes[i]` is `city.buildings[i]`'s.
    pub meshes: Vec<Mesh>,
}

/// The folder of a plan's tile outputs.
pub fn tiles_dir(plan_path: &Path) -> PathBuf {
    plan_path.parent().unwrap_or(Path::new(".")).join("tiles")
}

/// A tile's manifest path.
pub fn manifest_path(plan_path: &Path, tile: usize) -> PathBuf {
    tiles_dir(plan_path).join(format!("tile_{tile:05}.json"))
}

/// Before a tile runs: its manifest goes first (the tile is unfinished until the new one is
/// written), then what an earlier run of it left: the temporaries of a killed run (hidden
/// `.tile_NNNNN*` entries) and its BlockMaps folder (rewritten whole when maps are asked for,
/// and stale otherwise). Nothing else in the folder is touched.
fn clear_tile(dir: &Path, tile: usize) -> Result<(), JobsError> {
    let io = |file: &Path| {
        let file = file.to_path_buf();
        move |source| JobsError::Io { file, source }
    };
    let manifest = dir.join(format!("tile_{tile:05}.json"));
    match std::fs::remove_file(&manifest) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => return Err(io(&manifest)(e)),
        _ => {}
    }
    let mine = format!(".tile_{tile:05}");
    for e in std::fs::read_dir(dir).map_err(io(dir))? {
        let e = e.map_err(io(dir))?;
        let name = e.file_name().to_string_lossy().into_owned();
        // `.tile_00001.glb.XXXX.part`, `.tile_00001_maps.new-XXXX`, `.tile_00001_maps.old-XXXX`,
        // `.tile_00001_tileset.new-XXXX`.
        let rest = name.strip_prefix(&mine);
        if !rest.is_some_and(|r| {
            r.starts_with('.') || r.starts_with("_maps.") || r.starts_with("_tileset.")
        }) {
            continue;
        }
        let p = e.path();
        let r = if e.file_type().map_err(io(&p))?.is_dir() {
            std::fs::remove_dir_all(&p)
        } else {
            std::fs::remove_file(&p)
        };
        r.map_err(io(&p))?;
    }
    type Owns = fn(&std::ffi::OsStr) -> bool;
    let owned: [(String, Owns); 2] = [
        (
            format!("tile_{tile:05}_maps"),
            crate::blockmap::is_maps_entry,
        ),
        (
            format!("tile_{tile:05}_tileset"),
            crate::tiles::is_tileset_entry,
        ),
    ];
    for (name, owns) in owned {
        let sub = dir.join(name);
        if sub.is_dir() {
            let only_ours = std::fs::read_dir(&sub)
                .map_err(io(&sub))?
                .all(|e| e.is_ok_and(|e| owns(&e.file_name())));
            if only_ours {
                std::fs::remove_dir_all(&sub).map_err(io(&sub))?;
            }
        }
    }
    Ok(())
}

fn check_stamp(plan_path: &Path, want: &FileStamp) -> Result<(), JobsError> {
    let changed = |why: String| JobsError::InputChanged {
        plan: plan_path.to_path_buf(),
        file: want.path.clone(),
        why,
    };
    let meta =
        std::fs::metadata(&want.path).map_err(|e| changed(format!("cannot be read ({e})")))?;
    if meta.len() != want.bytes {
        return Err(changed(format!(
            "has {} bytes, the plan's had {}",
            meta.len(),
            want.bytes
        )));
    }
    let now = FileStamp::of(&want.path)?;
    if now.crc32 != want.crc32 {
        return Err(changed(format!(
            "has CRC-32 {}, the plan's had {}",
            now.crc32, want.crc32
        )));
    }
    Ok(())
}

/// Step 2: runs tile `tile` of the plan at `plan_path`, writing beside it in `tiles/` (see the
/// module documentation). Deterministic: the same plan and inputs give the same files. With
/// [`TileOptions::maps`], the tile's BlockMaps too, and with [`TileOptions::tileset`] its 3D
/// Tiles tileset. Their quadtree is built over the tile's own blocks, whose box is the region it
/// splits: below the tile its nodes are not the nodes of a quadtree over the whole city, and no
/// map covers more than one tile.
///
/// # Errors
/// [`JobsError::TileOutOfRange`], [`JobsError::InputChanged`] when the footprint file is not
/// the plan's, [`JobsError::TileMismatch`] when the buildings found disagree with the plan's
/// counts, reading, building and export errors naming their file.
pub fn run_tile(plan_path: &Path, tile: usize, opts: &TileOptions) -> Result<TileRun, JobsError> {
    let t0 = Instant::now();
    if let Some(t) = &opts.tileset {
        let why = if t.terrain.is_some() {
            Some("a tile's tileset holds buildings only: give the terrain to `blockwalk tileset` or a DEM to the plan")
        } else if t.archive {
            Some("a tile's tileset is a folder, which the root tileset.json references: a .3tz cannot be referenced from outside it")
        } else {
            None
        };
        if let Some(why) = why {
            return Err(JobsError::Unsupported {
                file: plan_path.to_path_buf(),
                why: why.into(),
            });
        }
    }
    let plan = Plan::read(plan_path)?;
    let Some(pt) = plan.tiles.get(tile) else {
        return Err(JobsError::TileOutOfRange {
            plan: plan_path.to_path_buf(),
            tile,
            tiles: plan.tiles.len(),
        });
    };
    for input in &plan.inputs {
        check_stamp(plan_path, input)?;
    }
    let fp = plan.footprints.path.as_path();
    let crs = shp::read_crs(fp).map_err(read_err(fp))?;
    let centre = [plan.transform_centre[0].0, plan.transform_centre[1].0];
    let transform = metric_transform(&crs, centre, fp)?;
    let frame = plan.frame();

    // Read the footprints whose box (mapped to metres by its corners) meets the tile's box.
    let mut layer = empty_like(&crs, fp);
    if let Some(rb) = pt.read_bounds {
        let r = Rect::from_array([
            rb[0] - READ_MARGIN_M,
            rb[1] - READ_MARGIN_M,
            rb[2] + READ_MARGIN_M,
            rb[3] + READ_MARGIN_M,
        ]);
        let identity = transform.is_identity();
        let mut keep = |_: u64, b: [f64; 4]| {
            if !b.iter().all(|v| v.is_finite()) {
                return false;
            }
            let m = if identity {
                Rect::from(b)
            } else {
                let mut m: Option<Rect> = None;
                for (x, y) in [(b[0], b[1]), (b[2], b[1]), (b[0], b[3]), (b[2], b[3])] {
                    match transform.try_to_metric([x, y]) {
                        Ok(p) => m = Some(Rect::grow(m, Rect::point(p))),
                        Err(_) => return false,
                    }
                }
                match m {
                    Some(m) => m,
                    None => return false,
                }
            };
            m.intersects(&r)
        };
        shp::read_streaming(fp, &mut keep, usize::MAX, &mut |l| {
            layer.report.read += l.report.read;
            layer.report.refused.extend(l.report.refused);
            layer.features.extend(l.features);
        })
        .map_err(read_err(fp))?;
    }
    let features_read = layer.features.len();
    let build = BuildOptions {
        ground: plan
            .ground
            .as_ref()
            .map(|g| g.options(plan_path))
            .transpose()?,
        ..BuildOptions::default()
    };
    let city =
        build_city_in_frame(&layer, None, None, &build, transform, frame).map_err(|source| {
            JobsError::Build {
                file: fp.to_path_buf(),
                source,
            }
        })?;
    drop(layer);

    // Assign with the one-job rule against every face whose box meets the buildings read: any
    // face containing (or bounding) a point of these buildings is among them, so the answer is
    // the one-job run's.
    let polys: Vec<Polygon<f64>> = city.buildings.iter().map(|b| b.footprint.clone()).collect();
    let mut seen: Option<Rect> = None;
    for p in &polys {
        if let Some(b) = finite_bbox(p) {
            seen = Some(Rect::grow(seen, b.into()));
        }
    }
    let mut cand: Vec<u32> = Vec::new();
    let mut cand_polys: Vec<Polygon<f64>> = Vec::new();
    if let Some(seen) = seen {
        for b in plan.blocks.iter().filter(|b| !b.outskirts) {
            let p = b.polygon();
            let outline = finite_bbox(&p);
            if outline.is_some_and(|o| Rect::from(o).intersects(&seen)) {
                cand.push(b.id);
                cand_polys.push(p);
            }
        }
    }
    let which = assign(&polys, &cand_polys);
    drop(polys);
    drop(cand_polys);
    let ours: HashSet<u32> = pt.blocks.iter().copied().collect();
    let mut member_of: HashMap<&str, u32> = HashMap::new();
    for &b in &pt.blocks {
        for m in &plan.blocks[b as usize].members {
            member_of.insert(m.as_str(), b);
        }
    }
    let mut block_of: Vec<Option<u32>> = Vec::with_capacity(city.buildings.len());
    for (b, w) in city.buildings.iter().zip(which) {
        block_of.push(match w {
            Some(k) => Some(cand[k]).filter(|id| ours.contains(id)),
            None => member_of.get(b.source_id.as_str()).copied(),
        });
    }
    let mut city = city;
    let all = std::mem::take(&mut city.buildings);
    let mut by_block: BTreeMap<u32, Vec<crate::city::BuildingId>> =
        pt.blocks.iter().map(|&b| (b, Vec::new())).collect();
    for (b, w) in all.into_iter().zip(&block_of) {
        if let Some(id) = w {
            let mut b = b;
            b.id = crate::city::BuildingId(city.buildings.len() as u32);
            by_block.get_mut(id).expect("a tile block").push(b.id);
            city.buildings.push(b);
        }
    }
    let buildings_read = block_of.len();
    let mpath = manifest_path(plan_path, tile);
    for (&id, list) in &by_block {
        let want = plan.blocks[id as usize].buildings;
        if list.len() != want {
            return Err(JobsError::TileMismatch {
                tile,
                file: fp.to_path_buf(),
                why: format!(
                    "block {id} has {} buildings here, the plan counted {want}",
                    list.len()
                ),
            });
        }
    }
    let layout = BlockLayout {
        blocks: by_block
            .iter()
            .map(|(&id, list)| {
                let pb = &plan.blocks[id as usize];
                Block {
                    id: BlockId(id),
                    kind: if pb.outskirts {
                        BlockKind::Outskirts
                    } else {
                        BlockKind::Block
                    },
                    polygon: pb.polygon(),
                    buildings: list.clone(),
                }
            })
            .collect(),
        source: BlockSource::Streets,
        street_edges: Vec::new(),
        dangles: 0,
    };

    let (meshes, failures) = try_extrude_city(&city);
    let dir = tiles_dir(plan_path);
    std::fs::create_dir_all(&dir).map_err(|source| JobsError::Io {
        file: dir.clone(),
        source,
    })?;
    clear_tile(&dir, tile)?;
    let mut files = Vec::new();
    if !city.buildings.is_empty() {
        let name = format!("tile_{tile:05}.glb");
        let gpath = dir.join(&name);
        // Buildings only: the terrain is the DEM's, not a tile's.
        write_glb_with_terrain(&city, &meshes, None, &gpath)
            .map_err(|source| JobsError::Export { tile, source })?;
        let st = FileStamp::of(&gpath)?;
        files.push(TileFile {
            path: format!("tiles/{name}"),
            bytes: st.bytes,
            crc32: st.crc32,
        });
    }
    // The blocks' meshes, packed for streaming: one record per block, in the tile's order.
    let block_meshes: Vec<Mesh> = layout
        .blocks
        .iter()
        .map(|b| {
            let mut m = Mesh::default();
            for id in &b.buildings {
                m.append(&meshes[id.0 as usize]);
            }
            m
        })
        .collect();
    let pack_name = format!("tile_{tile:05}.pack");
    let ranges = if city.buildings.is_empty() {
        vec![None; layout.blocks.len()]
    } else {
        let ppath = dir.join(&pack_name);
        let r = write_pack(&ppath, &block_meshes)?;
        let st = FileStamp::of(&ppath)?;
        files.push(TileFile {
            path: format!("tiles/{pack_name}"),
            bytes: st.bytes,
            crc32: st.crc32,
        });
        r
    };
    let bounds = crate::index::block_bounds(&city, &layout);
    let mut hierarchy = TileHierarchy {
        format: HIERARCHY_FORMAT.into(),
        plan_id: plan.plan_id.clone(),
        tile,
        pack: (!city.buildings.is_empty()).then(|| format!("tiles/{pack_name}")),
        compression: Some("zlib".into()),
        blocks: layout
            .blocks
            .iter()
            .zip(&bounds)
            .zip(ranges)
            .zip(&block_meshes)
            .map(|(((b, bb), mesh), m)| HierBlock {
                id: b.id.0,
                outskirts: b.kind == BlockKind::Outskirts,
                buildings: b.buildings.len(),
                triangles: m.triangle_count() as u64,
                aabb: bb.aabb,
                sphere: bb.sphere,
                center: bb.center.to_array(),
                mesh,
            })
            .collect(),
        maps: Vec::new(),
    };
    drop(block_meshes);
    let mut blockmaps = None;
    // The map builder and the tileset index blocks by id: give them the tile's blocks numbered
    // 0..n.
    let dense = || BlockLayout {
        blocks: layout
            .blocks
            .iter()
            .enumerate()
            .map(|(i, b)| Block {
                id: BlockId(i as u32),
                ..b.clone()
            })
            .collect(),
        ..layout.clone()
    };
    if let (Some(mo), false) = (&opts.maps, city.buildings.is_empty()) {
        let dense = dense();
        let bounds = crate::index::block_bounds(&city, &dense);
        let cm = build_city_maps(&city, &dense, &bounds, mo, &|_, _| {}).map_err(|e| {
            JobsError::TileMismatch {
                tile,
                file: plan_path.to_path_buf(),
                why: format!("BlockMaps: {e}"),
            }
        })?;
        let mdir = dir.join(format!("tile_{tile:05}_maps"));
        cm.write(&mdir, true).map_err(|e| JobsError::TileMismatch {
            tile,
            file: mdir.clone(),
            why: format!("writing BlockMaps: {e}"),
        })?;
        let mut names: Vec<String> = std::fs::read_dir(&mdir)
            .map_err(|source| JobsError::Io {
                file: mdir.clone(),
                source,
            })?
            .filter_map(|e| e.ok().map(|e| e.file_name().to_string_lossy().into_owned()))
            .collect();
        names.sort();
        for n in names {
            let st = FileStamp::of(&mdir.join(&n))?;
            files.push(TileFile {
                path: format!("tiles/tile_{tile:05}_maps/{n}"),
                bytes: st.bytes,
                crc32: st.crc32,
            });
        }
        for m in &cm.maps.maps {
            let name = format!("node_{:x}.png", m.key);
            let png = files
                .iter()
                .find(|f| f.path == format!("tiles/tile_{tile:05}_maps/{name}"))
                .cloned()
                .ok_or_else(|| JobsError::TileMismatch {
                    tile,
                    file: mdir.join(&name),
                    why: "a map the tree holds was not written".into(),
                })?;
            hierarchy.maps.push(HierMap {
                key: m.key,
                parent: m.parent,
                level: m.level,
                blocks: m
                    .blocks
                    .iter()
                    .map(|d| layout.blocks[d.0 as usize].id.0)
                    .collect(),
                meta: m.map.meta.clone(),
                png,
            });
        }
        let s = cm.summary();
        blockmaps = Some(serde_json::json!({
            "maps": s["maps"],
            "k": s["k"],
            "bytes": s["bytes"],
            "eps_declared_max_m": s["eps_declared_max"],
            "eps_measured_max_m": s["eps_measured_max"],
            "thin_features": s["thin_features"],
            "build_s": s["build_s"],
        }));
    }
    let mut tileset = None;
    if let (Some(to), false) = (&opts.tileset, city.buildings.is_empty()) {
        let dense = dense();
        let bounds = crate::index::block_bounds(&city, &dense);
        let name = format!("tile_{tile:05}_tileset");
        let tdir = dir.join(&name);
        let (set, summary) = build_tileset(&city, &dense, &bounds, &meshes, &tdir, to, &|_, _| {})
            .map_err(|e| JobsError::TileMismatch {
                tile,
                file: tdir.clone(),
                why: format!("3D Tiles: {e}"),
            })?;
        let root = set.tiles[0].aabb;
        let mut listed = Vec::new();
        list_files(&tdir, &mut listed)?;
        listed.sort();
        let mut bytes = 0;
        for p in listed {
            let st = FileStamp::of(&p)?;
            let rel = p.strip_prefix(&dir).unwrap_or(&p);
            bytes += st.bytes;
            files.push(TileFile {
                path: format!(
                    "tiles/{}",
                    rel.components()
                        .map(|c| c.as_os_str().to_string_lossy())
                        .collect::<Vec<_>>()
                        .join("/")
                ),
                bytes: st.bytes,
                crc32: st.crc32,
            });
        }
        tileset = Some(TileTileset {
            path: format!("tiles/{name}/tileset.json"),
            geometric_error: set.geometric_error,
            aabb: [
                root.min.x, root.min.y, root.min.z, root.max.x, root.max.y, root.max.z,
            ],
            transform: set.georef.map(|g| g.ecef_from_local),
            tiles: summary.tiles,
            buildings: summary.buildings,
            bytes,
            seconds: summary.seconds,
        });
    }
    if !city.buildings.is_empty() {
        let hpath = hierarchy_path(plan_path, tile);
        let text = serde_json::to_vec(&hierarchy).map_err(|source| JobsError::Json {
            file: hpath.clone(),
            source,
        })?;
        crate::output::write_bytes(&hpath, text)
            .map(drop)
            .map_err(crate::output::OutputError::into_io)
            .map_err(|source| JobsError::Io {
                file: hpath.clone(),
                source,
            })?;
        let st = FileStamp::of(&hpath)?;
        files.push(TileFile {
            path: format!("tiles/tile_{tile:05}.hier.json"),
            bytes: st.bytes,
            crc32: st.crc32,
        });
    }
    let tri = |b: &crate::city::BuildingId| meshes[b.0 as usize].indices.len() as u64 / 3;
    let blocks: Vec<TileBlock> = layout
        .blocks
        .iter()
        .map(|b| TileBlock {
            id: b.id.0,
            outskirts: b.kind == BlockKind::Outskirts,
            buildings: b
                .buildings
                .iter()
                .map(|i| city.buildings[i.0 as usize].source_id.clone())
                .collect(),
            triangles: b.buildings.iter().map(tri).sum(),
        })
        .collect();
    let manifest = TileManifest {
        format: TILE_FORMAT.into(),
        plan_id: plan.plan_id.clone(),
        tile,
        key: pt.key,
        bounds: pt.bounds,
        features_read,
        buildings_read,
        buildings: city.buildings.len(),
        triangles: blocks.iter().map(|b| b.triangles).sum(),
        extrusion_failures: failures.iter().map(|e| e.to_string()).collect(),
        blocks,
        files,
        blockmaps,
        tileset,
        seconds: t0.elapsed().as_secs_f64(),
        peak_rss_bytes: crate::process::peak_rss_bytes(),
    };
    let text = serde_json::to_string(&manifest).map_err(|source| JobsError::Json {
        file: mpath.clone(),
        source,
    })?;
    // Written under a temporary name and renamed: a manifest that exists is a finished tile.
    crate::output::write_bytes(&mpath, text)
        .map(drop)
        .map_err(crate::output::OutputError::into_io)
        .map_err(|source| JobsError::Io {
            file: mpath.clone(),
            source,
        })?;
    Ok(TileRun {
        manifest,
        manifest_path: mpath,
        city,
        layout,
        meshes,
    })
}

/// Every file under `dir`, depth first.
fn list_files(dir: &Path, out: &mut Vec<PathBuf>) -> Result<(), JobsError> {
    let io = |file: &Path| {
        let file = file.to_path_buf();
        move |source| JobsError::Io { file, source }
    };
    for e in std::fs::read_dir(dir).map_err(io(dir))? {
        let e = e.map_err(io(dir))?;
        let p = e.path();
        if e.file_type().map_err(io(&p))?.is_dir() {
            list_files(&p, out)?;
        } else {
            out.push(p);
        }
    }
    Ok(())
}
