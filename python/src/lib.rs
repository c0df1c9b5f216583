//! `blockwalk._blockwalk`: the compiled half of the `blockwalk` Python package. Each function
//! converts what Python hands over (WKB geometry, attribute columns, a CRS as text), makes one
//! library call with the GIL released, and converts the result back (WKB, columns, reports as
//! JSON text). The Python half (`python/blockwalk/__init__.py`) builds the GeoDataFrames.

use blockwalk::blocks::export::{feature_blocks, polygon_to_input, summary};
use blockwalk::blocks::{detect, BlockKind, BlockOptions, BlockSource};
use blockwalk::city::build::layers::street_columns;
use blockwalk::city::build::{
    build_city, build_street_city, footprint_columns, parse_crs, source_fid, BuildOptions,
    HeightFields,
};
use blockwalk::city::City;
use blockwalk::geom::predicates::polygon_area;
use blockwalk::importers::memory::{layer_from_wkb, WkbFeature};
use blockwalk::importers::wkb::encode_wkb;
use blockwalk::importers::{
    read_layer_with_stated_crs, AttrValue, Attributes, Columns, Crs, Layer, Theme,
};
use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyBytes, PyDict, PyFloat, PyInt, PyList, PyString};
use pyo3::IntoPyObjectExt;
use std::path::PathBuf;

create_exception!(
    _blockwalk,
    BlockwalkError,
    PyException,
    "Base class of every error blockwalk raises."
);
create_exception!(
    _blockwalk,
    ReadError,
    BlockwalkError,
    "A file could not be read (missing, unreadable, not in its format, an unusable CRS)."
);
create_exception!(
    _blockwalk,
    InputError,
    BlockwalkError,
    "The data or the options cannot make a city (no usable footprint, a CRS that cannot be set up, an option out of range)."
);
create_exception!(
    _blockwalk,
    BlocksError,
    BlockwalkError,
    "Blocks could not be detected (a forced source without its layer, an option out of range)."
);
create_exception!(
    _blockwalk,
    ExportError,
    BlockwalkError,
    "An output could not be written."
);

/// An error and its sources, one after the other (`what: why: deeper why`).
fn chain(e: &dyn std::error::Error) -> String {
    let mut s = e.to_string();
    let mut src = e.source();
    while let Some(c) = src {
        let t = c.to_string();
        if !s.contains(&t) {
            s.push_str(": ");
            s.push_str(&t);
        }
        src = c.source();
    }
    s
}

/// Which exception an error becomes.
#[derive(Clone, Copy)]
enum Kind {
    Read,
    Input,
    Blocks,
    Export,
}

/// A failure of the work done without the GIL, turned into its exception once the GIL is back.
struct Failure(Kind, String);

impl Failure {
    fn of(kind: Kind, e: &dyn std::error::Error) -> Self {
        Failure(kind, chain(e))
    }
}

impl From<Failure> for PyErr {
    fn from(Failure(kind, msg): Failure) -> PyErr {
        match kind {
            Kind::Read => ReadError::new_err(msg),
            Kind::Input => InputError::new_err(msg),
            Kind::Blocks => BlocksError::new_err(msg),
            Kind::Export => ExportError::new_err(msg),
        }
    }
}

/// Runs `work` with the GIL released; a panic (a bug) comes back as a `BlockwalkError`, never
/// across into Python.
fn without_gil<T: Send>(
    py: Python<'_>,
    work: impl FnOnce() -> Result<T, Failure> + Send,
) -> PyResult<T> {
    let r = py.detach(|| std::panic::catch_unwind(std::panic::AssertUnwindSafe(work)));
    match r {
        Ok(Ok(v)) => Ok(v),
        Ok(Err(f)) => Err(f.into()),
        Err(p) => {
            let msg = p
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_else(|| "unknown panic".into());
            Err(BlockwalkError::new_err(format!(
                "internal error in blockwalk (please report it): {msg}"
            )))
        }
    }
}

/// A layer's data copied out of Python, ready to be decoded without the GIL.
struct LayerData {
    name: String,
    crs: Option<String>,
    wkb: Vec<Option<Vec<u8>>>,
    attributes: Vec<Attributes>,
}

