//! A city processed in tiles, each tile a self-contained, deterministic job that any batch engine
//! can run (a Slurm array, Kubernetes indexed jobs, GNU parallel, `xargs -P`): no scheduler here.
//!
//! Three steps, each a function and a `blockwalk jobs` command:
//!
//! 1. [`plan`]: the street graph's faces for the whole city (seed 003 §3), then one streaming
//!    pass over the footprints (read [`STREAM_CHUNK`] at a time, never all at once) that repairs
//!    each footprint and assigns it to its block with the one-job rule
//!    ([`crate::blocks::assign::assign`]), counting buildings and growing each block's box; the
//!    buildings in no face form the outskirts groups, as in [`crate::blocks::detect`]. The blocks
//!    are then cut into tiles along the block quadtree (the BqR-tree's quadrant rule, seed 003
//!    §4: the region of the blocks' boxes and centres split into four equal quadrants, a block
//!    going to the quadrant of its centre) where a node holds at most `max_buildings`
//!    buildings (a single block, or blocks at the depth limit, is never split: a tile can hold
//!    more then). A tile is a set of whole blocks, so no building is ever cut. `plan.json`
//!    holds the blocks (outlines with exact coordinates), the tiles, the metric transform's
//!    centre and the local frame's origin of the whole city, and stamps (size, CRC-32) of the
//!    input files.
//! 2. [`run_tile`]: one tile. It reads only the footprints whose box meets the tile's box
//!    (streaming filter while reading: memory is bounded by the tile), builds them in the whole
//!    city's metric frame and local frame (so its f32 meshes are bit for bit the one-job run's),
//!    assigns them with the same rule against every block whose box meets them (a building
//!    straddling tile bounds is read by both tiles but assigned to exactly one), checks the
//!    counts against the plan, extrudes, writes `tiles/tile_NNNNN.glb` and, last, the manifest
//!    `tiles/tile_NNNNN.json` that says the tile is done.
//! 3. [`merge`]: checks that every tile is done, belongs to this plan and that its files are
//!    intact (size and CRC-32), and writes `index.json`: per tile its id, quadtree key, bounds,
//!    blocks, buildings, triangles and files with their hashes, and the sums.
//!
//! Supported input: a street layer (blocks are street faces) and Shapefile footprints (the
//! streaming reader, [`blockwalk_importers::shp::read_streaming`]); other footprint formats are
//! refused with the reason.

use crate::city::build::frame::finite_bbox;
use std::collections::{BTreeMap, HashMap, HashSet};
use std::io::Read;
use std::path::{Path, PathBuf};
use std::time::Instant;

use blockwalk_importers::{read_layer, shp, ImportError, Layer, MetricTransform, Theme};
use geo_types::{Coord, LineString, Polygon};
use glam::DVec3;
use serde::{Deserialize, Serialize};

use crate::blockmap::{build_city_maps, CityMapsOptions};
use crate::blocks::assign::{assign, outskirts_groups, DEFAULT_OUTSKIRTS_LINK};
use crate::blocks::{
    detect_geometry, Block, BlockError, BlockId, BlockKind, BlockLayout, BlockOptions, BlockSource,
};
use crate::city::build::frame::median_centre;
use crate::city::build::{build_city_in_frame, BuildError, BuildOptions};
use crate::city::export::gltf::write_glb;
use crate::city::export::ExportError;
use crate::city::extrude::try_extrude_city;
use crate::city::{City, LocalFrame, Mesh};

/// The format tag of `plan.json`.
pub const PLAN_FORMAT: &str = "blockwalk-jobs-plan/1";
/// The format tag of a tile's manifest.
pub const TILE_FORMAT: &str = "blockwalk-jobs-tile/1";
/// The format tag of `index.json`.
pub const INDEX_FORMAT: &str = "blockwalk-jobs-index/1";
/// Footprints read, repaired and assigned at a time by [`plan`].
pub const STREAM_CHUNK: usize = 50_000;
/// Depth at which the quadtree cut stops (as the BqR-tree's default `max_depth`).
pub const MAX_DEPTH: u32 = 24;
/// Margin, metres, added around a tile's box when its footprints are read: a footprint's box
/// in the file's CRS is mapped to metres by its corners, which is exact for projected metric
/// CRS and within millimetres for a building-sized box in Web Mercator or lon/lat.
pub const READ_MARGIN_M: f64 = 1.0;

