//! Layers → [`City`]: CRS to metric world coordinates, footprint repair, heights, streets and
//! parcels, and the [`CityReport`] that accounts for every input feature (seed 003 §3: the
//! cadastral map is the input of the whole pipeline).
//!
//! | module | does |
//! |---|---|
//! | [`frame`] | the metric frame (footprints' CRS), other layers reprojected into it, the robust local origin, f32 reach |
//! | [`repair_report`] | footprint features → buildings: checked transform, repair, heights, the account |
//! | [`heights`] | heights from attributes, implausible values |
//! | [`layers`] | street and parcel layers, and why a given layer is unusable |
//! | [`geometry`] | geometry kinds, tags, checked transforms of lines and polygons |
//!
//! # Coordinates
//! Every vertex is checked against its layer's CRS (latitudes beyond ±90°, metres under a
//! lon/lat CRS, points beyond a projection's valid range) and a feature with one that does not fit
//! is refused with the vertex and the reason. Streets and parcels in another CRS than the
//! footprints are reprojected into the footprints' frame, datum shifts included.
//!
//! # Footprints
//! Each footprint feature is transformed to metric world coordinates and repaired with
//! [`crate::geom::repair::repair_polygon`]. A MultiPolygon, or a polygon that repair splits, gives one [`Building`]
//! per part; parts are numbered in order and get the source id `layer:fid.k`, a single polygon
//! gets `layer:fid`. In the report each *feature* counts once: imported (every part valid as it
//! was, up to winding), repaired (something was done, including parts refused), or refused (no
//! part left, or refused by the importer). So `imported + repaired + refused == read`.
//!
//! # Heights
//! From the first field of [`HeightFields`] that holds a usable number: a height in metres
//! ([`HeightSource::Height`]); else levels × storey height, plus roof levels × storey height when
//! given ([`HeightSource::Levels`]); else the default height ([`HeightSource::Default`], 9 m: three
//! storeys of 3 m, a typical low-rise city building). A value is usable when it is finite,
//! positive and at most 1000 m (the tallest building is 828 m); an unusable value is noted and
//! the next source is tried; each such value is listed in [`CityReport::implausible_heights`]. The bottom of the prism is `min_height` (m) or `min_level` × storey
//! height, else 0; a bottom at or above the top is clamped to 0, with a note.

use std::collections::BTreeMap;

use blockwalk_importers::{format_groups, Columns, CrsError, Layer, MetricTransform, ReasonGroup};
use serde::Serialize;

use super::model::{Building, City, CityReport, LocalFrame};

pub mod frame;
pub mod geometry;
pub mod ground;
pub mod heights;
pub mod layers;
pub mod repair_report;

pub use frame::{robust_origin, FrameReport};
pub use geometry::{has_tag, truthy};
pub use ground::{GroundOptions, GroundReport, GroundSetupError};
pub use heights::{heights_from_attributes, source_name, HeightFields, Heights, ImplausibleHeight};
pub use repair_report::source_fid;

/// Options of [`build_city`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BuildOptions {
    /// Height fields and rules.
    pub heights: HeightFields,
    /// Leave out street features whose attribute `k` equals `v` (compared as text).
    pub exclude_street_tags: Vec<(String, String)>,
    /// The city's name; `None`: [`city_name`] of the footprint file.
    pub name: Option<String>,
    /// The footprint layer's CRS, stated or replacing the one its file gives (a Shapefile
    /// without `.prj`, a wrong one); `None`: the file's ([`parse_crs`] reads one from text).
    pub crs: Option<crate::importers::Crs>,
    /// Put the buildings on an elevation model (`None`: a flat city at z = 0).
    pub ground: Option<GroundOptions>,
}

/// Footprint file stems that say nothing about the city (`buildings.shp` of a city folder).
pub const GENERIC_LAYER_NAMES: [&str; 6] = [
    "buildings",
    "building",
    "footprints",
    "footprint",
    "polygons",
    "layer",
];