/// One attribute value from Python: None, pandas' missing values (NA, NaT) and float NaN as
/// null; bool; int (beyond 64 bits: its text); float; str; anything else as its `str()`.
fn attr_value(v: &Bound<'_, PyAny>) -> PyResult<AttrValue> {
    Ok(if v.is_none() {
        AttrValue::Null
    } else if v.is_instance_of::<PyBool>() {
        AttrValue::Bool(v.extract()?)
    } else if v.is_instance_of::<PyInt>() {
        match v.extract::<i64>() {
            Ok(i) => AttrValue::Int(i),
            Err(_) => AttrValue::Text(v.str()?.to_string()),
        }
    } else if v.is_instance_of::<PyFloat>() {
        let f: f64 = v.extract()?;
        if f.is_nan() {
            AttrValue::Null
        } else {
            AttrValue::Float(f)
        }
    } else if v.is_instance_of::<PyString>() {
        AttrValue::Text(v.extract()?)
    } else {
        let t = v.get_type().name()?;
        if t == "NAType" || t == "NaTType" {
            AttrValue::Null
        } else {
            AttrValue::Text(v.str()?.to_string())
        }
    })
}

impl LayerData {
    /// `wkb`: a sequence of `bytes` or `None`; `columns`: name → a sequence of values as long
    /// (a pandas Series or a list), of which those `keep` wants are converted. With a projection
    /// ([`Columns::Only`]) null values are left out of the features' attributes (a city reads a missing and a null
    /// attribute alike); with [`Columns::All`] every value is kept, nulls included.
    fn from_py(
        name: String,
        wkb: &Bound<'_, PyAny>,
        columns: &Bound<'_, PyDict>,
        crs: Option<String>,
        keep: &Columns,
    ) -> PyResult<Self> {
        let keep_nulls = matches!(keep, Columns::All);
        let mut geoms = Vec::new();
        for item in wkb.try_iter()? {
            let item = item?;
            geoms.push(if item.is_none() {
                None
            } else {
                Some(item.cast::<PyBytes>()?.as_bytes().to_vec())
            });
        }
        let mut attributes = vec![Attributes::new(); geoms.len()];
        for (k, col) in columns.iter() {
            let key: String = k.extract()?;
            if !keep.wants(&key) {
                continue;
            }
            // A Series (or array) gives Python scalars through `tolist`, not numpy ones.
            let col = if col.hasattr("tolist")? {
                col.call_method0("tolist")?
            } else {
                col
            };
            let mut n = 0usize;
            for (i, v) in col.try_iter()?.enumerate() {
                let Some(row) = attributes.get_mut(i) else {
                    return Err(InputError::new_err(format!(
                        "{name}: column {key:?} is longer than the geometry column ({} rows)",
                        geoms.len()
                    )));
                };
                let v = attr_value(&v?)?;
                if keep_nulls || v != AttrValue::Null {
                    row.insert(key.clone(), v);
                }
                n += 1;
            }
            if n != geoms.len() {
                return Err(InputError::new_err(format!(
                    "{name}: column {key:?} has {n} values for {} geometries",
                    geoms.len()
                )));
            }
        }
        Ok(LayerData {
            name,
            crs,
            wkb: geoms,
            attributes,
        })
    }

    /// The layer (features numbered by row position), its CRS parsed.
    fn into_layer(self) -> Result<Layer, Failure> {
        let crs = match &self.crs {
            Some(text) => parse_crs(text).map_err(|e| {
                Failure(
                    Kind::Input,
                    format!("the GeoDataFrame {}: {}", self.name, chain(&e)),
                )
            })?,
            None => Crs::Unknown,
        };
        let source = format!("the GeoDataFrame {}", self.name);
        let features =
            self.wkb
                .iter()
                .zip(self.attributes)
                .enumerate()
                .map(|(i, (w, attributes))| WkbFeature {
                    fid: i as u64,
                    wkb: w.as_deref(),
                    attributes,
                });
        Ok(layer_from_wkb(&self.name, source, crs, features))
    }
}

/// The CRS as text pyproj reads (`EPSG:n`, a PROJ string), `None` when unknown.
fn crs_text(crs: &Crs) -> Option<String> {
    match crs {
        Crs::Projected { epsg: Some(e), .. } | Crs::Geographic { epsg: Some(e) } => {
            Some(format!("EPSG:{e}"))
        }
        Crs::Projected { proj4, .. } => Some(proj4.clone()),
        Crs::Geographic { epsg: None } => Some("EPSG:4326".into()),
        Crs::WebMercator => Some("EPSG:3857".into()),
        Crs::Unknown => None,
    }
}

