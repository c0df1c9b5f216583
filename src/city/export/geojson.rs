//! GeoJSON export of the footprints with their computed heights, in the input's own
//! coordinates (metric world → input through [`MetricTransform::from_metric`]).
//!
//! The input CRS is written as the legacy (2008) `"crs"` member when it has an EPSG code, as GDAL
//! does for projected data; RFC 7946 readers ignore it.
//!
//! [`MetricTransform::from_metric`]: blockwalk_importers::MetricTransform::from_metric

use std::path::Path;

use blockwalk_importers::Crs;
use geo_types::LineString;
use serde_json::{json, Value};

use super::ExportError;
use crate::city::build::source_name;
use crate::city::City;

/// The legacy `"crs"` member for a CRS, when one can be named.
pub fn crs_member(crs: &Crs) -> Option<Value> {
    let name = match crs {
        Crs::Projected { epsg: Some(e), .. } => format!("urn:ogc:def:crs:EPSG::{e}"),
        Crs::WebMercator => "urn:ogc:def:crs:EPSG::3857".to_string(),
        Crs::Geographic { .. } => "urn:ogc:def:crs:OGC:1.3:CRS84".to_string(),
        _ => return None,
    };
    Some(json!({ "type": "name", "properties": { "name": name } }))
}

/// The footprints as a GeoJSON FeatureCollection (one feature per building).
pub fn geojson_value(city: &City) -> Value {
    let t = &city.transform;
    let ring = |l: &LineString<f64>| -> Vec<[f64; 2]> {
        l.0.iter().map(|c| t.from_metric([c.x, c.y])).collect()
    };
    let features: Vec<Value> = city
        .buildings
        .iter()
        .map(|b| {
            let mut rings = vec![ring(b.footprint.exterior())];
            rings.extend(b.footprint.interiors().iter().map(ring));
            json!({
                "type": "Feature",
                "properties": {
                    "source_id": b.source_id,
                    "height_m": b.height_m,
                    "min_height_m": b.min_height_m,
                    "base_m": b.base_m,
                    "height_source": source_name(b.height_source),
                },
                "geometry": { "type": "Polygon", "coordinates": rings },
            })
        })
        .collect();
    let mut v = json!({
        "type": "FeatureCollection",
        "name": city.name,
        "features": features,
    });
    if let Some(c) = crs_member(&t.crs) {
        v["crs"] = c;
    }
    v
}

/// Writes [`geojson_value`] to a file (under a temporary name, renamed when complete).
///
/// # Errors
/// [`ExportError`] naming the file.
pub fn write_geojson(city: &City, path: &Path) -> Result<(), ExportError> {
    let mut w = crate::output::AtomicFile::create(path)?;
    serde_json::to_writer(&mut w, &geojson_value(city)).map_err(|source| ExportError::Json {
        file: path.to_path_buf(),
        source,
    })?;
    w.commit()?;
    Ok(())
}
