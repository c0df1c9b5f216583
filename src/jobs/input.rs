//! The inputs of a plan and of its tiles: the city's files, their CRS and metric transform.

use std::path::{Path, PathBuf};

use blockwalk_importers::{ImportError, Layer, MetricTransform};

use crate::city::build::BuildError;

use super::*;

/// The footprint and street files of a city argument: a generated city's folder
/// (`buildings.shp`, `streets.shp`) or a footprint file with `streets`.
///
/// # Errors
/// [`JobsError::Unsupported`] for a path that does not exist, without a street layer or for
/// footprints that are not a Shapefile.
pub fn city_files(input: &Path, streets: Option<&Path>) -> Result<(PathBuf, PathBuf), JobsError> {
    for given in std::iter::once(input).chain(streets) {
        if !given.exists() {
            return Err(JobsError::Unsupported {
                file: given.to_path_buf(),
                why: "no such file or folder".into(),
            });
        }
    }
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
    if input.is_dir() && !fp.is_file() {
        return Err(JobsError::Unsupported {
            file: input.to_path_buf(),
            why: "the folder holds no buildings.shp (a generated city's folder has buildings.shp \
                  and streets.shp)"
                .into(),
        });
    }
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

pub(super) fn read_err(file: &Path) -> impl FnOnce(ImportError) -> JobsError + '_ {
    move |e| JobsError::Read {
        file: file.to_path_buf(),
        source: Box::new(e),
    }
}

pub(super) fn empty_like(crs: &blockwalk_importers::Crs, path: &Path) -> Layer {
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

pub(super) fn metric_transform(
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_missing_path_is_named_as_missing_not_as_the_wrong_kind() {
        let dir = tempfile::tempdir().unwrap();
        let gone = dir.path().join("no-such-city");
        let e = city_files(&gone, None).unwrap_err().to_string();
        assert!(
            e.contains("no-such-city") && e.contains("no such file or folder"),
            "{e}"
        );
        assert!(!e.contains("give a .shp"), "{e}");
        let fp = dir.path().join("b.shp");
        std::fs::write(&fp, b"").unwrap();
        let e = city_files(&fp, Some(&dir.path().join("streets.shp")))
            .unwrap_err()
            .to_string();
        assert!(e.contains("streets.shp: no such file or folder"), "{e}");
        let e = city_files(dir.path(), None).unwrap_err().to_string();
        assert!(e.contains("holds no buildings.shp"), "{e}");
        // A file that exists but is not a Shapefile still gets the Shapefile hint.
        let gj = dir.path().join("b.geojson");
        std::fs::write(&gj, b"{}").unwrap();
        let e = city_files(&gj, None).unwrap_err().to_string();
        assert!(e.contains("give a .shp"), "{e}");
    }
}