fn json_text<T: serde::Serialize>(v: &T) -> String {
    serde_json::to_string(v).unwrap_or_else(|e| format!("{{\"error\": \"{e}\"}}"))
}

/// Values of one attribute column as Python objects.
fn column<'py>(py: Python<'py>, values: &[&AttrValue]) -> PyResult<Bound<'py, PyList>> {
    let items = values
        .iter()
        .map(|v| match v {
            AttrValue::Null => Ok(py.None().into_bound(py)),
            AttrValue::Bool(b) => b.into_bound_py_any(py),
            AttrValue::Int(i) => i.into_bound_py_any(py),
            AttrValue::Float(f) => f.into_bound_py_any(py),
            AttrValue::Text(s) => s.into_bound_py_any(py),
        })
        .collect::<PyResult<Vec<_>>>()?;
    PyList::new(py, items)
}

fn bytes_list<'py>(py: Python<'py>, items: &[Vec<u8>]) -> PyResult<Bound<'py, PyList>> {
    PyList::new(py, items.iter().map(|b| PyBytes::new(py, b)))
}

/// Reads a layer file (Shapefile, GeoJSON, GeoPackage `path[:table]`, OSM PBF) as the importers
/// read it. Returns a dict: `name`, `source`, `crs` (text or None), `fid`, `wkb`, `columns`
/// (name → values, in the order first seen), `report` (JSON text).
#[pyfunction]
#[pyo3(signature = (path, theme="any", crs=None, columns=None))]
fn read<'py>(
    py: Python<'py>,
    path: PathBuf,
    theme: &str,
    crs: Option<String>,
    columns: Option<Vec<String>>,
) -> PyResult<Bound<'py, PyDict>> {
    let theme = match theme {
        "any" => Theme::Any,
        "buildings" => Theme::Buildings,
        "streets" => Theme::Streets,
        "parcels" => Theme::Parcels,
        t => match t.strip_prefix("table:") {
            Some(table) => Theme::Table(table.to_string()),
            None => {
                return Err(InputError::new_err(format!(
                    "theme {t:?}: expected any, buildings, streets, parcels or table:NAME"
                )))
            }
        },
    };
    let columns = columns.map_or(Columns::All, Columns::only);
    let (layer, wkb) = without_gil(py, || {
        let stated = crs
            .as_deref()
            .map(parse_crs)
            .transpose()
            .map_err(|e| Failure(Kind::Input, format!("{}: {}", path.display(), chain(&e))))?;
        let layer = read_layer_with_stated_crs(&path, &theme, &columns, stated.as_ref())
            .map_err(|e| Failure::of(Kind::Read, &e))?;
        let wkb: Vec<Vec<u8>> = layer
            .features
            .iter()
            .map(|f| encode_wkb(&f.geometry))
            .collect();
        Ok((layer, wkb))
    })?;
    let out = PyDict::new(py);
    out.set_item("name", &layer.name)?;
    out.set_item("source", layer.source.display().to_string())?;
    out.set_item("crs", crs_text(&layer.crs))?;
    out.set_item(
        "fid",
        layer.features.iter().map(|f| f.fid).collect::<Vec<_>>(),
    )?;
    out.set_item("wkb", bytes_list(py, &wkb)?)?;
    let mut names: Vec<&String> = Vec::new();
    let mut seen = std::collections::HashSet::new();
    for f in &layer.features {
        for k in f.attributes.keys() {
            if seen.insert(k) {
                names.push(k);
            }
        }
    }
    let cols = PyDict::new(py);
    for name in names {
        let values: Vec<&AttrValue> = layer
            .features
            .iter()
            .map(|f| f.attributes.get(name).unwrap_or(&AttrValue::Null))
            .collect();
        cols.set_item(name, column(py, &values)?)?;
    }
    out.set_item("columns", cols)?;
    out.set_item("report", json_text(&layer.report))?;
    Ok(out)
}

/// A city from the layers handed over, with `opts`.
fn city_of(
    buildings: LayerData,
    streets: Option<LayerData>,
    parcels: Option<LayerData>,
    opts: &BuildOptions,
) -> Result<City, Failure> {
    let b = buildings.into_layer()?;
    let s = streets.map(LayerData::into_layer).transpose()?;
    let p = parcels.map(LayerData::into_layer).transpose()?;
    build_city(&b, s.as_ref(), p.as_ref(), opts).map_err(|e| Failure::of(Kind::Input, &e))
}

