//! Where a city comes from: footprint files with optional street and parcel layers, a generated
//! city's folder, or a synthetic grid (`synthetic:COLSxROWS`). The conventions live here, once,
//! for every command and test.

use crate::blocks::{BlockId, BlockLayout};
use crate::city::build::{build_city, BuildError, BuildOptions};
use crate::city::{City, Mesh};
use crate::importers::{read_layer_with_stated_crs, Columns, ImportError, Layer, Theme};
use crate::visibility::synthetic::SyntheticCity;
use glam::DVec2;
use std::path::{Path, PathBuf};

/// The most blocks a synthetic grid may have (1,000,000: about 27 million buildings would not
/// fit in memory anyway).
pub const MAX_SYNTHETIC_BLOCKS: usize = 1_000_000;

/// Where a synthetic grid is placed in world coordinates: far from (0, 0), so that the local
/// frame is exercised (a UTM-like easting and northing).
pub const SYNTHETIC_ORIGIN: DVec2 = DVec2::new(500_000.0, 6_600_000.0);

/// File names a city folder holds, as `blockwalk generate` writes them.
pub mod folder {
    /// Footprints (required).
    pub const BUILDINGS: &str = "buildings.shp";
    /// Street centre lines (optional).
    pub const STREETS: &str = "streets.shp";
    /// Cadastral parcels (optional).
    pub const PARCELS: &str = "parcels.shp";
}

/// Footprint, street and parcel files.
pub type LayerFiles = (PathBuf, Option<PathBuf>, Option<PathBuf>);

/// Footprint, street and parcel layers.
pub type Layers = (Layer, Option<Layer>, Option<Layer>);

/// A city's input.
#[derive(Clone, Debug, PartialEq)]
pub enum CitySource {
    /// Layer files: footprints (`.shp`, `.geojson`, `.gpkg[:table]`, `.osm.pbf`), or a city
    /// folder holding [`folder::BUILDINGS`] (and [`folder::STREETS`], [`folder::PARCELS`] when
    /// present); explicit `streets` / `parcels` replace the folder's.
    Files {
        /// Footprint file or city folder.
        footprints: PathBuf,
        /// Street centre lines.
        streets: Option<PathBuf>,
        /// Cadastral parcels.
        parcels: Option<PathBuf>,
        /// Street features left out when their attribute `k` equals `v`.
        exclude_street_tags: Vec<(String, String)>,
        /// The city's name (`None`: [`crate::city::build::city_name`]).
        name: Option<String>,
        /// The footprint layer's CRS, replacing the file's (`None`: the file's).
        crs: Option<crate::importers::Crs>,
        /// The elevation model the buildings stand on (`None`: flat, z = 0).
        ground: Option<Box<crate::city::build::GroundOptions>>,
    },
    /// A synthetic grid of `cols × rows` blocks of box buildings (see [`SyntheticCity`]).
    Synthetic {
        /// Blocks along x.
        cols: usize,
        /// Blocks along y.
        rows: usize,
        /// Seed of the heights and lots.
        seed: u64,
    },
}

/// Why a city could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum SourceError {
    /// A folder without its footprint file.
    #[error("{}: directory has no {}", folder.display(), folder::BUILDINGS)]
    NoBuildingsInFolder {
        /// The folder.
        folder: PathBuf,
    },
    /// A `synthetic:` spec that does not parse or is out of range.
    #[error("{spec}: {reason}")]
    BadSynthetic {
        /// The spec as given.
        spec: String,
        /// What is wrong.
        reason: &'static str,
    },
    /// A street exclusion that is not `k=v`.
    #[error("street exclusion {0:?}: expected k=v")]
    BadTag(String),
    /// A layer could not be read.
    #[error("reading {}", file.display())]
    Read {
        /// The file.
        file: PathBuf,
        /// What the importer said (boxed: import errors are large).
        #[source]
        source: Box<ImportError>,
    },
    /// The layers did not make a city.
    #[error("building the city from {}", file.display())]
    Build {
        /// The footprint file.
        file: PathBuf,
        /// What went wrong.
        #[source]
        source: BuildError,
    },
}

