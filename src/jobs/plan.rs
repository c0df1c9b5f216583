//! Step 1, [`plan`]: the city's blocks from one streaming pass over the footprints, cut into
//! tiles, and `plan.json`.

use crate::city::build::frame::finite_bbox;
use std::path::{Path, PathBuf};

use blockwalk_importers::{read_layer, shp, Theme};
use geo_types::{Coord, LineString, Polygon};
use glam::DVec3;
use serde::{Deserialize, Serialize};

use crate::blocks::assign::{assign, outskirts_groups, DEFAULT_OUTSKIRTS_LINK};
use crate::blocks::{detect_geometry, BlockOptions, BlockSource};
use crate::city::build::frame::median_centre;
use crate::city::build::{build_city_in_frame, BuildOptions};
use crate::city::LocalFrame;

use super::input::{empty_like, metric_transform, read_err};
use super::*;
use crate::geom::Rect;

/// A block of the plan.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PlanBlock {
    /// Its id in the one-job run's [`crate::blocks::BlockLayout`] (faces first, then outskirts groups).
    pub id: u32,
    /// A street face or an outskirts group.
    pub outskirts: bool,
    /// Outline rings (exterior first), metric world coordinates, each vertex `"x y"` exact.
    pub rings: Vec<Vec<[ExactF64; 2]>>,
    /// Buildings assigned to it.
    pub buildings: usize,
    /// Box `[xmin, ymin, xmax, ymax]` of its outline and its buildings' footprints, metres.
    pub bounds: [f64; 4],
    /// Box of its buildings' footprints alone (`None` for a block without buildings).
    pub building_bounds: Option<[f64; 4]>,
    /// An outskirts group's buildings by source id (empty for a face: its buildings are the
    /// ones the assignment rule puts in it).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub members: Vec<String>,
}

impl PlanBlock {
    /// The outline as a polygon.
    pub fn polygon(&self) -> Polygon<f64> {
        let ring = |r: &Vec<[ExactF64; 2]>| {
            LineString::new(
                r.iter()
                    .map(|c| Coord {
                        x: c[0].0,
                        y: c[1].0,
                    })
                    .collect(),
            )
        };
        let mut rings = self.rings.iter();
        let exterior = rings.next().map(ring).unwrap_or(LineString::new(vec![]));
        Polygon::new(exterior, rings.map(ring).collect())
    }
}

/// A tile of the plan: a node of the block quadtree and all the blocks under it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PlanTile {
    /// Index in [`Plan::tiles`] (the `--tile` of `jobs run`, the index of a job array).
    pub id: usize,
    /// The node's linear quadtree key (root 1, child `4k + q`, as the BqR-tree's).
    pub key: u64,
    /// Its blocks' ids, ascending.
    pub blocks: Vec<u32>,
    /// Buildings in its blocks.
    pub buildings: usize,
    /// Box of its blocks' outlines and buildings, metres.
    pub bounds: [f64; 4],
    /// Box its footprints are read from (its buildings' box), metres; `None` when it has none.
    pub read_bounds: Option<[f64; 4]>,
}

/// `plan.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Plan {
    /// [`PLAN_FORMAT`].
    pub format: String,
    /// The plan's id: CRC-32 of the rest of the plan as written (inputs' stamps, options,
    /// frame, blocks, tiles; [`Plan::content_id`]), checked when the plan is read, so an edited
    /// plan is refused rather than merged.
    pub plan_id: String,
    /// The city's name (the footprint layer's).
    pub city: String,
    /// The footprint file.
    pub footprints: FileStamp,
    /// The street file.
    pub streets: FileStamp,
    /// Every file the plan read, the two layers with the files beside them (`.shx`, `.dbf`,
    /// `.prj`, `.cpg`): a tile checks them all before it reads.
    pub inputs: Vec<FileStamp>,
    /// The cut's limit of buildings per tile.
    pub max_buildings: usize,
    /// The footprints' metric transform's centre, in the file's CRS.
    pub transform_centre: [ExactF64; 2],
    /// The local frame's origin (world metres, z = 0): the median of all footprints' box centres.
    pub frame_origin: [ExactF64; 2],
    /// Features read from the footprint file.
    pub features_read: usize,
    /// Buildings (after repair: a multipolygon gives one building per part).
    pub buildings: usize,
    /// Buildings per block source: `faces` and `outskirts`.
    pub outskirts_buildings: usize,
    /// The blocks, by id.
    pub blocks: Vec<PlanBlock>,
    /// The tiles.
    pub tiles: Vec<PlanTile>,
    /// The elevation model every tile puts its buildings on, and how (`None`: flat).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ground: Option<PlanGround>,
}