/// A city's name from its footprint file and the layer's name (the file stem): the layer's name,
/// unless it is generic ([`GENERIC_LAYER_NAMES`], any case) and the file lies in a named folder
/// (not `.`), whose name is then the city's (`data/helsinki/buildings.shp` → `helsinki`).
pub fn city_name(footprint_file: &std::path::Path, layer_name: &str) -> String {
    let generic = GENERIC_LAYER_NAMES
        .iter()
        .any(|g| g.eq_ignore_ascii_case(layer_name));
    let folder = footprint_file
        .parent()
        .and_then(|p| p.file_name())
        .map(|n| n.to_string_lossy().into_owned())
        .filter(|n| !n.is_empty() && n != "." && n != "..");
    match folder {
        Some(f) if generic => f,
        _ => layer_name.to_string(),
    }
}

/// A CRS from text: `EPSG:NNNN`, a PROJ string (`+proj=… `, projected, in metres or another
/// linear unit such as `+units=us-ft`), WKT, or the path of a file holding WKT (a `.prj`).
///
/// # Errors
/// [`BuildError::Options`] naming the text and the problem (an unknown code, a projection that
/// cannot be set up, a file that cannot be read, …).
pub fn parse_crs(text: &str) -> Result<crate::importers::Crs, BuildError> {
    use crate::importers::Crs;
    let t = text.trim();
    let bad = |why: String| BuildError::Options(format!("CRS '{text}': {why}"));
    if let Some(code) = t.strip_prefix("EPSG:").or_else(|| t.strip_prefix("epsg:")) {
        let code: u32 = code
            .trim()
            .parse()
            .map_err(|_| bad("expected EPSG:NNNN".into()))?;
        return Crs::from_epsg(code).map_err(|e| bad(e.to_string()));
    }
    if t.starts_with("+proj=") {
        if t.contains("+proj=longlat") || t.contains("+proj=latlong") {
            return Err(bad(
                "geographic PROJ strings are not taken: give EPSG:4326 or the code".into(),
            ));
        }
        let crs = Crs::Projected {
            epsg: None,
            name: t.to_string(),
            proj4: t.to_string(),
        };
        crs.try_metric_transform([0.0, 0.0])
            .map_err(|e| bad(e.to_string()))?;
        return Ok(crs);
    }
    let wkt = if std::path::Path::new(t).is_file() {
        std::fs::read_to_string(t).map_err(|e| bad(e.to_string()))?
    } else {
        t.to_string()
    };
    Crs::from_wkt(&wkt).map_err(|e| bad(e.to_string()))
}

/// A building whose height attribute could not be used, for the report.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct HeightNote {
    /// The building's source id.
    pub id: String,
    /// The field.
    pub field: String,
    /// The value as read.
    pub value: String,
    /// What is wrong with it.
    pub why: String,
}

/// Why a city could not be built at all (single features never fail the build: they are
/// refused in the report).
#[derive(Debug, thiserror::Error)]
pub enum BuildError {
    /// The footprint layer holds no building that could be imported.
    #[error(
        "{file}: no usable building footprint ({read} feature(s) read, all refused): {}",
        format_groups(reasons)
    )]
    NoBuildings {
        /// The footprint file.
        file: String,
        /// Features read.
        read: usize,
        /// The refusals grouped by reason, largest group first.
        reasons: Vec<ReasonGroup>,
    },
    /// A layer's CRS cannot be set up.
    #[error("{layer}: {source}")]
    Crs {
        /// The layer's file.
        layer: String,
        /// Why.
        #[source]
        source: CrsError,
    },
    /// The options are unusable.
    #[error("invalid build options: {0}")]
    Options(String),
    /// The elevation model cannot be used.
    #[error(transparent)]
    Ground(#[from] GroundSetupError),
}