/// Street exclusions `k=v` as pairs.
fn tags(exclude: Vec<String>) -> PyResult<Vec<(String, String)>> {
    exclude
        .into_iter()
        .map(|t| {
            t.split_once('=')
                .map(|(k, v)| (k.to_string(), v.to_string()))
                .ok_or_else(|| InputError::new_err(format!("street exclusion {t:?}: expected k=v")))
        })
        .collect()
}

/// A layer as handed over by the Python half: (wkb, columns, crs).
type LayerArgs<'py> = (Bound<'py, PyAny>, Bound<'py, PyDict>, Option<String>);

fn layer_arg(name: &str, a: Option<LayerArgs<'_>>, keep: &Columns) -> PyResult<Option<LayerData>> {
    a.map(|(w, c, crs)| LayerData::from_py(name.to_string(), &w, &c, crs, keep))
        .transpose()
}

/// Blocks of the layers (`city::build` then `blocks::detect`, as `blockwalk blocks`; without
/// buildings the faces of the street layer alone, `city::build::build_street_city`). Returns a
/// dict: `wkb` (block outlines in the input's CRS), `id`, `kind`, `area`, `area_m2`,
/// `n_buildings`, `buildings` (each block's buildings, indices into the city's buildings),
/// `building_fid` (the feature each building came from), `source`, `feature_fid` / `feature_block` (the block of every footprint feature
/// that gave a building), `summary` and `report` (JSON text).
#[pyfunction]
#[pyo3(signature = (buildings=None, streets=None, parcels=None, *, snap, source=None,
                    grade_separated_bridges=false, street_width, outskirts_link,
                    exclude_tags=Vec::new()))]
#[allow(clippy::too_many_arguments)]
fn blocks<'py>(
    py: Python<'py>,
    buildings: Option<LayerArgs<'py>>,
    streets: Option<LayerArgs<'py>>,
    parcels: Option<LayerArgs<'py>>,
    snap: f64,
    source: Option<&str>,
    grade_separated_bridges: bool,
    street_width: f64,
    outskirts_link: f64,
    exclude_tags: Vec<String>,
) -> PyResult<Bound<'py, PyDict>> {
    let force_source = match source {
        None => None,
        Some("streets") => Some(BlockSource::Streets),
        Some("parcels") => Some(BlockSource::Parcels),
        Some("footprints") => Some(BlockSource::Footprints),
        Some(s) => {
            return Err(InputError::new_err(format!(
                "source {s:?}: expected streets, parcels or footprints"
            )))
        }
    };
    let block_opts = BlockOptions {
        snap_tolerance: snap,
        force_source,
        grade_separation: grade_separated_bridges,
        outskirts_link,
        street_width,
    };
    let build_opts = BuildOptions {
        exclude_street_tags: tags(exclude_tags)?,
        name: Some("buildings".into()),
        ..Default::default()
    };
    // Only the attributes the city is built from are converted (the buildings' height and
    // appearance fields, the streets' grade separation and exclusion keys): the same city.
    if buildings.is_none() {
        if streets.is_none() {
            return Err(InputError::new_err(
                "blocks without buildings are the faces of a street layer: give streets",
            ));
        }
        if parcels.is_some() || !matches!(force_source, None | Some(BlockSource::Streets)) {
            return Err(InputError::new_err(
                "blocks without buildings come from the street layer alone: give buildings for blocks from parcels or footprints",
            ));
        }
    }
    let b = layer_arg(
        "buildings",
        buildings,
        &footprint_columns(&build_opts.heights),
    )?;
    let s = layer_arg("streets", streets, &street_columns(&build_opts))?;
    let p = layer_arg("parcels", parcels, &Columns::only::<String>([]))?;
    let r = without_gil(py, move || {
        let city = match b {
            Some(b) => city_of(b, s, p, &build_opts)?,
            // The faces of the street layer alone.
            None => {
                let s = s.expect("checked").into_layer()?;
                build_street_city(&s, &build_opts).map_err(|e| Failure::of(Kind::Input, &e))?
            }
        };
        let layout = detect(&city, &block_opts).map_err(|e| Failure::of(Kind::Blocks, &e))?;
        let t = &city.transform;
        let outlines: Vec<Vec<u8>> = layout
            .blocks
            .iter()
            .map(|b| {
                encode_wkb(&geo_types::Geometry::Polygon(polygon_to_input(
                    t, &b.polygon,
                )))
            })
            .collect();
        let areas: Vec<(f64, f64)> = layout
            .blocks
            .iter()
            .map(|b| {
                (
                    polygon_area(&polygon_to_input(t, &b.polygon)),
                    polygon_area(&b.polygon),
                )
            })
            .collect();
        let per_feature = feature_blocks(&city, &layout);
        let building_fid: Vec<Option<u64>> = city
            .buildings
            .iter()
            .map(|b| source_fid(&b.source_id))
            .collect();
        let summary = json_text(&summary(&layout, t));
        let report = json_text(&city.report);
        Ok((
            layout,
            outlines,
            areas,
            per_feature,
            building_fid,
            summary,
            report,
        ))
    })?;
    let (layout, outlines, areas, per_feature, building_fid, summary, report) = r;
    let out = PyDict::new(py);
    out.set_item("wkb", bytes_list(py, &outlines)?)?;
    out.set_item(
        "id",
        layout.blocks.iter().map(|b| b.id.0).collect::<Vec<_>>(),
    )?;
    out.set_item(
        "kind",
        layout
            .blocks
            .iter()
            .map(|b| match b.kind {
                BlockKind::Block => "block",
                BlockKind::Outskirts => "outskirts",
            })
            .collect::<Vec<_>>(),
    )?;
    out.set_item("area", areas.iter().map(|a| a.0).collect::<Vec<_>>())?;
    out.set_item("area_m2", areas.iter().map(|a| a.1).collect::<Vec<_>>())?;
    out.set_item(
        "n_buildings",
        layout
            .blocks
            .iter()
            .map(|b| b.buildings.len())
            .collect::<Vec<_>>(),
    )?;
    out.set_item(
        "source",
        match layout.source {
            BlockSource::Streets => "streets",
            BlockSource::Parcels => "parcels",
            BlockSource::Footprints => "footprints",
        },
    )?;
    out.set_item(
        "buildings",
        layout
            .blocks
            .iter()
            .map(|b| b.buildings.iter().map(|i| i.0).collect::<Vec<_>>())
            .collect::<Vec<_>>(),
    )?;
    out.set_item("building_fid", building_fid)?;
    out.set_item(
        "feature_fid",
        per_feature.keys().copied().collect::<Vec<_>>(),
    )?;
    out.set_item(
        "feature_block",
        per_feature.values().map(|b| b.0).collect::<Vec<_>>(),
    )?;
    out.set_item("summary", summary)?;
    out.set_item("report", report)?;
    Ok(out)
}