/// Why a job step failed. Every variant names the file (and the tile) it concerns.
#[derive(Debug, thiserror::Error)]
pub enum JobsError {
    /// A file could not be read or written.
    #[error("{file}: {source}")]
    Io {
        /// The file.
        file: PathBuf,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// A JSON file could not be parsed or written.
    #[error("{file}: {source}")]
    Json {
        /// The file.
        file: PathBuf,
        /// The parser's error.
        #[source]
        source: serde_json::Error,
    },
    /// A file is not what it should be (another format, a bad value).
    #[error("{file}: {why}")]
    Format {
        /// The file.
        file: PathBuf,
        /// What is wrong.
        why: String,
    },
    /// An input layer could not be read.
    #[error("reading {file}: {source}")]
    Read {
        /// The layer's file.
        file: PathBuf,
        /// The importer's error.
        #[source]
        source: Box<ImportError>,
    },
    /// A layer could not be built into the city.
    #[error("building {file}: {source}")]
    Build {
        /// The layer's file.
        file: PathBuf,
        /// Why.
        #[source]
        source: BuildError,
    },
    /// Block detection failed.
    #[error("blocks of {file}: {source}")]
    Blocks {
        /// The street file.
        file: PathBuf,
        /// Why.
        #[source]
        source: BlockError,
    },
    /// The input cannot be processed in tiles.
    #[error("{file}: {why}")]
    Unsupported {
        /// The input.
        file: PathBuf,
        /// Why.
        why: String,
    },
    /// A tile index beyond the plan's tiles.
    #[error("{plan}: tile {tile} is out of range: the plan has {tiles} tiles (0..={last})", last = tiles.saturating_sub(1))]
    TileOutOfRange {
        /// The plan.
        plan: PathBuf,
        /// The tile asked for.
        tile: usize,
        /// Tiles in the plan.
        tiles: usize,
    },
    /// An input file is not the one the plan was made from (another city, or changed since).
    #[error("{plan} was made from another city: {file} {why}; make a new plan")]
    InputChanged {
        /// The plan.
        plan: PathBuf,
        /// The input file.
        file: PathBuf,
        /// What differs.
        why: String,
    },
    /// A tile has not finished (its manifest is missing).
    #[error("tile {tile} has not finished: {file} is missing (run `blockwalk jobs run {plan} --tile {tile}`)")]
    MissingTile {
        /// The plan.
        plan: PathBuf,
        /// The tile.
        tile: usize,
        /// The missing manifest.
        file: PathBuf,
    },
    /// A tile's output belongs to another plan.
    #[error("tile {tile}: {file} belongs to another plan (plan id {found}, this plan is {expected}); run the tile again")]
    OtherPlan {
        /// The tile.
        tile: usize,
        /// Its manifest.
        file: PathBuf,
        /// This plan's id.
        expected: String,
        /// The manifest's plan id.
        found: String,
    },
    /// A tile's output disagrees with the plan or its own manifest.
    #[error("tile {tile}: {file}: {why}")]
    TileMismatch {
        /// The tile.
        tile: usize,
        /// The file concerned.
        file: PathBuf,
        /// What disagrees.
        why: String,
    },
    /// The tile's `.glb` could not be written.
    #[error("tile {tile}: {source}")]
    Export {
        /// The tile.
        tile: usize,
        /// Why.
        #[source]
        source: ExportError,
    },
}

/// A number written as text in Rust's shortest round-trip form, read back bit for bit (JSON
/// numbers would go through `serde_json`'s fast float parser, which may be one ulp off).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExactF64(pub f64);

impl Serialize for ExactF64 {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(&format!("{}", self.0))
    }
}

impl<'de> Deserialize<'de> for ExactF64 {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = String::deserialize(d)?;
        s.parse::<f64>()
            .map(ExactF64)
            .map_err(|_| serde::de::Error::custom(format!("{s:?} is not a number")))
    }
}

/// An input file's identity: path, size and CRC-32 of its bytes.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct FileStamp {
    /// The file (absolute when it was given as an existing path).
    pub path: PathBuf,
    /// Size in bytes.
    pub bytes: u64,
    /// CRC-32 of the bytes, 8 hex digits.
    pub crc32: String,
}