/// A loaded city: the city, and for a synthetic grid its known blocks and exact meshes.
#[derive(Clone, Debug)]
pub struct LoadedCity {
    /// The city.
    pub city: City,
    /// Blocks that are known without detection (synthetic grids).
    pub layout: Option<BlockLayout>,
    /// Exact per-block meshes that come with the layout (synthetic grids).
    pub meshes: Option<Vec<(BlockId, Mesh)>>,
}

impl CitySource {
    /// A source from one command-line input: `synthetic:COLSxROWS` (with `seed`), a folder, or a
    /// footprint file; `streets`, `parcels` and `k=v` exclusions as given.
    ///
    /// # Errors
    /// [`SourceError::BadSynthetic`] and [`SourceError::BadTag`].
    pub fn parse(
        input: &Path,
        streets: Option<PathBuf>,
        parcels: Option<PathBuf>,
        exclude_tags: &[String],
        seed: u64,
    ) -> Result<Self, SourceError> {
        let text = input.to_string_lossy();
        if let Some(spec) = text.strip_prefix("synthetic:") {
            let bad = |reason| SourceError::BadSynthetic {
                spec: text.to_string(),
                reason,
            };
            let (cols, rows) = spec
                .split_once(['x', 'X'])
                .and_then(|(a, b)| Some((a.trim().parse().ok()?, b.trim().parse().ok()?)))
                .ok_or_else(|| bad("expected synthetic:COLSxROWS, e.g. synthetic:20x20"))?;
            let (cols, rows): (usize, usize) = (cols, rows);
            if cols == 0 || rows == 0 || cols.saturating_mul(rows) > MAX_SYNTHETIC_BLOCKS {
                return Err(bad("between 1 and 1,000,000 blocks"));
            }
            return Ok(CitySource::Synthetic { cols, rows, seed });
        }
        let exclude_street_tags = exclude_tags
            .iter()
            .map(|t| {
                t.split_once('=')
                    .map(|(k, v)| (k.to_string(), v.to_string()))
                    .ok_or_else(|| SourceError::BadTag(t.clone()))
            })
            .collect::<Result<_, _>>()?;
        Ok(CitySource::Files {
            footprints: input.to_path_buf(),
            streets,
            parcels,
            exclude_street_tags,
            name: None,
            crs: None,
            ground: None,
        })
    }

    /// The same source standing on an elevation model (`None` leaves it as it was). A
    /// synthetic grid has no CRS to place a DEM by and stays flat.
    pub fn with_ground(mut self, ground: Option<crate::city::build::GroundOptions>) -> Self {
        if let CitySource::Files { ground: g, .. } = &mut self {
            if let Some(ground) = ground {
                *g = Some(Box::new(ground));
            }
        }
        self
    }

    /// The elevation model of a file source, when it has one.
    pub fn ground(&self) -> Option<&crate::city::build::GroundOptions> {
        match self {
            CitySource::Files { ground, .. } => ground.as_deref(),
            CitySource::Synthetic { .. } => None,
        }
    }

    /// The same source with the city's name and the footprint layer's CRS stated (each `None`
    /// leaves it as it was); a synthetic city keeps its own.
    pub fn with_name_and_crs(
        mut self,
        name: Option<String>,
        crs: Option<crate::importers::Crs>,
    ) -> Self {
        if let CitySource::Files {
            name: n, crs: c, ..
        } = &mut self
        {
            if name.is_some() {
                *n = name;
            }
            if crs.is_some() {
                *c = crs;
            }
        }
        self
    }