/// Builds a city from a footprint layer and optional street and parcel layers, each in its own
/// CRS: streets and parcels are reprojected into the footprints' frame.
///
/// # Errors
/// [`BuildError::NoBuildings`] when no footprint survives (with the reasons, grouped);
/// [`BuildError::Crs`] when a layer's CRS cannot be set up; [`BuildError::Options`] for a storey
/// or default height that is not positive.
pub fn build_city(
    footprints: &Layer,
    streets: Option<&Layer>,
    parcels: Option<&Layer>,
    opts: &BuildOptions,
) -> Result<City, BuildError> {
    let hf = &opts.heights;
    check_heights(hf)?;
    let stated;
    let footprints = match &opts.crs {
        Some(crs) if *crs != footprints.crs => {
            stated = Layer {
                crs: crs.clone(),
                ..footprints.clone()
            };
            &stated
        }
        _ => footprints,
    };
    let transform = frame::footprint_transform(footprints)?;
    let mut report = CityReport {
        crs: match footprints.crs {
            crate::importers::Crs::Unknown => {
                "no CRS: coordinates taken as metres in a local frame".into()
            }
            _ => transform.describe(),
        },
        ..Default::default()
    };
    let mut buildings = repair_report::build_footprints(footprints, &transform, hf, &mut report);
    let terrain = on_ground(&mut buildings, &transform, opts, &mut report)?;
    if buildings.is_empty() {
        return Err(BuildError::NoBuildings {
            file: footprints.source.display().to_string(),
            read: report.buildings_read,
            reasons: report.refused_by_reason,
        });
    }
    let (local, frame_report) = robust_origin(&buildings);
    report.notes.extend(frame::frame_notes(&frame_report));
    report.frame = frame_report;

    let mut city = with_layers(
        footprints,
        streets,
        parcels,
        opts,
        (transform, local),
        buildings,
        report,
    )?;
    city.terrain = terrain;
    city.name = opts
        .name
        .clone()
        .unwrap_or_else(|| city_name(&footprints.source, &footprints.name));
    Ok(city)
}

/// A city of a street layer alone, without buildings: what the faces of a street graph
/// ([`crate::blocks::detect`]) need when no footprints are given. Ground metres are centred on
/// the lines ([`frame::line_layer_centre`]), as [`build_city`] centres them on the footprints,
/// and the local origin is there. [`BuildOptions::crs`] states the layer's CRS.
///
/// # Errors
/// [`BuildError::Crs`] when the layer's CRS cannot be set up.
pub fn build_street_city(streets: &Layer, opts: &BuildOptions) -> Result<City, BuildError> {
    let crs = opts.crs.clone().unwrap_or_else(|| streets.crs.clone());
    let centre = frame::line_layer_centre(streets).unwrap_or([0.0, 0.0]);
    let transform = crs
        .try_metric_transform(centre)
        .map_err(|source| BuildError::Crs {
            layer: streets.source.display().to_string(),
            source,
        })?;
    let [ox, oy] = transform.to_metric(centre);
    let local = LocalFrame {
        origin: glam::DVec3::new(ox, oy, 0.0),
    };
    // No footprints: an empty layer in the streets' CRS stands for them.
    let none = Layer {
        name: streets.name.clone(),
        source: streets.source.clone(),
        crs,
        features: Vec::new(),
        report: Default::default(),
    };
    let stated;
    let streets = if streets.crs == none.crs {
        streets
    } else {
        stated = Layer {
            crs: none.crs.clone(),
            ..streets.clone()
        };
        &stated
    };
    let mut city = build_city_in_frame(&none, Some(streets), None, opts, transform, local)?;
    city.name = opts.name.clone().unwrap_or_else(|| streets.name.clone());
    Ok(city)
}

/// [`build_city`] with the metric transform and the local frame given instead of derived from
/// the footprints, for a part of a city read on its own (a tile of `jobs`): its buildings get
/// exactly the world coordinates and f32 local coordinates they have in the whole city. A part
/// with no building is not an error here: it gives a city without buildings.
///
/// # Errors
/// [`BuildError::Crs`] when a street or parcel layer's CRS cannot be set up;
/// [`BuildError::Options`] as [`build_city`].
pub fn build_city_in_frame(
    footprints: &Layer,
    streets: Option<&Layer>,
    parcels: Option<&Layer>,
    opts: &BuildOptions,
    transform: MetricTransform,
    frame: LocalFrame,
) -> Result<City, BuildError> {
    let hf = &opts.heights;
    check_heights(hf)?;
    let mut report = CityReport {
        crs: transform.describe(),
        ..Default::default()
    };
    let mut buildings = repair_report::build_footprints(footprints, &transform, hf, &mut report);
    let terrain = on_ground(&mut buildings, &transform, opts, &mut report)?;
    let mut city = with_layers(
        footprints,
        streets,
        parcels,
        opts,
        (transform, frame),
        buildings,
        report,
    )?;
    city.terrain = terrain;
    Ok(city)
}