impl FileStamp {
    /// The stamp of the file at `path`, read in 1 MiB pieces.
    ///
    /// # Errors
    /// [`JobsError::Io`].
    pub fn of(path: &Path) -> Result<Self, JobsError> {
        let io = |source| JobsError::Io {
            file: path.to_path_buf(),
            source,
        };
        let mut f = std::fs::File::open(path).map_err(io)?;
        let mut h = crc32fast::Hasher::new();
        let mut buf = vec![0u8; 1 << 20];
        let mut bytes = 0u64;
        loop {
            let n = f.read(&mut buf).map_err(io)?;
            if n == 0 {
                break;
            }
            h.update(&buf[..n]);
            bytes += n as u64;
        }
        Ok(FileStamp {
            path: std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf()),
            bytes,
            crc32: format!("{:08x}", h.finalize()),
        })
    }
}

/// A block of the plan.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PlanBlock {
    /// Its id in the one-job run's [`BlockLayout`] (faces first, then outskirts groups).
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
    /// The plan's id: CRC-32 of the inputs' stamps, the options and the tiles.
    pub plan_id: String,
    /// The city's name (the footprint layer's).
    pub city: String,
    /// The footprint file.
    pub footprints: FileStamp,
    /// The street file.
    pub streets: FileStamp,
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
        serde_json::from_value(v).map_err(|source| JobsError::Json {
            file: path.to_path_buf(),
            source,
        })
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

fn union(a: Option<[f64; 4]>, b: [f64; 4]) -> [f64; 4] {
    match a {
        None => b,
        Some(a) => [
            a[0].min(b[0]),
            a[1].min(b[1]),
            a[2].max(b[2]),
            a[3].max(b[3]),
        ],
    }
}

fn meets(a: &[f64; 4], b: &[f64; 4]) -> bool {
    a[0] <= b[2] && b[0] <= a[2] && a[1] <= b[3] && b[1] <= a[3]
}

fn centre_of(b: &[f64; 4]) -> [f64; 2] {
    [(b[0] + b[2]) * 0.5, (b[1] + b[3]) * 0.5]
}

/// The footprint and street files of a city argument: a generated city's folder
/// (`buildings.shp`, `streets.shp`) or a footprint file with `streets`.
///
/// # Errors
/// [`JobsError::Unsupported`] without a street layer or for footprints that are not a Shapefile.
pub fn city_files(input: &Path, streets: Option<&Path>) -> Result<(PathBuf, PathBuf), JobsError> {
    let (fp, st) = if input.is_dir() {
        let s = input.join("streets.shp");
        (
            input.join("buildings.shp"),
            streets
                .map(Path::to_path_buf)
                .or_else(|| s.exists().then_some(s)),
        )
    } else {
        (input.to_path_buf(), streets.map(Path::to_path_buf))
    };
    if !fp.to_string_lossy().to_ascii_lowercase().ends_with(".shp") {
        return Err(JobsError::Unsupported {
            file: fp,
            why: "tiles read their footprints with the streaming Shapefile reader: give a .shp"
                .into(),
        });
    }
    let Some(st) = st else {
        return Err(JobsError::Unsupported {
            file: fp,
            why: "tiles are cut from street blocks: give --streets (or a folder with streets.shp)"
                .into(),
        });
    };
    Ok((fp, st))
}

fn read_err(file: &Path) -> impl FnOnce(ImportError) -> JobsError + '_ {
    move |e| JobsError::Read {
        file: file.to_path_buf(),
        source: Box::new(e),
    }
}

fn empty_like(crs: &blockwalk_importers::Crs, path: &Path) -> Layer {
    Layer {
        name: path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default(),
        source: path.to_path_buf(),
        crs: crs.clone(),
        features: Vec::new(),
        report: Default::default(),
    }
}

