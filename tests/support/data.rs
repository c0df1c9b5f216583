//! The repository's bundled data and the scenes the tests build from it.

use blockwalk::index::Structure;
use blockwalk::scene::{CitySource, Scene, SceneOptions};
use blockwalk::visibility::CullerOptions;
use std::path::PathBuf;

/// `data/REL` in the repository (Bubeneč and Helsinki are copied there; see `data/README.md`).
pub fn data(rel: &str) -> PathBuf {
    super::repo().join("data").join(rel)
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