/// With [`BuildOptions::ground`]: the terrain in the city's frame, every building put on it
/// ([`ground::place_buildings`]) and the account in `report`. Without: `None`, buildings at 0.
fn on_ground(
    buildings: &mut Vec<Building>,
    transform: &MetricTransform,
    opts: &BuildOptions,
    report: &mut CityReport,
) -> Result<Option<std::sync::Arc<crate::terrain::Terrain>>, BuildError> {
    let Some(g) = &opts.ground else {
        return Ok(None);
    };
    let t0 = std::time::Instant::now();
    let terrain = ground::load_terrain(g, transform, buildings)?;
    let terrain_ms = t0.elapsed().as_secs_f64() * 1e3;
    let mut placed = ground::place_buildings(buildings, &terrain, g, report);
    placed.terrain_ms = terrain_ms;
    report.ground = Some(placed);
    Ok(Some(std::sync::Arc::new(terrain)))
}

/// Refuses a storey or default height that is not usable.
fn check_heights(hf: &HeightFields) -> Result<(), BuildError> {
    if !(hf.storey_m.is_finite() && hf.storey_m > 0.0) {
        return Err(BuildError::Options(format!(
            "storey height {} m is not positive",
            hf.storey_m
        )));
    }
    if !heights::usable(hf.default_height_m) {
        return Err(BuildError::Options(format!(
            "default height {} m is not in (0, 1000]",
            hf.default_height_m
        )));
    }
    Ok(())
}

/// The rest of a city around its `buildings`, in `transform` and `frame`: the street and parcel
/// layers reprojected into the footprints' frame, their warnings in the report.
fn with_layers(
    footprints: &Layer,
    streets: Option<&Layer>,
    parcels: Option<&Layer>,
    opts: &BuildOptions,
    (transform, frame): (MetricTransform, LocalFrame),
    buildings: Vec<Building>,
    mut report: CityReport,
) -> Result<City, BuildError> {
    let streets_out = match streets {
        Some(l) => {
            let t = frame::layer_transform(&transform, l, &mut report.notes)?;
            layers::build_streets(l, &t, opts, &mut report)
        }
        None => Vec::new(),
    };
    let parcels_out = match parcels {
        Some(l) => {
            let t = frame::layer_transform(&transform, l, &mut report.notes)?;
            layers::build_parcels(l, &t, &mut report)
        }
        None => Vec::new(),
    };
    for why in [&report.street_layer_unusable, &report.parcel_layer_unusable]
        .into_iter()
        .flatten()
    {
        report.notes.push(format!("warning: {why}"));
    }
    Ok(City {
        name: footprints.name.clone(),
        transform,
        frame,
        buildings,
        streets: streets_out,
        parcels: parcels_out,
        report,
        terrain: None,
    })
}

/// The footprint attributes a city's buildings are made from: the height fields of `hf` and
/// what the buildings' appearance reads ([`crate::city::appearance::KIND_KEYS`],
/// [`crate::city::appearance::LEVELS_KEYS`]). Reading only these
/// ([`blockwalk_importers::read_layer_with`]) gives the same buildings and meshes; an export
/// of the source attributes (CityJSON) needs them all.
pub fn footprint_columns(hf: &HeightFields) -> Columns {
    use crate::city::appearance::{KIND_KEYS, LEVELS_KEYS};
    Columns::only(
        [
            &hf.height,
            &hf.levels,
            &hf.roof_levels,
            &hf.min_height,
            &hf.min_level,
        ]
        .into_iter()
        .flatten()
        .map(String::as_str)
        .chain(KIND_KEYS)
        .chain(LEVELS_KEYS),
    )
}

/// Buildings per height source, as the report counts them.
pub fn count_height_sources(buildings: &[Building]) -> BTreeMap<String, usize> {
    let mut m = BTreeMap::new();
    for b in buildings {
        *m.entry(source_name(b.height_source).to_string())
            .or_insert(0) += 1;
    }
    m
}

#[cfg(test)]
mod tests {

    #[test]
    fn a_city_is_named_after_its_folder_when_its_file_is_generic() {
        use std::path::Path;
        let n = |p: &str, stem: &str| city_name(Path::new(p), stem);
        assert_eq!(n("data/helsinki/buildings.shp", "buildings"), "helsinki");
        assert_eq!(n("x/astana/Footprints.gpkg", "Footprints"), "astana");
        assert_eq!(
            n("data/bubenec/bubenec_houses.shp", "bubenec_houses"),
            "bubenec_houses"
        );
        assert_eq!(n("buildings.shp", "buildings"), "buildings");
        assert_eq!(n("./buildings.shp", "buildings"), "buildings");
    }