    /// The layer files this source reads: footprints, streets, parcels (folder convention
    /// applied).
    ///
    /// # Errors
    /// [`SourceError::NoBuildingsInFolder`].
    pub fn layer_files(&self) -> Result<Option<LayerFiles>, SourceError> {
        let CitySource::Files {
            footprints,
            streets,
            parcels,
            ..
        } = self
        else {
            return Ok(None);
        };
        let (fp, mut st, mut pa) = if footprints.is_dir() {
            let b = footprints.join(folder::BUILDINGS);
            if !b.exists() {
                return Err(SourceError::NoBuildingsInFolder {
                    folder: footprints.clone(),
                });
            }
            let s = footprints.join(folder::STREETS);
            let p = footprints.join(folder::PARCELS);
            (b, s.exists().then_some(s), p.exists().then_some(p))
        } else {
            (footprints.clone(), None, None)
        };
        if streets.is_some() {
            st.clone_from(streets);
        }
        if parcels.is_some() {
            pa.clone_from(parcels);
        }
        Ok(Some((fp, st, pa)))
    }

    /// The same source without a city folder's parcel layer (an explicit parcel file is kept),
    /// for commands that do not use parcels: `import` builds and extrudes the buildings only,
    /// and a folder's parcels (as many polygons as buildings in a generated city) would cost
    /// it as much reading and memory as the footprints.
    ///
    /// # Errors
    /// [`SourceError::NoBuildingsInFolder`].
    pub fn without_folder_parcels(&self) -> Result<Self, SourceError> {
        match (self, self.layer_files()?) {
            (
                CitySource::Files {
                    footprints,
                    parcels,
                    exclude_street_tags,
                    name,
                    crs,
                    ground,
                    ..
                },
                Some((fp, st, _)),
            ) if footprints.is_dir() => Ok(CitySource::Files {
                footprints: fp,
                streets: st,
                parcels: parcels.clone(),
                exclude_street_tags: exclude_street_tags.clone(),
                name: name.clone(),
                crs: crs.clone(),
                ground: ground.clone(),
            }),
            _ => Ok(self.clone()),
        }
    }

    /// Reads the layers (footprints, streets, parcels) of a file source; `None` for a synthetic
    /// one. `progress` hears what is being read.
    ///
    /// # Errors
    /// [`SourceError::NoBuildingsInFolder`], [`SourceError::Read`].
    pub fn read_layers(
        &self,
        progress: &mut dyn FnMut(&str),
    ) -> Result<Option<Layers>, SourceError> {
        self.read_layers_with(&Columns::All, progress)
    }

    /// [`Self::read_layers`] keeping only the footprint attribute `columns` asked for.
    ///
    /// # Errors
    /// As [`Self::read_layers`].
    pub fn read_layers_with(
        &self,
        columns: &Columns,
        progress: &mut dyn FnMut(&str),
    ) -> Result<Option<Layers>, SourceError> {
        let Some((fp, st, pa)) = self.layer_files()? else {
            return Ok(None);
        };
        // A stated CRS replaces the footprints' own (`.prj` included, which is then not read).
        let stated = match self {
            CitySource::Files { crs, .. } => crs.as_ref(),
            _ => None,
        };
        let read = |path: &Path, theme: &Theme| {
            let (columns, stated) = if *theme == Theme::Buildings {
                (columns, stated)
            } else {
                (&Columns::All, None)
            };
            read_layer_with_stated_crs(path, theme, columns, stated).map_err(|source| {
                SourceError::Read {
                    file: path.to_path_buf(),
                    source: Box::new(source),
                }
            })
        };
        for p in std::iter::once(&fp).chain(&st).chain(&pa) {
            progress(&format!("reading {}", p.display()));
        }
        // The layers are read side by side on rayon's pool. Besides the time, this keeps the
        // layers' memory, freed once the city is built, in the pool's allocation arenas, where
        // the extrusion (also on the pool) reuses it.
        let (footprints, (streets, parcels)) = rayon::join(
            || read(&fp, &Theme::Buildings),
            || {
                rayon::join(
                    || st.as_deref().map(|s| read(s, &Theme::Streets)).transpose(),
                    || pa.as_deref().map(|p| read(p, &Theme::Parcels)).transpose(),
                )
            },
        );
        Ok(Some((footprints?, streets?, parcels?)))
    }

