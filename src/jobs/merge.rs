//! Step 3, [`merge`]: every tile checked and `index.json` written.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::*;

/// A tile of `index.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct IndexTile {
    /// Tile id.
    pub id: usize,
    /// Quadtree key.
    pub key: u64,
    /// Box, metres (world frame).
    pub bounds: [f64; 4],
    /// Block ids.
    pub blocks: Vec<u32>,
    /// Buildings.
    pub buildings: usize,
    /// Triangles.
    pub triangles: u64,
    /// Files with their sizes and hashes.
    pub files: Vec<TileFile>,
    /// Seconds the job took.
    pub seconds: f64,
    /// Peak resident memory of the job, bytes.
    pub peak_rss_bytes: Option<u64>,
    /// The tile's own tileset, when its job built one.
    #[serde(default)]
    pub tileset: Option<TileTileset>,
}

/// `index.json`: the index of tiles and the sums.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TileIndex {
    /// [`INDEX_FORMAT`].
    pub format: String,
    /// The plan's id.
    pub plan_id: String,
    /// The city.
    pub city: String,
    /// The local frame's origin (world metres): meshes in the `.glb` files are relative to it.
    pub frame_origin: [f64; 2],
    /// The centre of the whole city's metric transform (input CRS units), for layers read
    /// later into the same frame (e.g. a street layer for a walk).
    #[serde(default)]
    pub transform_centre: Option<[f64; 2]>,
    /// The footprints' CRS, which the metric transform starts from (`None` when the input
    /// could not be read at merge time).
    #[serde(default)]
    pub crs: Option<blockwalk_importers::Crs>,
    /// Tiles.
    pub tiles: Vec<IndexTile>,
    /// Blocks in all tiles.
    pub blocks: usize,
    /// Buildings in all tiles.
    pub buildings: usize,
    /// Triangles in all tiles.
    pub triangles: u64,
    /// Bytes of all tile files.
    pub bytes: u64,
    /// Sum of the jobs' seconds.
    pub job_seconds: f64,
    /// The largest peak resident memory of a job, bytes.
    pub max_peak_rss_bytes: Option<u64>,
    /// The root `tileset.json` referencing every tile's tileset (relative to the plan's
    /// folder), when the tiles have tilesets.
    #[serde(default)]
    pub tileset: Option<String>,
}

