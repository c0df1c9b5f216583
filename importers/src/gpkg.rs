//! GeoPackage reader (OGC 12-128r18, SQLite through `rusqlite` with bundled SQLite).
//!
//! - The feature tables are listed from `gpkg_contents` (`data_type = 'features'`) joined with
//!   `gpkg_geometry_columns` (geometry column and `srs_id`). The [`Theme`] picks one:
//!   `Buildings` → a name containing "build", `Streets` → "street" or "road", `Parcels` →
//!   "plot" or "parcel", `Table(name)` → that exact name, `Any` → the first table. No match is an
//!   error that lists the tables there are.
//! - Geometry blobs are decoded by the crate's WKB decoder: the `GP` header (envelope, byte order, empty
//!   flag), then WKB of any of the seven simple-feature types, Z/M dropped.
//! - The CRS comes from `gpkg_spatial_ref_sys`: an `EPSG` organisation code gives
//!   [`Crs::from_epsg`] (with the name from the WKT definition), otherwise the definition is
//!   read with [`Crs::from_wkt`]; srs_id 0 is undefined geographic, −1 undefined Cartesian.
//! - Every other column except the integer primary key becomes an attribute (integer, real,
//!   text; a blob becomes a short text saying its size). [`Feature::fid`] is the primary key.
//! - A row with a null, empty or undecodable geometry, or NaN coordinates, is refused with its
//!   fid and the reason.

use crate::crs::Crs;
use crate::wkb;
use crate::{AttrValue, Attributes, Feature, ImportError, ImportReport, Layer, Theme};
use rusqlite::types::ValueRef;
use rusqlite::{Connection, OpenFlags};
use std::path::Path;

/// A feature table of a GeoPackage.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FeatureTable {
    /// Table name.
    pub name: String,
    /// Geometry column.
    pub geometry_column: String,
    /// Geometry type name declared in `gpkg_geometry_columns`.
    pub geometry_type: String,
    /// Spatial reference system id.
    pub srs_id: i64,
}

fn sql_err(path: &Path, what: &str) -> impl Fn(rusqlite::Error) -> ImportError {
    let file = path.to_path_buf();
    let what = what.to_string();
    move |source| ImportError::Sqlite {
        file: file.clone(),
        what: what.clone(),
        source,
    }
}

fn open(path: &Path) -> Result<Connection, ImportError> {
    match std::fs::metadata(path) {
        Err(source) => {
            return Err(ImportError::Io {
                file: path.to_path_buf(),
                source,
            })
        }
        // SQLite opens an empty file as an empty database.
        Ok(m) if m.len() == 0 => {
            return Err(ImportError::Empty {
                file: path.to_path_buf(),
                what: "a GeoPackage is an SQLite database".into(),
            })
        }
        Ok(_) => {}
    }
    Connection::open_with_flags(
        path,
        OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX,
    )
    .map_err(sql_err(path, "cannot open as SQLite"))
}

/// Lists the feature tables of a GeoPackage, in `gpkg_contents` order.
///
/// # Errors
/// [`ImportError::Format`] when the file is not a SQLite database with GeoPackage tables.
pub fn feature_tables(path: &Path) -> Result<Vec<FeatureTable>, ImportError> {
    let conn = open(path)?;
    list_tables(&conn, path)
}

fn list_tables(conn: &Connection, path: &Path) -> Result<Vec<FeatureTable>, ImportError> {
    let err = sql_err(
        path,
        "not a GeoPackage (gpkg_contents / gpkg_geometry_columns unreadable)",
    );
    let mut st = conn
        .prepare(
            "SELECT c.table_name, g.column_name, g.geometry_type_name, g.srs_id \
             FROM gpkg_contents c JOIN gpkg_geometry_columns g ON g.table_name = c.table_name \
             WHERE lower(c.data_type) = 'features' ORDER BY c.rowid",
        )
        .map_err(&err)?;
    let rows = st
        .query_map([], |r| {
            Ok(FeatureTable {
                name: r.get(0)?,
                geometry_column: r.get(1)?,
                geometry_type: r.get(2)?,
                srs_id: r.get(3)?,
            })
        })
        .map_err(&err)?;
    rows.collect::<Result<Vec<_>, _>>().map_err(&err)
}