/// A plan's ground: the DEM (stamped, checked by every tile as the other inputs are) and the
/// base rule, so that every tile gives a building the base the whole city's run gives it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PlanGround {
    /// The DEM.
    pub dem: FileStamp,
    /// The base rule: `min` or `pNN`.
    pub rule: String,
    /// The steep-ground threshold, metres.
    pub steep_m: f64,
    /// Terrain kept around a tile's footprints, metres.
    pub margin_m: f64,
    /// A DEM without CRS is taken in the city's frame.
    pub assume_city_frame: bool,
}

impl PlanGround {
    /// The build options' ground of this plan.
    ///
    /// # Errors
    /// [`JobsError::Format`] for a rule that does not parse.
    pub fn options(&self, plan: &Path) -> Result<crate::city::build::GroundOptions, JobsError> {
        let rule = crate::city::build::ground::parse_rule(&self.rule).map_err(|why| {
            JobsError::Format {
                file: plan.to_path_buf(),
                why,
            }
        })?;
        Ok(crate::city::build::GroundOptions {
            dem: self.dem.path.clone(),
            rule,
            steep_m: self.steep_m,
            margin_m: self.margin_m,
            assume_city_frame: self.assume_city_frame,
        })
    }
}

impl Plan {
    /// Reads `plan.json`.
    ///
    /// # Errors
    /// [`JobsError::Io`], [`JobsError::Json`], [`JobsError::Format`] for a file that is not a
    /// plan of this version.
    pub fn read(path: &Path) -> Result<Self, JobsError> {
        let text = std::fs::read_to_string(path).map_err(|source| JobsError::Io {
            file: path.to_path_buf(),
            source,
        })?;
        let v: serde_json::Value =
            serde_json::from_str(&text).map_err(|source| JobsError::Json {
                file: path.to_path_buf(),
                source,
            })?;
        if v.get("format").and_then(|f| f.as_str()) != Some(PLAN_FORMAT) {
            return Err(JobsError::Format {
                file: path.to_path_buf(),
                why: format!("not a jobs plan (expected \"format\": \"{PLAN_FORMAT}\")"),
            });
        }
        let plan: Plan = serde_json::from_value(v).map_err(|source| JobsError::Json {
            file: path.to_path_buf(),
            source,
        })?;
        plan.check().map_err(|why| JobsError::Format {
            file: path.to_path_buf(),
            why,
        })?;
        let id = plan.content_id();
        if id != plan.plan_id {
            return Err(JobsError::Format {
                file: path.to_path_buf(),
                why: format!(
                    "the plan was changed after it was written (plan_id {} but its content \
                     hashes to {id}); make a new plan with `blockwalk jobs plan`",
                    plan.plan_id
                ),
            });
        }
        Ok(plan)
    }

    /// CRC-32 of the plan's JSON with `plan_id` left empty, 8 hex digits.
    pub fn content_id(&self) -> String {
        let mut p = self.clone();
        p.plan_id.clear();
        let text = serde_json::to_vec(&p).expect("a plan serialises");
        format!("{:08x}", crc32fast::hash(&text))
    }