/// Step 3: checks every tile of the plan in `dir` (`dir/plan.json`) and writes `dir/index.json`.
///
/// When the tiles' jobs built tilesets, it writes `dir/tileset.json` first: a 3D Tiles 1.1
/// tileset without content of its own whose leaves are the tiles' tilesets (external tilesets,
/// each placed by its own root transform). Its inner tiles follow the plan's quadtree: a tile
/// for every quadtree node above two or more tiles, refined by `ADD`, with a box holding its
/// children's (written in the frame of the transform, ECEF for a georeferenced city) and a
/// geometric error of at least its children's and half its box's diagonal (the rule of
/// [`crate::tiles::build_tileset`]'s top level). A country's thousands of tiles thus stream
/// by region.
///
/// # Errors
/// [`JobsError::MissingTile`] for a tile without a manifest, [`JobsError::OtherPlan`] for a
/// manifest of another plan, [`JobsError::TileMismatch`] for a manifest that disagrees with
/// the plan or a file whose size or CRC-32 is not the manifest's, and for tilesets built by
/// some tiles and not others, or placed by different transforms.
pub fn merge(dir: &Path) -> Result<(TileIndex, PathBuf), JobsError> {
    let plan_path = dir.join("plan.json");
    let plan = Plan::read(&plan_path)?;
    let mut tiles = Vec::with_capacity(plan.tiles.len());
    let mut seen_blocks = vec![false; plan.blocks.len()];
    for pt in &plan.tiles {
        let mpath = manifest_path(&plan_path, pt.id);
        let text = match std::fs::read_to_string(&mpath) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                return Err(JobsError::MissingTile {
                    plan: plan_path.clone(),
                    tile: pt.id,
                    file: mpath,
                })
            }
            Err(source) => {
                return Err(JobsError::Io {
                    file: mpath,
                    source,
                })
            }
        };
        let m: TileManifest = serde_json::from_str(&text).map_err(|source| JobsError::Json {
            file: mpath.clone(),
            source,
        })?;
        if m.plan_id != plan.plan_id {
            return Err(JobsError::OtherPlan {
                tile: pt.id,
                file: mpath,
                expected: plan.plan_id.clone(),
                found: m.plan_id,
            });
        }
        let mismatch = |why: String| JobsError::TileMismatch {
            tile: pt.id,
            file: mpath.clone(),
            why,
        };
        let ids: Vec<u32> = m.blocks.iter().map(|b| b.id).collect();
        if m.tile != pt.id || ids != pt.blocks || m.buildings != pt.buildings {
            return Err(mismatch(format!(
                "manifest of tile {} with {} blocks and {} buildings; the plan's tile has {} blocks and {} buildings",
                m.tile,
                ids.len(),
                m.buildings,
                pt.blocks.len(),
                pt.buildings
            )));
        }
        for &b in &ids {
            if std::mem::replace(&mut seen_blocks[b as usize], true) {
                return Err(mismatch(format!("block {b} is in two tiles")));
            }
        }
        for f in &m.files {
            let path = dir.join(&f.path);
            let st = FileStamp::of(&path).map_err(|_| JobsError::TileMismatch {
                tile: pt.id,
                file: path.clone(),
                why: "listed in the manifest but cannot be read".into(),
            })?;
            if st.bytes != f.bytes || st.crc32 != f.crc32 {
                return Err(JobsError::TileMismatch {
                    tile: pt.id,
                    file: path,
                    why: format!(
                        "{} bytes, CRC-32 {}; the manifest says {} bytes, {}",
                        st.bytes, st.crc32, f.bytes, f.crc32
                    ),
                });
            }
        }
        tiles.push(IndexTile {
            id: pt.id,
            key: pt.key,
            bounds: pt.bounds,
            blocks: ids,
            buildings: m.buildings,
            triangles: m.triangles,
            files: m.files,
            seconds: m.seconds,
            peak_rss_bytes: m.peak_rss_bytes,
            tileset: m.tileset,
        });
    }
    if let Some(b) = seen_blocks.iter().position(|s| !s) {
        return Err(JobsError::Format {
            file: plan_path,
            why: format!("block {b} is in no tile"),
        });
    }
    let tileset = root_tileset(dir, &plan.plan_id, &tiles)?;
    let index = TileIndex {
        format: INDEX_FORMAT.into(),
        plan_id: plan.plan_id.clone(),
        city: plan.city.clone(),
        frame_origin: [plan.frame_origin[0].0, plan.frame_origin[1].0],
        transform_centre: Some([plan.transform_centre[0].0, plan.transform_centre[1].0]),
        crs: blockwalk_importers::shp::read_crs(&plan.footprints.path).ok(),
        blocks: tiles.iter().map(|t| t.blocks.len()).sum(),
        buildings: tiles.iter().map(|t| t.buildings).sum(),
        triangles: tiles.iter().map(|t| t.triangles).sum(),
        bytes: tiles
            .iter()
            .flat_map(|t| t.files.iter().map(|f| f.bytes))
            .sum(),
        job_seconds: tiles.iter().map(|t| t.seconds).sum(),
        max_peak_rss_bytes: tiles.iter().filter_map(|t| t.peak_rss_bytes).max(),
        tileset,
        tiles,
    };
    let ipath = dir.join("index.json");
    let text = serde_json::to_string_pretty(&index).map_err(|source| JobsError::Json {
        file: ipath.clone(),
        source,
    })?;
    crate::output::write_bytes(&ipath, text)
        .map(drop)
        .map_err(crate::output::OutputError::into_io)
        .map_err(|source| JobsError::Io {
            file: ipath.clone(),
            source,
        })?;
    Ok((index, ipath))
}

/// A tile of the root tileset as it is made: its JSON, its box in the local frame and its
/// geometric error.
type Part = (serde_json::Value, crate::geom::Aabb3, f64);

/// A node of the root tileset's tree: a plan tile's tileset, or a quadtree node grouping others.
struct Group {
    /// The plan tile whose key this is, if any.
    tile: Option<usize>,
    /// Child quadtree keys.
    kids: Vec<u64>,
}