/// Picks the table for a theme (see the module documentation).
fn pick<'a>(tables: &'a [FeatureTable], theme: &Theme) -> Option<&'a FeatureTable> {
    let has = |t: &FeatureTable, keys: &[&str]| {
        let n = t.name.to_ascii_lowercase();
        keys.iter().any(|k| n.contains(k))
    };
    match theme {
        Theme::Any => tables.first(),
        Theme::Buildings => tables.iter().find(|t| has(t, &["build"])),
        Theme::Streets => tables.iter().find(|t| has(t, &["street", "road"])),
        Theme::Parcels => tables.iter().find(|t| has(t, &["plot", "parcel"])),
        Theme::Table(name) => tables.iter().find(|t| &t.name == name),
    }
}

fn quote(ident: &str) -> String {
    format!("\"{}\"", ident.replace('"', "\"\""))
}

/// Reads one feature table of a GeoPackage, chosen by `theme`.
///
/// # Errors
/// [`ImportError::Io`] when the file cannot be opened, [`ImportError::Format`] when it is not a
/// GeoPackage or when no table matches the theme (the message lists the feature tables).
pub fn read(path: &Path, theme: &Theme) -> Result<Layer, ImportError> {
    let conn = open(path)?;
    let tables = list_tables(&conn, path)?;
    let Some(table) = pick(&tables, theme) else {
        let names: Vec<&str> = tables.iter().map(|t| t.name.as_str()).collect();
        return Err(ImportError::Format {
            file: path.to_path_buf(),
            message: format!(
                "no feature table matches {theme:?}; feature tables: {}",
                if names.is_empty() {
                    "none".to_string()
                } else {
                    names.join(", ")
                }
            ),
        });
    };
    let mut report = ImportReport::default();
    let crs = table_crs(&conn, path, table.srs_id, &mut report)?;

    // Columns; the integer primary key is the fid.
    let cols_err = sql_err(path, &format!("table {}: columns", table.name));
    let mut st = conn
        .prepare(&format!("PRAGMA table_info({})", quote(&table.name)))
        .map_err(&cols_err)?;
    let cols: Vec<(String, bool)> = st
        .query_map([], |r| {
            Ok((r.get::<_, String>(1)?, r.get::<_, i64>(5)? > 0))
        })
        .map_err(&cols_err)?
        .collect::<Result<_, _>>()
        .map_err(&cols_err)?;
    let pk = cols.iter().find(|c| c.1).map(|c| c.0.clone());
    let attr_cols: Vec<String> = cols
        .iter()
        .filter(|c| !c.1 && c.0 != table.geometry_column)
        .map(|c| c.0.clone())
        .collect();
    let mut select = vec![
        pk.as_deref().map(quote).unwrap_or_else(|| "rowid".into()),
        quote(&table.geometry_column),
    ];
    select.extend(attr_cols.iter().map(|c| quote(c)));
    let sql = format!(
        "SELECT {} FROM {} ORDER BY 1",
        select.join(", "),
        quote(&table.name)
    );
    let rows_err = sql_err(path, &format!("table {}", table.name));
    let mut st = conn.prepare(&sql).map_err(&rows_err)?;
    let mut rows = st.query([]).map_err(&rows_err)?;
    let mut features = Vec::new();
    let mut other_srs = 0usize;
    while let Some(row) = rows.next().map_err(&rows_err)? {
        report.read += 1;
        let fid: i64 = row.get(0).map_err(&rows_err)?;
        let fid = fid.max(0) as u64;
        let geometry = match row.get_ref(1).map_err(&rows_err)? {
            ValueRef::Null => Err("null geometry".to_string()),
            ValueRef::Blob(b) => match wkb::decode_gpkg(b) {
                Ok(g) => {
                    if i64::from(g.srs_id) != table.srs_id {
                        other_srs += 1;
                    }
                    match g.geometry {
                        None => Err("empty geometry".to_string()),
                        Some(g) => wkb::check_finite(&g).map(|_| g),
                    }
                }
                Err(e) => Err(format!("geometry blob cannot be decoded: {e}")),
            },
            _ => Err("geometry column does not hold a blob".to_string()),
        };
        let geometry = match geometry {
            Ok(g) => g,
            Err(reason) => {
                report.refuse(fid, reason);
                continue;
            }
        };
        let mut attributes = Attributes::new();
        for (i, name) in attr_cols.iter().enumerate() {
            let v = match row.get_ref(i + 2).map_err(&rows_err)? {
                ValueRef::Null => AttrValue::Null,
                ValueRef::Integer(n) => AttrValue::Int(n),
                ValueRef::Real(x) => AttrValue::Float(x),
                ValueRef::Text(t) => AttrValue::Text(String::from_utf8_lossy(t).into_owned()),
                ValueRef::Blob(b) => AttrValue::Text(format!("<blob of {} bytes>", b.len())),
            };
            attributes.insert(name.clone(), v);
        }
        features.push(Feature {
            fid,
            geometry,
            attributes,
        });
    }
    report.imported = features.len();
    report.group_refusals();
    if other_srs > 0 {
        report.notes.push(format!(
            "{other_srs} geometries carry an srs_id other than the table's {}; the table's CRS \
             was used",
            table.srs_id
        ));
    }
    Ok(Layer {
        name: table.name.clone(),
        source: path.to_path_buf(),
        crs,
        features,
        report,
    })
}