/// Heights: from the column `height_field`, or `height_m` for every building.
fn height_fields(height_field: Option<String>, height_m: Option<f64>) -> HeightFields {
    let mut h = HeightFields::default();
    if let Some(f) = height_field {
        h.height = vec![f];
    }
    if let Some(m) = height_m {
        h.height.clear();
        h.levels.clear();
        h.roof_levels.clear();
        h.default_height_m = m;
    }
    h
}

/// Extrudes the buildings and writes `path`: `.glb` (binary glTF), `.jsonl` (CityJSONSeq), else
/// CityJSON. Returns a dict: `format`, `stats` and `report` (JSON text), `extrude_errors`.
#[pyfunction]
#[pyo3(signature = (buildings, path, *, height_field=None, height_m=None, storey_m=None))]
fn extrude<'py>(
    py: Python<'py>,
    buildings: LayerArgs<'py>,
    path: PathBuf,
    height_field: Option<String>,
    height_m: Option<f64>,
    storey_m: Option<f64>,
) -> PyResult<Bound<'py, PyDict>> {
    use blockwalk::city::export::cityjson::{is_cityjson_seq, write_cityjson, write_cityjson_seq};
    use blockwalk::city::export::write_glb;
    let mut heights = height_fields(height_field, height_m);
    if let Some(s) = storey_m {
        heights.storey_m = s;
    }
    let opts = BuildOptions {
        heights,
        name: Some("buildings".into()),
        ..Default::default()
    };
    let b = layer_arg("buildings", Some(buildings), &Columns::All)?.expect("given");
    let (format, stats, report, errors) = without_gil(py, move || {
        let city = city_of(b, None, None, &opts)?;
        let glb = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("glb"));
        let (format, stats, errors) = if glb {
            let (meshes, errors) = blockwalk::city::extrude::try_extrude_city(&city);
            let s = write_glb(&city, &meshes, &path).map_err(|e| Failure::of(Kind::Export, &e))?;
            let errors: Vec<String> = errors.iter().map(|e| e.to_string()).collect();
            ("glb", json_text(&s), errors)
        } else if is_cityjson_seq(&path) {
            let s = write_cityjson_seq(&city, &path).map_err(|e| Failure::of(Kind::Export, &e))?;
            ("cityjsonseq", json_text(&s), Vec::new())
        } else {
            let s = write_cityjson(&city, &path).map_err(|e| Failure::of(Kind::Export, &e))?;
            ("cityjson", json_text(&s), Vec::new())
        };
        Ok((format, stats, json_text(&city.report), errors))
    })?;
    let out = PyDict::new(py);
    out.set_item("format", format)?;
    out.set_item("stats", stats)?;
    out.set_item("report", report)?;
    out.set_item("extrude_errors", errors)?;
    Ok(out)
}