/// The root `tileset.json` over the tiles' tilesets (see [`merge`]), or `None` when no tile
/// built one.
fn root_tileset(
    dir: &Path,
    plan_id: &str,
    tiles: &[IndexTile],
) -> Result<Option<String>, JobsError> {
    use crate::geom::Aabb3;
    use glam::{DMat4, DVec3};
    use serde_json::json;
    use std::collections::BTreeMap;

    let with: Vec<&IndexTile> = tiles.iter().filter(|t| t.tileset.is_some()).collect();
    if with.is_empty() {
        return Ok(None);
    }
    let path = dir.join("tileset.json");
    let mismatch = |tile: usize, why: String| JobsError::TileMismatch {
        tile,
        file: path.clone(),
        why,
    };
    // Every tile with buildings built one, or none did.
    if let Some(t) = tiles
        .iter()
        .find(|t| t.tileset.is_none() && t.buildings > 0)
    {
        return Err(mismatch(
            t.id,
            "this tile's job built no tileset while others did: run it again with the same options"
                .into(),
        ));
    }
    let transform = with[0].tileset.as_ref().and_then(|s| s.transform);
    if let Some(t) = with
        .iter()
        .find(|t| t.tileset.as_ref().and_then(|s| s.transform) != transform)
    {
        return Err(mismatch(
            t.id,
            format!(
                "its tileset is placed by another transform than tile {}'s",
                with[0].id
            ),
        ));
    }
    let m = transform.map_or(DMat4::IDENTITY, |t| DMat4::from_cols_array(&t));
    // The quadtree above the tiles: every ancestor key of a tile's key.
    let mut nodes: BTreeMap<u64, Group> = BTreeMap::new();
    for (i, t) in with.iter().enumerate() {
        nodes
            .entry(t.key)
            .or_insert(Group {
                tile: None,
                kids: Vec::new(),
            })
            .tile = Some(i);
        let mut k = t.key;
        while k > 1 {
            let parent = k >> 2;
            let p = nodes.entry(parent).or_insert(Group {
                tile: None,
                kids: Vec::new(),
            });
            if p.kids.contains(&k) {
                break;
            }
            p.kids.push(k);
            k = parent;
        }
    }
    for g in nodes.values_mut() {
        g.kids.sort_unstable();
    }
    let aabb_of = |t: &TileTileset| {
        Aabb3::new(
            DVec3::new(t.aabb[0], t.aabb[1], t.aabb[2]),
            DVec3::new(t.aabb[3], t.aabb[4], t.aabb[5]),
        )
    };
    let box_json = |a: &Aabb3| {
        let c = m.transform_point3(a.center());
        let h = 0.5 * a.extent();
        let [x, y, z] =
            [DVec3::X * h.x, DVec3::Y * h.y, DVec3::Z * h.z].map(|v| m.transform_vector3(v));
        json!([c.x, c.y, c.z, x.x, x.y, x.z, y.x, y.y, y.z, z.x, z.y, z.z])
    };
    // (tile JSON, local box, geometric error) of a node; a group of one child is that child.
    fn emit(
        key: u64,
        nodes: &BTreeMap<u64, Group>,
        with: &[&IndexTile],
        leaf: &dyn Fn(&IndexTile) -> Part,
        group: &dyn Fn(Vec<Part>) -> Part,
    ) -> Part {
        let g = &nodes[&key];
        let mut parts: Vec<Part> = Vec::new();
        if let Some(i) = g.tile {
            parts.push(leaf(with[i]));
        }
        for &k in &g.kids {
            parts.push(emit(k, nodes, with, leaf, group));
        }
        if parts.len() == 1 {
            return parts.pop().expect("one part");
        }
        group(parts)
    }
    let leaf = |t: &IndexTile| {
        let s = t.tileset.as_ref().expect("tiles with a tileset");
        let a = aabb_of(s);
        (
            json!({
                "boundingVolume": { "box": box_json(&a) },
                "geometricError": s.geometric_error,
                "content": { "uri": s.path },
                "extras": { "kind": "job_tile", "tile": t.id, "key": t.key },
            }),
            a,
            s.geometric_error,
        )
    };
    let group = |parts: Vec<Part>| {
        let a = parts.iter().fold(Aabb3::EMPTY, |a, p| a.union(p.1));
        let ge = parts
            .iter()
            .map(|p| p.2)
            .fold(0.5 * a.extent().length(), f64::max);
        (
            json!({
                "boundingVolume": { "box": box_json(&a) },
                "geometricError": ge,
                "refine": "ADD",
                "children": parts.into_iter().map(|p| p.0).collect::<Vec<_>>(),
            }),
            a,
            ge,
        )
    };
    let top = *nodes.keys().next().expect("at least one node");
    // The root of the quadtree is key 1 (or the only tile's key).
    let root_key = if nodes.contains_key(&1) { 1 } else { top };
    let (mut root, _, ge) = emit(root_key, &nodes, &with, &leaf, &group);
    if root.get("refine").is_none() {
        // One tile: a root that adds it.
        root["refine"] = json!("ADD");
    }
    let doc = json!({
        "asset": {
            "version": "1.1",
            "generator": "blockwalk",
            "extras": { "plan_id": plan_id, "tiles": with.len() },
        },
        "geometricError": ge,
        "root": root,
    });
    let text = serde_json::to_vec_pretty(&doc).expect("a JSON value serialises");
    crate::output::write_bytes(&path, text)
        .map(drop)
        .map_err(crate::output::OutputError::into_io)
        .map_err(|source| JobsError::Io {
            file: path.clone(),
            source,
        })?;
    Ok(Some("tileset.json".into()))
}