    /// What the tile jobs and the merge rely on: tile `i` and block `i` have id `i`, every
    /// block a tile names exists, and every coordinate and box is finite.
    fn check(&self) -> Result<(), String> {
        let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
        let exact = |v: &[ExactF64; 2]| v[0].0.is_finite() && v[1].0.is_finite();
        if !exact(&self.transform_centre) || !exact(&self.frame_origin) {
            return Err("transform_centre and frame_origin must be finite".into());
        }
        for (i, b) in self.blocks.iter().enumerate() {
            if b.id as usize != i {
                return Err(format!(
                    "block {i} has id {} (block ids are their positions)",
                    b.id
                ));
            }
            if !b.rings.iter().flatten().all(exact) || !finite(&b.bounds) {
                return Err(format!("block {i} has a coordinate that is not finite"));
            }
            if !b.building_bounds.is_none_or(|bb| finite(&bb)) {
                return Err(format!("block {i} has building_bounds that are not finite"));
            }
        }
        for (i, t) in self.tiles.iter().enumerate() {
            if t.id != i {
                return Err(format!(
                    "tile {i} has id {} (tile ids are their positions)",
                    t.id
                ));
            }
            if let Some(&b) = t.blocks.iter().find(|&&b| b as usize >= self.blocks.len()) {
                return Err(format!(
                    "tile {i} names block {b}, but the plan has {} blocks",
                    self.blocks.len()
                ));
            }
            if !finite(&t.bounds) || !t.read_bounds.is_none_or(|rb| finite(&rb)) {
                return Err(format!("tile {i} has bounds that are not finite"));
            }
        }
        Ok(())
    }

    /// The local frame of the whole city.
    pub fn frame(&self) -> LocalFrame {
        LocalFrame {
            origin: DVec3::new(self.frame_origin[0].0, self.frame_origin[1].0, 0.0),
        }
    }
}

/// Options of [`plan`].
#[derive(Clone, Debug)]
pub struct PlanOptions {
    /// At most this many buildings per tile (a single block with more is a tile of its own).
    pub max_buildings: usize,
    /// Height rules and street exclusions.
    pub build: BuildOptions,
}

impl Default for PlanOptions {
    fn default() -> Self {
        Self {
            max_buildings: 50_000,
            build: BuildOptions::default(),
        }
    }
}