/// A 3D Tiles 1.1 tileset of the city in `out` (`blockwalk::tiles::build_tileset`). Returns a
/// dict: `summary` and `report` (JSON text).
#[pyfunction]
#[pyo3(signature = (buildings, streets, out, *, k, levels=None, height_field=None, height_m=None, implicit=false, plain=false))]
#[allow(clippy::too_many_arguments)]
fn tileset<'py>(
    py: Python<'py>,
    buildings: LayerArgs<'py>,
    streets: Option<LayerArgs<'py>>,
    out: PathBuf,
    k: u32,
    levels: Option<u32>,
    height_field: Option<String>,
    height_m: Option<f64>,
    implicit: bool,
    plain: bool,
) -> PyResult<Bound<'py, PyDict>> {
    use blockwalk::blockmap::Stop;
    use blockwalk::scene::{LoadedCity, Scene, SceneOptions};
    use blockwalk::tiles::{build_tileset, ContentEncoding, TilesetOptions};
    if levels == Some(0) {
        return Err(InputError::new_err(
            "levels 0: give at least 1, or None for a map where it costs fewer bytes than the meshes",
        ));
    }
    blockwalk::blockmap::BuildOptions {
        k,
        ..Default::default()
    }
    .validate()
    .map_err(|e| InputError::new_err(chain(&e)))?;
    let opts = BuildOptions {
        heights: height_fields(height_field, height_m),
        name: Some("buildings".into()),
        ..Default::default()
    };
    // Every attribute, as `blockwalk tileset` reads them (the leaves' metadata tables).
    let b = layer_arg("buildings", Some(buildings), &Columns::All)?.expect("given");
    let s = layer_arg("streets", streets, &street_columns(&opts))?;
    let (summary, report) = without_gil(py, move || {
        let city = city_of(b, s, None, &opts)?;
        let report = json_text(&city.report);
        let scene = Scene::from_loaded(
            LoadedCity {
                city,
                layout: None,
                meshes: None,
            },
            &SceneOptions {
                structures: Vec::new(),
                ..SceneOptions::default()
            },
            &mut |_| {},
        )
        .map_err(|e| Failure::of(Kind::Blocks, &e))?;
        let topts = TilesetOptions {
            k,
            stop: levels.map_or(Stop::Competitive, Stop::Levels),
            implicit,
            // A `.3tz` name asks for the one-file archive, as on the command line.
            archive: out
                .extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("3tz")),
            content: if plain {
                ContentEncoding::Plain
            } else {
                ContentEncoding::Compact
            },
            ..TilesetOptions::default()
        };
        let (_, summary) = build_tileset(
            &scene.city,
            &scene.layout,
            &scene.bounds,
            &scene.building_meshes,
            &out,
            &topts,
            &|_, _| {},
        )
        .map_err(|e| Failure::of(Kind::Export, &e))?;
        Ok((json_text(&summary), report))
    })?;
    let d = PyDict::new(py);
    d.set_item("summary", summary)?;
    d.set_item("report", report)?;
    Ok(d)
}

/// The compiled module.
#[pymodule]
fn _blockwalk(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("BlockwalkError", py.get_type::<BlockwalkError>())?;
    m.add("ReadError", py.get_type::<ReadError>())?;
    m.add("InputError", py.get_type::<InputError>())?;
    m.add("BlocksError", py.get_type::<BlocksError>())?;
    m.add("ExportError", py.get_type::<ExportError>())?;
    m.add_function(wrap_pyfunction!(read, m)?)?;
    m.add_function(wrap_pyfunction!(blocks, m)?)?;
    m.add_function(wrap_pyfunction!(extrude, m)?)?;
    m.add_function(wrap_pyfunction!(tileset, m)?)?;
    Ok(())
}