fn metric_transform(
    crs: &blockwalk_importers::Crs,
    centre: [f64; 2],
    file: &Path,
) -> Result<MetricTransform, JobsError> {
    crs.try_metric_transform(centre)
        .map_err(|source| JobsError::Build {
            file: file.to_path_buf(),
            source: BuildError::Crs {
                layer: file.display().to_string(),
                source,
            },
        })
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
                    .filter_map(|p| finite_bbox(p).map(|b| centre_of(&b))),
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
                origin_centres.push(centre_of(&bb));
            }
            match w {
                Some(k) => {
                    counts[k] += 1;
                    if let Some(bb) = bb {
                        bboxes[k] = Some(union(bboxes[k], bb));
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
            bounds: bboxes[k].map_or(outline, |b| union(Some(outline), b)),
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
                bb = Some(union(bb, b));
            }
        }
        let outline = finite_bbox(&hull);
        blocks.push(PlanBlock {
            id: blocks.len() as u32,
            outskirts: true,
            rings: rings_of(&hull),
            buildings: group.len(),
            bounds: match (outline, bb) {
                (Some(o), b) => b.map_or(o, |b| union(Some(o), b)),
                (None, b) => b.unwrap_or([0.0; 4]),
            },
            building_bounds: bb,
            members: group.iter().map(|&i| outskirts[i].0.clone()).collect(),
        });
    }

    progress("cutting the block quadtree");
    let tiles = cut_tiles(&blocks, opts.max_buildings);
    let mut h = crc32fast::Hasher::new();
    for part in [
        &fp_stamp.crc32,
        &st_stamp.crc32,
        &opts.max_buildings.to_string(),
        &tiles.len().to_string(),
        &blocks.len().to_string(),
        &buildings.to_string(),
    ] {
        h.update(part.as_bytes());
        h.update(b"/");
    }
    Ok(Plan {
        format: PLAN_FORMAT.into(),
        plan_id: format!("{:08x}", h.finalize()),
        city: name,
        footprints: fp_stamp,
        streets: st_stamp,
        max_buildings: opts.max_buildings,
        transform_centre: [ExactF64(tcentre[0]), ExactF64(tcentre[1])],
        frame_origin: [ExactF64(origin[0]), ExactF64(origin[1])],
        features_read,
        buildings,
        outskirts_buildings,
        blocks,
        tiles,
    })
}

/// Cuts the blocks into tiles along the block quadtree: a node becomes a tile when its blocks
/// hold at most `max_buildings` buildings, when it holds one block, or at [`MAX_DEPTH`].
/// Tiles come in depth-first order, quadrants 0..3 (south-west, south-east, north-west,
/// north-east).
pub fn cut_tiles(blocks: &[PlanBlock], max_buildings: usize) -> Vec<PlanTile> {
    if blocks.is_empty() {
        return Vec::new();
    }
    let centre = |b: &PlanBlock| {
        let r = b.rings.first();
        let mut bb: Option<[f64; 4]> = None;
        for c in r.into_iter().flatten() {
            bb = Some(union(bb, [c[0].0, c[1].0, c[0].0, c[1].0]));
        }
        centre_of(&bb.unwrap_or(b.bounds))
    };
    let centres: Vec<[f64; 2]> = blocks.iter().map(centre).collect();
    let mut region: Option<[f64; 4]> = None;
    for (b, c) in blocks.iter().zip(&centres) {
        region = Some(union(region, b.bounds));
        region = Some(union(region, [c[0], c[1], c[0], c[1]]));
    }
    let mut items: Vec<u32> = (0..blocks.len() as u32).collect();
    let mut tiles = Vec::new();
    let ctx = Cut {
        blocks,
        centres: &centres,
        max_buildings,
    };
    ctx.node(&mut items, region.unwrap_or([0.0; 4]), 1, 0, &mut tiles);
    tiles
}

struct Cut<'a> {
    blocks: &'a [PlanBlock],
    centres: &'a [[f64; 2]],
    max_buildings: usize,
}

impl Cut<'_> {
    fn node(&self, items: &mut [u32], q: [f64; 4], key: u64, depth: u32, out: &mut Vec<PlanTile>) {
        let buildings: usize = items
            .iter()
            .map(|&i| self.blocks[i as usize].buildings)
            .sum();
        if buildings <= self.max_buildings || items.len() <= 1 || depth >= MAX_DEPTH {
            let mut ids: Vec<u32> = items.to_vec();
            ids.sort_unstable();
            let mut bounds: Option<[f64; 4]> = None;
            let mut read: Option<[f64; 4]> = None;
            for &i in &ids {
                let b = &self.blocks[i as usize];
                bounds = Some(union(bounds, b.bounds));
                if let Some(bb) = b.building_bounds {
                    read = Some(union(read, bb));
                }
            }
            out.push(PlanTile {
                id: out.len(),
                key,
                blocks: ids,
                buildings,
                bounds: bounds.unwrap_or([0.0; 4]),
                read_bounds: read,
            });
            return;
        }
        let mid = centre_of(&q);
        let quadrant = |i: &u32| {
            let c = self.centres[*i as usize];
            usize::from(c[0] >= mid[0]) + 2 * usize::from(c[1] >= mid[1])
        };
        items.sort_by_key(|i| (quadrant(i), *i));
        let mut rest: &mut [u32] = items;
        for k in 0..4 {
            let n = rest.iter().take_while(|i| quadrant(i) == k).count();
            let (head, tail) = rest.split_at_mut(n);
            rest = tail;
            if head.is_empty() {
                continue;
            }
            let cq = [
                if k & 1 == 1 { mid[0] } else { q[0] },
                if k & 2 == 2 { mid[1] } else { q[1] },
                if k & 1 == 1 { q[2] } else { mid[0] },
                if k & 2 == 2 { q[3] } else { mid[1] },
            ];
            self.node(head, cq, (key << 2) | k as u64, depth + 1, out);
        }
    }
}

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
    /// Seconds the job took.
    pub seconds: f64,
    /// Peak resident memory of the job's process, bytes (`VmHWM`), where the system tells.
    pub peak_rss_bytes: Option<u64>,
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