/// Step 1: the plan of a city in tiles (see the module documentation). `progress` hears what is
/// being done.
///
/// # Errors
/// Reading, building and block errors naming their file; [`JobsError::Unsupported`] for a city
/// without buildings.
pub fn plan(
    footprints: &Path,
    streets: &Path,
    opts: &PlanOptions,
    progress: &mut dyn FnMut(&str),
) -> Result<Plan, JobsError> {
    if opts.max_buildings == 0 {
        return Err(JobsError::Unsupported {
            file: footprints.to_path_buf(),
            why: "--max-buildings must be at least 1".into(),
        });
    }
    progress("stamping the inputs");
    let fp_stamp = FileStamp::of(footprints)?;
    let st_stamp = FileStamp::of(streets)?;
    let mut inputs = Vec::new();
    for layer in [footprints, streets] {
        for f in layer_files(layer) {
            inputs.push(FileStamp::of(&f)?);
        }
    }
    let ground = match &opts.build.ground {
        Some(g) => {
            let dem = FileStamp::of(&g.dem)?;
            inputs.push(dem.clone());
            Some(PlanGround {
                dem,
                rule: crate::city::build::ground::rule_name(g.rule),
                steep_m: g.steep_m,
                margin_m: g.margin_m,
                assume_city_frame: g.assume_city_frame,
            })
        }
        None => None,
    };
    // The plan itself assigns footprints in plan view: no ground needed.
    let opts = &PlanOptions {
        build: BuildOptions {
            ground: None,
            ..opts.build.clone()
        },
        ..opts.clone()
    };
    let crs = shp::read_crs(footprints).map_err(read_err(footprints))?;

    // Pass 1: the metric transform's centre, the median of the footprint polygons' box centres
    // in the file's CRS (as `city::build::frame::layer_centre` on the whole layer).
    progress("pass 1: footprint centres");
    let mut centres: Vec<[f64; 2]> = Vec::new();
    let mut name = String::new();
    shp::read_streaming(footprints, &mut |_, _| true, STREAM_CHUNK, &mut |l| {
        name.clone_from(&l.name);
        for f in &l.features {
            let polys: Vec<&Polygon<f64>> = match &f.geometry {
                geo_types::Geometry::Polygon(p) => vec![p],
                geo_types::Geometry::MultiPolygon(m) => m.0.iter().collect(),
                _ => Vec::new(),
            };
            centres.extend(
                polys
                    .into_iter()
                    .filter_map(|p| finite_bbox(p).map(|b| Rect::from(b).centre())),
            );
        }
    })
    .map_err(read_err(footprints))?;
    let tcentre = median_centre(&centres).unwrap_or([0.0, 0.0]);
    drop(centres);
    let transform = metric_transform(&crs, tcentre, footprints)?;

    // Streets and their faces.
    progress("street faces");
    let st_layer = read_layer(streets, &Theme::Streets).map_err(read_err(streets))?;
    let scity = build_city_in_frame(
        &empty_like(&crs, footprints),
        Some(&st_layer),
        None,
        &opts.build,
        transform.clone(),
        LocalFrame {
            origin: DVec3::ZERO,
        },
    )
    .map_err(|source| JobsError::Build {
        file: streets.to_path_buf(),
        source,
    })?;
    drop(st_layer);
    let bopts = BlockOptions::default();
    let lines: Vec<LineString<f64>> = scity
        .streets
        .iter()
        .filter(|s| !(bopts.grade_separation && s.grade_separated))
        .map(|s| s.line.clone())
        .collect();
    drop(scity);
    let faces =
        detect_geometry(BlockSource::Streets, &lines, &[], &[], &bopts).map_err(|source| {
            JobsError::Blocks {
                file: streets.to_path_buf(),
                source,
            }
        })?;
    drop(lines);
    let face_polys: Vec<Polygon<f64>> = faces.blocks.into_iter().map(|b| b.polygon).collect();

    // Pass 2: repair and assign, chunk by chunk.
    progress("pass 2: footprints to blocks");
    let mut counts = vec![0usize; face_polys.len()];
    let mut bboxes: Vec<Option<[f64; 4]>> = vec![None; face_polys.len()];
    let mut origin_centres: Vec<[f64; 2]> = Vec::new();
    let mut outskirts: Vec<(String, Polygon<f64>)> = Vec::new();
    let mut features_read = 0usize;
    let mut buildings = 0usize;
    let mut failure: Option<JobsError> = None;
    shp::read_streaming(footprints, &mut |_, _| true, STREAM_CHUNK, &mut |l| {
        if failure.is_some() {
            return;
        }
        features_read += l.report.read;
        let city = match build_city_in_frame(
            &l,
            None,
            None,
            &opts.build,
            transform.clone(),
            LocalFrame {
                origin: DVec3::ZERO,
            },
        ) {
            Ok(c) => c,
            Err(source) => {
                failure = Some(JobsError::Build {
                    file: footprints.to_path_buf(),
                    source,
                });
                return;
            }
        };
        drop(l);
        let polys: Vec<Polygon<f64>> = city.buildings.iter().map(|b| b.footprint.clone()).collect();
        let which = assign(&polys, &face_polys);
        buildings += polys.len();
        for ((b, poly), w) in city.buildings.iter().zip(polys).zip(which) {
            let bb = finite_bbox(&poly);
            if let Some(bb) = bb {
                origin_centres.push(Rect::from(bb).centre());
            }
            match w {
                Some(k) => {
                    counts[k] += 1;
                    if let Some(bb) = bb {
                        bboxes[k] =
                            Some(Rect::grow(bboxes[k].map(Rect::from), bb.into()).to_array());
                    }
                }
                None => outskirts.push((b.source_id.clone(), poly)),
            }
        }
    })
    .map_err(read_err(footprints))?;
    if let Some(e) = failure {
        return Err(e);
    }
    if buildings == 0 {
        return Err(JobsError::Unsupported {
            file: footprints.to_path_buf(),
            why: format!("no usable building footprint ({features_read} features read)"),
        });
    }
    let origin = median_centre(&origin_centres).unwrap_or([0.0, 0.0]);
    drop(origin_centres);

    // Blocks: faces, then the outskirts groups (as `blocks::detect_geometry` numbers them).
    let mut blocks: Vec<PlanBlock> = Vec::with_capacity(face_polys.len());
    let ring = |r: &LineString<f64>| -> Vec<[ExactF64; 2]> {
        r.0.iter().map(|c| [ExactF64(c.x), ExactF64(c.y)]).collect()
    };
    let rings_of = |p: &Polygon<f64>| -> Vec<Vec<[ExactF64; 2]>> {
        std::iter::once(ring(p.exterior()))
            .chain(p.interiors().iter().map(ring))
            .collect()
    };
    for (k, p) in face_polys.iter().enumerate() {
        let outline = finite_bbox(p).unwrap_or([0.0; 4]);
        blocks.push(PlanBlock {
            id: k as u32,
            outskirts: false,
            rings: rings_of(p),
            buildings: counts[k],
            bounds: bboxes[k].map_or(outline, |b| Rect::from(outline).union(b.into()).to_array()),
            building_bounds: bboxes[k],
            members: Vec::new(),
        });
    }
    drop(face_polys);
    let outskirts_buildings = outskirts.len();
    let opolys: Vec<Polygon<f64>> = outskirts.iter().map(|o| o.1.clone()).collect();
    let all: Vec<usize> = (0..opolys.len()).collect();
    for (hull, group) in outskirts_groups(&opolys, &all, DEFAULT_OUTSKIRTS_LINK) {
        let mut bb: Option<[f64; 4]> = None;
        for &i in &group {
            if let Some(b) = finite_bbox(&opolys[i]) {
                bb = Some(Rect::grow(bb.map(Rect::from), b.into()).to_array());
            }
        }
        let outline = finite_bbox(&hull);
        blocks.push(PlanBlock {
            id: blocks.len() as u32,
            outskirts: true,
            rings: rings_of(&hull),
            buildings: group.len(),
            bounds: match (outline, bb) {
                (Some(o), b) => b.map_or(o, |b| Rect::from(o).union(b.into()).to_array()),
                (None, b) => b.unwrap_or([0.0; 4]),
            },
            building_bounds: bb,
            members: group.iter().map(|&i| outskirts[i].0.clone()).collect(),
        });
    }

    progress("cutting the block quadtree");
    let tiles = cut_tiles(&blocks, opts.max_buildings);
    let mut plan = Plan {
        format: PLAN_FORMAT.into(),
        plan_id: String::new(),
        city: name,
        footprints: fp_stamp,
        streets: st_stamp,
        inputs,
        max_buildings: opts.max_buildings,
        transform_centre: [ExactF64(tcentre[0]), ExactF64(tcentre[1])],
        frame_origin: [ExactF64(origin[0]), ExactF64(origin[1])],
        features_read,
        buildings,
        outskirts_buildings,
        blocks,
        tiles,
        ground,
    };
    plan.plan_id = plan.content_id();
    Ok(plan)
}