    #[test]
    fn a_crs_is_read_from_a_code_a_proj_string_or_wkt() {
        use crate::importers::Crs;
        assert!(matches!(
            parse_crs("EPSG:32633").unwrap(),
            Crs::Projected {
                epsg: Some(32633),
                ..
            }
        ));
        assert!(matches!(
            parse_crs("+proj=utm +zone=35 +ellps=GRS80 +units=m").unwrap(),
            Crs::Projected { epsg: None, .. }
        ));
        let feet = parse_crs("+proj=tmerc +lat_0=40 +lon_0=-74 +datum=NAD83 +units=us-ft").unwrap();
        assert!((feet.metres_per_unit().unwrap() - 1200.0 / 3937.0).abs() < 1e-12);
        assert!(!feet.is_metric_projected());
        for bad in [
            "EPSG:x",
            "EPSG:1",
            "+proj=longlat",
            "+proj=nosuchprojection +units=m",
            "nonsense",
        ] {
            let e = parse_crs(bad).unwrap_err().to_string();
            assert!(e.contains(bad), "{e}");
        }
    }

    use super::*;
    use crate::city::model::BuildingId;
    use crate::geom::predicates::polygon_area;
    use crate::geom::repair::check_polygon;
    use blockwalk_importers::{AttrValue, Attributes, Crs, Feature, ImportReport};
    use geo_types::{coord, Geometry, LineString, MultiPolygon, Polygon};

    fn attrs(kv: &[(&str, AttrValue)]) -> Attributes {
        kv.iter().map(|(k, v)| (k.to_string(), v.clone())).collect()
    }

    fn rect(x0: f64, y0: f64, w: f64, h: f64) -> Polygon<f64> {
        // Clockwise, as a Shapefile stores it.
        Polygon::new(
            LineString::from(vec![
                (x0, y0),
                (x0, y0 + h),
                (x0 + w, y0 + h),
                (x0 + w, y0),
                (x0, y0),
            ]),
            vec![],
        )
    }

    fn layer(features: Vec<Feature>, refused: usize) -> Layer {
        let mut report = ImportReport {
            read: features.len() + refused,
            imported: features.len(),
            ..Default::default()
        };
        for i in 0..refused {
            report.refuse(1000 + i as u64, "truncated record");
        }
        Layer {
            name: "b".into(),
            source: "b.shp".into(),
            crs: Crs::from_epsg(32633).unwrap(),
            features,
            report,
        }
    }

