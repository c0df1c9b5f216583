//! The repository's bundled data, the shared data beside it, and the scenes the tests build from
//! them.

use blockwalk::city::City;
use blockwalk::index::Structure;
use blockwalk::scene::{CitySource, Scene, SceneOptions};
use blockwalk::visibility::CullerOptions;
use std::path::{Path, PathBuf};

/// `data/REL` in the repository (Bubeneč and Helsinki are copied there; see `data/README.md`).
pub fn data(rel: &str) -> PathBuf {
    super::repo().join("data").join(rel)
}

/// `../shared/data/REL` from the repository: the data too big for it (Astana).
pub fn shared_data(rel: &str) -> PathBuf {
    super::repo().join("../shared/data").join(rel)
}

/// The Astana directory: `$BLOCKWALK_ASTANA`, else `../shared/data/astana` from the repository;
/// else what is absent.
pub fn astana_dir() -> Result<PathBuf, String> {
    let (dir, named) = match std::env::var_os("BLOCKWALK_ASTANA") {
        Some(d) => (PathBuf::from(d), "$BLOCKWALK_ASTANA"),
        None => (shared_data("astana"), "../shared/data/astana"),
    };
    if dir.join("streets_blockclass.shp").is_file() {
        Ok(dir)
    } else {
        Err(format!("{named} absent ({})", dir.display()))
    }
}

/// The city of `buildings` (with `streets` when given), loaded with the default options.
pub fn load_city(buildings: &Path, streets: Option<&str>) -> City {
    let source = CitySource::parse(buildings, streets.map(Into::into), None, &[], 0).unwrap();
    source.load(&Default::default(), &mut |_| {}).unwrap().city
}

/// Helsinki (bundled) with the BqR-tree and the occlusion culler.
pub fn helsinki_bqr_occlusion() -> Scene {
    let source = CitySource::parse(
        &data("helsinki/buildings.shp"),
        Some(data("helsinki/streets_blockclass.shp")),
        None,
        &[],
        0,
    )
    .unwrap();
    let opts = SceneOptions {
        structures: vec![Structure::Bqr],
        occlusion: Some(CullerOptions::default()),
        ..SceneOptions::default()
    };
    Scene::load(&source, &opts, &mut |_| {}).unwrap()
}
