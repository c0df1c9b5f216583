//! Writing a generated city as Shapefiles.

use std::path::{Path, PathBuf};

use super::heights::round_cm;
use super::{GenerateError, GeneratedCity};

/// The EPSG:32633 definition written to the `.prj` files (ESRI WKT).
pub const UTM33N_PRJ: &str = "PROJCS[\"WGS_1984_UTM_Zone_33N\",GEOGCS[\"GCS_WGS_1984\",DATUM[\"D_WGS_1984\",SPHEROID[\"WGS_1984\",6378137.0,298.257223563]],PRIMEM[\"Greenwich\",0.0],UNIT[\"Degree\",0.0174532925199433]],PROJECTION[\"Transverse_Mercator\"],PARAMETER[\"False_Easting\",500000.0],PARAMETER[\"False_Northing\",0.0],PARAMETER[\"Central_Meridian\",15.0],PARAMETER[\"Scale_Factor\",0.9996],PARAMETER[\"Latitude_Of_Origin\",0.0],UNIT[\"Meter\",1.0]]";

/// What [`write_city`] wrote.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct WrittenCity {
    /// Files written.
    pub files: Vec<PathBuf>,
    /// Buildings.
    pub buildings: usize,
    /// Street segments.
    pub streets: usize,
    /// Parcels.
    pub parcels: usize,
    /// Blocks.
    pub blocks: usize,
}

fn io_err(file: &Path) -> impl FnOnce(std::io::Error) -> GenerateError + '_ {
    move |source| GenerateError::Io {
        file: file.to_path_buf(),
        source,
    }
}

fn shp_err(file: &Path) -> impl FnOnce(shapefile::Error) -> GenerateError + '_ {
    move |source| GenerateError::Shapefile {
        file: file.to_path_buf(),
        source,
    }
}

fn write_prj(shp: &Path, files: &mut Vec<PathBuf>) -> Result<(), GenerateError> {
    let prj = shp.with_extension("prj");
    std::fs::write(&prj, UTM33N_PRJ).map_err(io_err(&prj))?;
    let cpg = shp.with_extension("cpg");
    std::fs::write(&cpg, "UTF-8").map_err(io_err(&cpg))?;
    files.extend([
        shp.to_path_buf(),
        shp.with_extension("shx"),
        shp.with_extension("dbf"),
        prj,
        cpg,
    ]);
    Ok(())
}

fn field(name: &str) -> shapefile::dbase::FieldName {
    shapefile::dbase::FieldName::try_from(name).expect("field names here are valid")
}

/// Writes a generated city to `dir` as `buildings.shp` (fields `id`, `height`, `levels`),
/// `streets.shp` (`id`, `width`) and, when it has parcels, `parcels.shp` (`id`), each with a
/// `.prj` (EPSG:32633) and a `.cpg`.
///
/// # Errors
/// [`GenerateError::Io`] or [`GenerateError::Shapefile`] naming the file.
pub fn write_city(city: &GeneratedCity, dir: &Path) -> Result<WrittenCity, GenerateError> {
    use shapefile::dbase::{FieldValue, Record, TableWriterBuilder};
    std::fs::create_dir_all(dir).map_err(io_err(dir))?;
    let mut files = Vec::new();

    let path = dir.join("buildings.shp");
    let table = TableWriterBuilder::new()
        .add_numeric_field(field("id"), 10, 0)
        .add_numeric_field(field("height"), 8, 2)
        .add_numeric_field(field("levels"), 4, 0);
    let mut w = shapefile::Writer::from_path(&path, table).map_err(shp_err(&path))?;
    for (i, b) in city.buildings.iter().enumerate() {
        let shape = shapefile::Polygon::from(b.footprint.clone());
        let mut r = Record::default();
        r.insert("id".into(), FieldValue::Numeric(Some(i as f64)));
        r.insert("height".into(), FieldValue::Numeric(Some(b.height_m)));
        r.insert("levels".into(), FieldValue::Numeric(Some(b.levels as f64)));
        w.write_shape_and_record(&shape, &r)
            .map_err(shp_err(&path))?;
    }
    drop(w);
    write_prj(&path, &mut files)?;

    let path = dir.join("streets.shp");
    let table = TableWriterBuilder::new()
        .add_numeric_field(field("id"), 10, 0)
        .add_numeric_field(field("width"), 6, 2);
    let mut w = shapefile::Writer::from_path(&path, table).map_err(shp_err(&path))?;
    for (i, s) in city.streets.iter().enumerate() {
        let pts: Vec<shapefile::Point> = s
            .line
            .0
            .iter()
            .map(|c| shapefile::Point::new(c.x, c.y))
            .collect();
        let shape = shapefile::Polyline::new(pts);
        let mut r = Record::default();
        r.insert("id".into(), FieldValue::Numeric(Some(i as f64)));
        r.insert(
            "width".into(),
            FieldValue::Numeric(Some(round_cm(s.width_m))),
        );
        w.write_shape_and_record(&shape, &r)
            .map_err(shp_err(&path))?;
    }
    drop(w);
    write_prj(&path, &mut files)?;

    if !city.parcels.is_empty() {
        let path = dir.join("parcels.shp");
        let table = TableWriterBuilder::new().add_numeric_field(field("id"), 10, 0);
        let mut w = shapefile::Writer::from_path(&path, table).map_err(shp_err(&path))?;
        for (i, p) in city.parcels.iter().enumerate() {
            let shape = shapefile::Polygon::from(p.clone());
            let mut r = Record::default();
            r.insert("id".into(), FieldValue::Numeric(Some(i as f64)));
            w.write_shape_and_record(&shape, &r)
                .map_err(shp_err(&path))?;
        }
        drop(w);
        write_prj(&path, &mut files)?;
    }
    Ok(WrittenCity {
        files,
        buildings: city.buildings.len(),
        streets: city.streets.len(),
        parcels: city.parcels.len(),
        blocks: city.blocks,
    })
}