fn peak_rss_bytes() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
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
/// `maps`, the tile's BlockMaps too ([`build_city_maps`] over the tile's blocks, written as
/// `tiles/tile_NNNNN_maps/node_KEY.png` + `.json`). Their quadtree is built over the tile's own
/// blocks, whose box is the region it splits: below the tile its nodes are not the nodes of a
/// quadtree over the whole city, and no map covers more than one tile.
///
/// # Errors
/// [`JobsError::TileOutOfRange`], [`JobsError::InputChanged`] when the footprint file is not
/// the plan's, [`JobsError::TileMismatch`] when the buildings found disagree with the plan's
/// counts, reading, building and export errors naming their file.
pub fn run_tile(
    plan_path: &Path,
    tile: usize,
    maps: Option<&CityMapsOptions>,
) -> Result<TileRun, JobsError> {
    let t0 = Instant::now();
    let plan = Plan::read(plan_path)?;
    let Some(pt) = plan.tiles.get(tile) else {
        return Err(JobsError::TileOutOfRange {
            plan: plan_path.to_path_buf(),
            tile,
            tiles: plan.tiles.len(),
        });
    };
    check_stamp(plan_path, &plan.footprints)?;
    let fp = plan.footprints.path.as_path();
    let crs = shp::read_crs(fp).map_err(read_err(fp))?;
    let centre = [plan.transform_centre[0].0, plan.transform_centre[1].0];
    let transform = metric_transform(&crs, centre, fp)?;
    let frame = plan.frame();

    // Read the footprints whose box (mapped to metres by its corners) meets the tile's box.
    let mut layer = empty_like(&crs, fp);
    if let Some(rb) = pt.read_bounds {
        let r = [
            rb[0] - READ_MARGIN_M,
            rb[1] - READ_MARGIN_M,
            rb[2] + READ_MARGIN_M,
            rb[3] + READ_MARGIN_M,
        ];
        let identity = transform.is_identity();
        let mut keep = |_: u64, b: [f64; 4]| {
            if !b.iter().all(|v| v.is_finite()) {
                return false;
            }
            let m = if identity {
                b
            } else {
                let mut m: Option<[f64; 4]> = None;
                for (x, y) in [(b[0], b[1]), (b[2], b[1]), (b[0], b[3]), (b[2], b[3])] {
                    match transform.try_to_metric([x, y]) {
                        Ok(p) => m = Some(union(m, [p[0], p[1], p[0], p[1]])),
                        Err(_) => return false,
                    }
                }
                match m {
                    Some(m) => m,
                    None => return false,
                }
            };
            meets(&m, &r)
        };
        shp::read_streaming(fp, &mut keep, usize::MAX, &mut |l| {
            layer.report.read += l.report.read;
            layer.report.refused.extend(l.report.refused);
            layer.features.extend(l.features);
        })
        .map_err(read_err(fp))?;
    }
    let features_read = layer.features.len();
    let city = build_city_in_frame(
        &layer,
        None,
        None,
        &BuildOptions::default(),
        transform,
        frame,
    )
    .map_err(|source| JobsError::Build {
        file: fp.to_path_buf(),
        source,
    })?;
    drop(layer);

    // Assign with the one-job rule against every face whose box meets the buildings read: any
    // face containing (or bounding) a point of these buildings is among them, so the answer is
    // the one-job run's.
    let polys: Vec<Polygon<f64>> = city.buildings.iter().map(|b| b.footprint.clone()).collect();
    let mut seen: Option<[f64; 4]> = None;
    for p in &polys {
        if let Some(b) = finite_bbox(p) {
            seen = Some(union(seen, b));
        }
    }
    let mut cand: Vec<u32> = Vec::new();
    let mut cand_polys: Vec<Polygon<f64>> = Vec::new();
    if let Some(seen) = seen {
        for b in plan.blocks.iter().filter(|b| !b.outskirts) {
            let p = b.polygon();
            let outline = finite_bbox(&p);
            if outline.is_some_and(|o| meets(&o, &seen)) {
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
    let mut files = Vec::new();
    if !city.buildings.is_empty() {
        let name = format!("tile_{tile:05}.glb");
        let gpath = dir.join(&name);
        write_glb(&city, &meshes, &gpath).map_err(|source| JobsError::Export { tile, source })?;
        let st = FileStamp::of(&gpath)?;
        files.push(TileFile {
            path: format!("tiles/{name}"),
            bytes: st.bytes,
            crc32: st.crc32,
        });
    }
    let mut blockmaps = None;
    if let (Some(mo), false) = (maps, city.buildings.is_empty()) {
        // The map builder indexes blocks by id: give it the tile's blocks numbered 0..n.
        let dense = BlockLayout {
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
        let bounds = crate::index::block_bounds(&city, &dense);
        let cm = build_city_maps(&city, &dense, &bounds, mo, &|_, _| {}).map_err(|e| {
            JobsError::TileMismatch {
                tile,
                file: plan_path.to_path_buf(),
                why: format!("BlockMaps: {e}"),
            }
        })?;
        let mdir = dir.join(format!("tile_{tile:05}_maps"));
        std::fs::create_dir_all(&mdir).map_err(|source| JobsError::Io {
            file: mdir.clone(),
            source,
        })?;
        cm.write(&mdir).map_err(|e| JobsError::TileMismatch {
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
        seconds: t0.elapsed().as_secs_f64(),
        peak_rss_bytes: peak_rss_bytes(),
    };
    let text = serde_json::to_string(&manifest).map_err(|source| JobsError::Json {
        file: mpath.clone(),
        source,
    })?;
    // Written under a temporary name and renamed: a manifest that exists is a finished tile.
    let tmp = mpath.with_extension("json.part");
    std::fs::write(&tmp, text).map_err(|source| JobsError::Io {
        file: tmp.clone(),
        source,
    })?;
    std::fs::rename(&tmp, &mpath).map_err(|source| JobsError::Io {
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
}

/// Step 3: checks every tile of the plan in `dir` (`dir/plan.json`) and writes `dir/index.json`.
///
/// # Errors
/// [`JobsError::MissingTile`] for a tile without a manifest, [`JobsError::OtherPlan`] for a
/// manifest of another plan, [`JobsError::TileMismatch`] for a manifest that disagrees with
/// the plan or a file whose size or CRC-32 is not the manifest's.
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
        });
    }
    if let Some(b) = seen_blocks.iter().position(|s| !s) {
        return Err(JobsError::Format {
            file: plan_path,
            why: format!("block {b} is in no tile"),
        });
    }
    let index = TileIndex {
        format: INDEX_FORMAT.into(),
        plan_id: plan.plan_id.clone(),
        city: plan.city.clone(),
        frame_origin: [plan.frame_origin[0].0, plan.frame_origin[1].0],
        blocks: tiles.iter().map(|t| t.blocks.len()).sum(),
        buildings: tiles.iter().map(|t| t.buildings).sum(),
        triangles: tiles.iter().map(|t| t.triangles).sum(),
        bytes: tiles
            .iter()
            .flat_map(|t| t.files.iter().map(|f| f.bytes))
            .sum(),
        job_seconds: tiles.iter().map(|t| t.seconds).sum(),
        max_peak_rss_bytes: tiles.iter().filter_map(|t| t.peak_rss_bytes).max(),
        tiles,
    };
    let ipath = dir.join("index.json");
    let text = serde_json::to_string_pretty(&index).map_err(|source| JobsError::Json {
        file: ipath.clone(),
        source,
    })?;
    std::fs::write(&ipath, text).map_err(|source| JobsError::Io {
        file: ipath.clone(),
        source,
    })?;
    Ok((index, ipath))
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
    std::fs::write(&path, text).map_err(|source| JobsError::Io {
        file: path.clone(),
        source,
    })?;
    Ok(path)
}