    /// Loads the city with `opts` (the source's street exclusions are added to them).
    ///
    /// # Errors
    /// Reading or building errors, with the file they concern.
    pub fn load(
        &self,
        opts: &BuildOptions,
        progress: &mut dyn FnMut(&str),
    ) -> Result<LoadedCity, SourceError> {
        self.load_with_columns(opts, &Columns::All, progress)
    }

    /// [`Self::load`] reading only the footprint attribute `columns` asked for
    /// (`city::build::footprint_columns` gives the buildings and meshes of a full read).
    ///
    /// # Errors
    /// As [`Self::load`].
    pub fn load_with_columns(
        &self,
        opts: &BuildOptions,
        columns: &Columns,
        progress: &mut dyn FnMut(&str),
    ) -> Result<LoadedCity, SourceError> {
        match self {
            CitySource::Synthetic { cols, rows, seed } => {
                progress(&format!("generating a synthetic {cols}x{rows} grid"));
                let s = SyntheticCity::generate(*cols, *rows, *seed, SYNTHETIC_ORIGIN);
                Ok(LoadedCity {
                    city: s.city,
                    layout: Some(s.layout),
                    meshes: Some(s.meshes),
                })
            }
            CitySource::Files {
                exclude_street_tags,
                name,
                crs,
                ground,
                ..
            } => {
                let (f, s, p) = self
                    .read_layers_with(columns, progress)?
                    .expect("a file source has layers");
                let mut opts = opts.clone();
                opts.exclude_street_tags
                    .extend(exclude_street_tags.iter().cloned());
                if name.is_some() {
                    opts.name.clone_from(name);
                }
                if crs.is_some() {
                    opts.crs.clone_from(crs);
                }
                if let Some(g) = ground {
                    opts.ground = Some((**g).clone());
                }
                progress(&format!(
                    "building the city from {} footprints",
                    f.features.len()
                ));
                let city = build_city(&f, s.as_ref(), p.as_ref(), &opts).map_err(|source| {
                    SourceError::Build {
                        file: f.source.clone(),
                        source,
                    }
                })?;
                Ok(LoadedCity {
                    city,
                    layout: None,
                    meshes: None,
                })
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn synthetic_specs_parse_and_refuse() {
        let s = CitySource::parse(Path::new("synthetic:3x4"), None, None, &[], 9).unwrap();
        assert_eq!(
            s,
            CitySource::Synthetic {
                cols: 3,
                rows: 4,
                seed: 9
            }
        );
        for bad in [
            "synthetic:3",
            "synthetic:0x4",
            "synthetic:axb",
            "synthetic:2000x2000",
        ] {
            let e = CitySource::parse(Path::new(bad), None, None, &[], 1).unwrap_err();
            assert!(
                matches!(e, SourceError::BadSynthetic { ref spec, .. } if spec == bad),
                "{bad}: {e}"
            );
        }
    }

    #[test]
    fn tags_must_be_key_value() {
        let e =
            CitySource::parse(Path::new("a.shp"), None, None, &["tunnel".into()], 1).unwrap_err();
        assert!(matches!(e, SourceError::BadTag(ref t) if t == "tunnel"));
        let s = CitySource::parse(Path::new("a.shp"), None, None, &["tunnel=1".into()], 1).unwrap();
        assert!(
            matches!(s, CitySource::Files { ref exclude_street_tags, .. }
            if exclude_street_tags == &[("tunnel".to_string(), "1".to_string())])
        );
    }

    #[test]
    fn a_folder_without_buildings_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let s = CitySource::parse(dir.path(), None, None, &[], 1).unwrap();
        let e = s.layer_files().unwrap_err();
        assert!(
            matches!(e, SourceError::NoBuildingsInFolder { ref folder } if folder == dir.path())
        );
    }
}
