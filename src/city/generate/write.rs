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

fn write_prj(shp: &Path, epsg: u32, files: &mut Vec<PathBuf>) -> Result<(), GenerateError> {
    let prj = shp.with_extension("prj");
    let wkt = match epsg {
        32633 => UTM33N_PRJ,
        code => blockwalk_importers::crs::epsg_wkt(code).ok_or(GenerateError::BadCrs {
            epsg: code,
            why: "no WKT for the .prj files".into(),
        })?,
    };
    std::fs::write(&prj, wkt).map_err(io_err(&prj))?;
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

/// True for the names [`write_city`] writes (`buildings`, `streets`, `parcels` with the
/// `.shp`, `.shx`, `.dbf`, `.prj` and `.cpg` extensions): a folder holding only these may be
/// replaced by a new city.
pub fn is_city_file(name: &std::ffi::OsStr) -> bool {
    let p = Path::new(name);
    let stem = p.file_stem().and_then(|s| s.to_str());
    let ext = p.extension().and_then(|s| s.to_str());
    matches!(stem, Some("buildings" | "streets" | "parcels"))
        && matches!(ext, Some("shp" | "shx" | "dbf" | "prj" | "cpg"))
}

/// One layer as `.shp` + `.shx` + `.dbf`, every write checked (the finishing writes too, which a
/// writer dropped without finishing would leave unchecked).
fn write_layer<S: shapefile::record::EsriShape>(
    path: &Path,
    table: shapefile::dbase::TableWriterBuilder,
    items: impl Iterator<Item = (S, shapefile::dbase::Record)>,
) -> Result<(), GenerateError> {
    use std::io::BufWriter;
    let create = |p: &Path| {
        std::fs::File::create(p)
            .map(BufWriter::new)
            .map_err(|source| GenerateError::Io {
                file: p.to_path_buf(),
                source,
            })
    };
    let shp = create(path)?;
    let shx = create(&path.with_extension("shx"))?;
    let dbf_path = path.with_extension("dbf");
    let dbf = create(&dbf_path)?;
    let mut shapes = shapefile::ShapeWriter::with_shx(shp, shx);
    let mut records = table.build_with_dest(dbf);
    for (shape, record) in items {
        shapes.write_shape(&shape).map_err(shp_err(path))?;
        records
            .write_record(&record)
            .map_err(|e| shp_err(&dbf_path)(e.into()))?;
    }
    shapes.finalize().map_err(shp_err(path))?;
    records
        .finalize()
        .map_err(|e| shp_err(&dbf_path)(e.into()))?;
    Ok(())
}

/// Writes a generated city to `dir` as `buildings.shp` (fields `id`, `height`, `levels`),
/// `streets.shp` (`id`, `width`) and, when it has parcels, `parcels.shp` (`id`), each with a
/// `.prj` (EPSG:32633) and a `.cpg`. The folder is written under a temporary name beside `dir`
/// and swapped in when complete ([`crate::output::StagedDir`]); an existing `dir` is replaced
/// only if it holds nothing but such files.
///
/// # Errors
/// [`GenerateError::Io`], [`GenerateError::Shapefile`] or [`GenerateError::Output`] naming the
/// file or folder.
pub fn write_city(city: &GeneratedCity, dir: &Path) -> Result<WrittenCity, GenerateError> {
    use shapefile::dbase::{FieldValue, Record, TableWriterBuilder};
    let staged = crate::output::StagedDir::create(
        dir,
        "city written by `blockwalk generate`",
        is_city_file,
    )?;
    let stage = staged.path().to_path_buf();
    let mut files = Vec::new();

    let path = stage.join("buildings.shp");
    let table = TableWriterBuilder::new()
        .add_numeric_field(field("id"), 10, 0)
        .add_numeric_field(field("height"), 8, 2)
        .add_numeric_field(field("levels"), 4, 0);
    write_layer(
        &path,
        table,
        city.buildings.iter().enumerate().map(|(i, b)| {
            let mut r = Record::default();
            r.insert("id".into(), FieldValue::Numeric(Some(i as f64)));
            r.insert("height".into(), FieldValue::Numeric(Some(b.height_m)));
            r.insert("levels".into(), FieldValue::Numeric(Some(b.levels as f64)));
            (shapefile::Polygon::from(b.footprint.clone()), r)
        }),
    )?;
    write_prj(&path, city.epsg, &mut files)?;

    let path = stage.join("streets.shp");
    let table = TableWriterBuilder::new()
        .add_numeric_field(field("id"), 10, 0)
        .add_numeric_field(field("width"), 6, 2);
    write_layer(
        &path,
        table,
        city.streets.iter().enumerate().map(|(i, s)| {
            let pts: Vec<shapefile::Point> = s
                .line
                .0
                .iter()
                .map(|c| shapefile::Point::new(c.x, c.y))
                .collect();
            let mut r = Record::default();
            r.insert("id".into(), FieldValue::Numeric(Some(i as f64)));
            r.insert(
                "width".into(),
                FieldValue::Numeric(Some(round_cm(s.width_m))),
            );
            (shapefile::Polyline::new(pts), r)
        }),
    )?;
    write_prj(&path, city.epsg, &mut files)?;

    if !city.parcels.is_empty() {
        let path = stage.join("parcels.shp");
        let table = TableWriterBuilder::new().add_numeric_field(field("id"), 10, 0);
        write_layer(
            &path,
            table,
            city.parcels.iter().enumerate().map(|(i, p)| {
                let mut r = Record::default();
                r.insert("id".into(), FieldValue::Numeric(Some(i as f64)));
                (shapefile::Polygon::from(p.clone()), r)
            }),
        )?;
        write_prj(&path, city.epsg, &mut files)?;
    }
    staged.commit()?;
    let files = files
        .into_iter()
        .map(|f| dir.join(f.strip_prefix(&stage).unwrap_or(&f)))
        .collect();
    Ok(WrittenCity {
        files,
        buildings: city.buildings.len(),
        streets: city.streets.len(),
        parcels: city.parcels.len(),
        blocks: city.blocks,
    })
}