/// A layer's file and the files read with it: for a Shapefile its `.shx`, `.dbf`, `.prj` and
/// `.cpg` when they exist (either case of extension).
pub fn layer_files(path: &Path) -> Vec<PathBuf> {
    let mut out = vec![path.to_path_buf()];
    let is_shp = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("shp"));
    if is_shp {
        for ext in ["shx", "dbf", "prj", "cpg"] {
            let lower = path.with_extension(ext);
            let upper = path.with_extension(ext.to_ascii_uppercase());
            if lower.is_file() {
                out.push(lower);
            } else if upper.is_file() {
                out.push(upper);
            }
        }
    }
    out
}

/// Writes `plan` as `dir/plan.json` (creating `dir`), returning the path.
///
/// # Errors
/// [`JobsError::Io`], [`JobsError::Json`].
pub fn write_plan(plan: &Plan, dir: &Path) -> Result<PathBuf, JobsError> {
    std::fs::create_dir_all(dir).map_err(|source| JobsError::Io {
        file: dir.to_path_buf(),
        source,
    })?;
    let path = dir.join("plan.json");
    let text = serde_json::to_string(plan).map_err(|source| JobsError::Json {
        file: path.clone(),
        source,
    })?;
    crate::output::write_bytes(&path, text)
        .map(drop)
        .map_err(crate::output::OutputError::into_io)
        .map_err(|source| JobsError::Io {
            file: path.clone(),
            source,
        })?;
    Ok(path)
}
