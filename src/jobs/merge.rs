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
