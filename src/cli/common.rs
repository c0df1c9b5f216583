//! Inputs shared by the commands that take a city.

use std::path::PathBuf;

/// A city on the command line: footprints, optional streets and parcels, or a generated city's
/// directory.
#[derive(clap::Args, Debug, Clone)]
pub struct CityArgs {
    /// Footprint file(s) (.shp, .geojson, .gpkg[:table], .osm.pbf) or a generated city directory.
    #[arg(required = true)]
    pub inputs: Vec<PathBuf>,
    /// Street centre lines.
    #[arg(long)]
    pub streets: Option<PathBuf>,
    /// Cadastral parcels.
    #[arg(long)]
    pub parcels: Option<PathBuf>,
    /// Leave out street features with this attribute value (k=v), e.g. `tunnel=1`.
    #[arg(long = "exclude-tag")]
    pub exclude_tag: Vec<String>,
}