fn table_crs(
    conn: &Connection,
    path: &Path,
    srs_id: i64,
    report: &mut ImportReport,
) -> Result<Crs, ImportError> {
    let row = conn.query_row(
        "SELECT organization, organization_coordsys_id, definition FROM gpkg_spatial_ref_sys \
         WHERE srs_id = ?1",
        [srs_id],
        |r| {
            Ok((
                r.get::<_, Option<String>>(0)?,
                r.get::<_, Option<i64>>(1)?,
                r.get::<_, Option<String>>(2)?,
            ))
        },
    );
    let (org, code, def) = match row {
        Ok(v) => v,
        Err(rusqlite::Error::QueryReturnedNoRows) => {
            report.notes.push(format!(
                "srs_id {srs_id} is not in gpkg_spatial_ref_sys: CRS unknown, coordinates taken as metres"
            ));
            return Ok(Crs::Unknown);
        }
        Err(e) => return Err(sql_err(path, "gpkg_spatial_ref_sys")(e)),
    };
    let crs_err = |source| ImportError::Crs {
        file: path.to_path_buf(),
        from: format!("gpkg_spatial_ref_sys (srs_id {srs_id})"),
        source,
    };
    let from_def = || def.as_deref().map(Crs::from_wkt);
    let crs = match (org.as_deref(), code) {
        (Some(o), Some(c)) if o.eq_ignore_ascii_case("EPSG") && c > 0 => {
            match u32::try_from(c).map_err(|_| crate::CrsError::UnknownEpsg { code: u32::MAX }) {
                Ok(c) => match (Crs::from_epsg(c), from_def()) {
                    (
                        Ok(Crs::Projected { epsg, proj4, .. }),
                        Some(Ok(Crs::Projected { name, .. })),
                    ) => Crs::Projected { epsg, name, proj4 },
                    (Ok(crs), _) => crs,
                    // A code the registry lacks: the definition may still say what it is.
                    (Err(_), Some(Ok(crs))) => crs,
                    (Err(e), _) => return Err(crs_err(e)),
                },
                Err(e) => return Err(crs_err(e)),
            }
        }
        _ => match (srs_id, from_def()) {
            (_, Some(Ok(crs))) => crs,
            (0, _) => Crs::Geographic { epsg: None },
            (-1, _) => Crs::Unknown,
            (_, Some(Err(e))) => return Err(crs_err(e)),
            (_, None) => Crs::Unknown,
        },
    };
    report.notes.push(format!(
        "CRS from gpkg_spatial_ref_sys (srs_id {srs_id}): {}",
        crs.describe()
    ));
    Ok(crs)
}