    #[test]
    fn every_feature_is_accounted_for() {
        let bow = Polygon::new(
            LineString::from(vec![(0., 0.), (10., 10.), (10., 0.), (0., 10.), (0., 0.)]),
            vec![],
        );
        let feats = vec![
            Feature {
                fid: 0,
                geometry: Geometry::Polygon(rect(500000., 5.4e6, 10., 20.)),
                attributes: attrs(&[("height", AttrValue::Float(20.0))]),
            },
            Feature {
                fid: 1,
                geometry: Geometry::Polygon(bow),
                attributes: attrs(&[]),
            },
            Feature {
                fid: 2,
                geometry: Geometry::MultiPolygon(MultiPolygon::new(vec![
                    rect(500100., 5.4e6, 5., 5.),
                    rect(500200., 5.4e6, 5., 5.),
                ])),
                attributes: attrs(&[("levels", AttrValue::Int(2))]),
            },
            Feature {
                fid: 3,
                geometry: Geometry::Point(geo_types::Point::new(1.0, 2.0)),
                attributes: attrs(&[]),
            },
            Feature {
                fid: 4,
                geometry: Geometry::Polygon(Polygon::new(
                    LineString::from(vec![(1., 1.), (2., 2.), (3., 3.), (1., 1.)]),
                    vec![],
                )),
                attributes: attrs(&[]),
            },
        ];
        let l = layer(feats, 2);
        let city = build_city(&l, None, None, &BuildOptions::default()).unwrap();
        let r = &city.report;
        assert_eq!(r.buildings_read, 7);
        assert_eq!(
            r.buildings_imported + r.buildings_repaired.len() + r.buildings_refused.len(),
            r.buildings_read
        );
        assert_eq!(r.buildings_imported, 2); // fid 0 and the multipolygon fid 2
        assert_eq!(r.buildings_repaired.len(), 1); // bowtie
        assert_eq!(r.buildings_refused.len(), 4); // 2 importer, point, collinear
                                                  // 1 + 2 bowtie lobes + 2 parts
        assert_eq!(city.buildings.len(), 5);
        let ids: Vec<&str> = city
            .buildings
            .iter()
            .map(|b| b.source_id.as_str())
            .collect();
        assert_eq!(ids, ["b:0", "b:1.0", "b:1.1", "b:2.0", "b:2.1"]);
        for (i, b) in city.buildings.iter().enumerate() {
            assert_eq!(b.id, BuildingId(i as u32));
            check_polygon(&b.footprint).unwrap();
        }
        assert_eq!(polygon_area(&city.buildings[0].footprint), 200.0);
        assert_eq!(r.height_sources["height"], 1);
        assert_eq!(r.height_sources["levels"], 2);
        assert_eq!(r.height_sources["default"], 2);
        assert_eq!(count_height_sources(&city.buildings), r.height_sources);
        // Frame origin: the median of the buildings' centres (x 2.5, 7.5, 500005, 500102.5,
        // 500202.5; y 5, 5, 5.4e6 + 2.5, + 2.5, + 10), not the bounding box's centre, which the
        // two bowtie lobes near (0, 0) would pull 2,700 km away.
        let o = city.frame.origin;
        assert_eq!((o.x, o.y, o.z), (500005.0, 5_400_002.5, 0.0));
        let outliers: Vec<&str> = r.frame.outliers.iter().map(|o| o.0.as_str()).collect();
        assert_eq!(outliers, ["b:1.0", "b:1.1"]);
        assert!(!r.frame.f32_ok && r.frame.f32_spacing_m >= 0.25);
        assert!(r
            .notes
            .iter()
            .any(|n| n.contains("b:1.0") && n.contains("far from")));
    }

    #[test]
    fn streets_grade_separation_and_exclusion() {
        let feats = vec![Feature {
            fid: 0,
            geometry: Geometry::Polygon(rect(0., 0., 10., 10.)),
            attributes: attrs(&[]),
        }];
        let fl = layer(feats, 0);
        let line = |fid, a: &[(&str, AttrValue)]| Feature {
            fid,
            geometry: Geometry::LineString(LineString::from(vec![(0., -5.), (10., -5.)])),
            attributes: attrs(a),
        };
        let sl = Layer {
            name: "s".into(),
            features: vec![
                line(0, &[("bridge", AttrValue::Text("yes".into()))]),
                line(1, &[("tunnel", AttrValue::Float(1.0))]),
                line(2, &[("bridge", AttrValue::Text("no".into()))]),
                line(3, &[("highway", AttrValue::Text("footway".into()))]),
                Feature {
                    fid: 4,
                    geometry: Geometry::Point(geo_types::Point::new(0., 0.)),
                    attributes: attrs(&[]),
                },
            ],
            ..layer(vec![], 0)
        };
        let opts = BuildOptions {
            exclude_street_tags: vec![("highway".into(), "footway".into())],
            ..Default::default()
        };
        let city = build_city(&fl, Some(&sl), None, &opts).unwrap();
        let gs: Vec<bool> = city.streets.iter().map(|s| s.grade_separated).collect();
        assert_eq!(gs, [true, true, false]);
        let note = city
            .report
            .notes
            .iter()
            .find(|n| n.starts_with("streets"))
            .unwrap();
        assert!(
            note.contains("1 excluded") && note.contains("1 refused"),
            "{note}"
        );
        let _ = coord! {x: 0.0, y: 0.0};
    }

    #[test]
    fn no_buildings_is_an_error() {
        let l = layer(vec![], 3);
        let e = build_city(&l, None, None, &BuildOptions::default()).unwrap_err();
        match &e {
            BuildError::NoBuildings {
                read: 3, reasons, ..
            } => {
                assert_eq!(reasons.len(), 1);
                assert_eq!(reasons[0].count, 3);
                assert_eq!(reasons[0].examples, ["b:1000", "b:1001", "b:1002"]);
            }
            other => panic!("{other:?}"),
        }
        assert!(
            e.to_string().contains("3 × importer: truncated record"),
            "{e}"
        );
    }
}
