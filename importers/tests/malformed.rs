//! Malformed input, one case per test function section: each bad file is written to a temporary
//! folder and the reader must answer with the specific error variant, or with the documented
//! repair (a note, a refused feature), never with a panic or a silently wrong layer.

use blockwalk_importers::{
    geojson_reader, gpkg, osm, read_layer, shp, AttrValue, Crs, CrsError, ImportError, Theme,
};
use std::path::{Path, PathBuf};

fn data(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../data")
        .join(rel)
}

/// Copies a Shapefile's parts to `dir/l.*` and returns the `.shp` path.
fn copy_shp(stem: &str, dir: &Path) -> PathBuf {
    for ext in ["shp", "shx", "dbf", "prj", "cpg"] {
        std::fs::copy(data(&format!("{stem}.{ext}")), dir.join(format!("l.{ext}"))).unwrap();
    }
    dir.join("l.shp")
}

fn write(dir: &Path, name: &str, bytes: impl AsRef<[u8]>) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

const FC_START: &str = r#"{"type":"FeatureCollection","features":["#;

fn square(x: f64, y: f64, d: f64) -> String {
    format!(
        r#"{{"type":"Feature","properties":{{}},"geometry":{{"type":"Polygon","coordinates":[[[{x},{y}],[{},{y}],[{},{}],[{x},{}],[{x},{y}]]]}}}}"#,
        x + d,
        x + d,
        y + d,
        y + d
    )
}

// ---- Shapefile -------------------------------------------------------------------------------

#[test]
fn shp_empty_file_is_empty() {
    let dir = tempfile::tempdir().unwrap();
    let p = copy_shp("bubenec/streets", dir.path());
    std::fs::write(&p, b"").unwrap();
    let e = shp::read(&p).unwrap_err();
    assert!(matches!(e, ImportError::Empty { .. }), "{e:?}");
    assert!(e.to_string().contains("l.shp"), "{e}");
}

#[test]
fn shp_truncated_is_a_shapefile_error_naming_the_record() {
    let dir = tempfile::tempdir().unwrap();
    let p = copy_shp("bubenec/streets", dir.path());
    let b = std::fs::read(&p).unwrap();
    std::fs::write(&p, &b[..b.len() - 37]).unwrap();
    let e = shp::read(&p).unwrap_err();
    assert!(matches!(e, ImportError::Shapefile { .. }), "{e:?}");
    assert!(e.to_string().contains("record 34"), "{e}");
    assert!(std::error::Error::source(&e).is_some(), "keeps its cause");
}

#[test]
fn shp_missing_dbf_is_a_missing_companion() {
    let dir = tempfile::tempdir().unwrap();
    let p = copy_shp("bubenec/streets", dir.path());
    std::fs::remove_file(dir.path().join("l.dbf")).unwrap();
    assert!(matches!(
        shp::read(&p),
        Err(ImportError::MissingCompanion { .. })
    ));
}

#[test]
fn shp_damaged_shx_is_handled_like_a_missing_one() {
    let dir = tempfile::tempdir().unwrap();
    let p = copy_shp("bubenec/streets", dir.path());
    let reference = shp::read(&p).unwrap();
    // Garbage index.
    write(
        dir.path(),
        "l.shx",
        b"this is no index at all, just some bytes of text",
    );
    let l = shp::read(&p).unwrap();
    assert_eq!(l.features.len(), reference.features.len());
    assert!(
        l.report.notes.iter().any(|n| n.contains("damaged")),
        "{:?}",
        l.report.notes
    );
    // An index whose offsets point past the file.
    let mut shx = std::fs::read(data("bubenec/streets.shx")).unwrap();
    for k in 0..4 {
        shx[100 + 8 * 5 + k] = 0x7f;
    }
    std::fs::write(dir.path().join("l.shx"), &shx).unwrap();
    let l = shp::read(&p).unwrap();
    assert_eq!(l.features.len(), reference.features.len());
    assert!(l.report.notes.iter().any(|n| n.contains("damaged")));
    // A truncated index.
    std::fs::write(dir.path().join("l.shx"), &shx[..150]).unwrap();
    let l = shp::read(&p).unwrap();
    assert_eq!(l.features.len(), reference.features.len());
}

#[test]
fn shx_and_record_length_lies_are_named_by_record() {
    let dir = tempfile::tempdir().unwrap();
    let p = copy_shp("bubenec/streets", dir.path());
    let reference = shp::read(&p).unwrap();
    let n = reference.features.len();
    let good_shx = std::fs::read(data("bubenec/streets.shx")).unwrap();
    let good_shp = std::fs::read(data("bubenec/streets.shp")).unwrap();
    let be = |b: &[u8], at: usize| i32::from_be_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]]);
    // Record 5's index entry points at record 6: read through the index, record 6 would be read
    // twice. The note names the record and both offsets; the features are the file's.
    let mut shx = good_shx.clone();
    let six: Vec<u8> = shx[100 + 8 * 6..100 + 8 * 7].to_vec();
    shx[100 + 8 * 5..100 + 8 * 6].copy_from_slice(&six);
    std::fs::write(dir.path().join("l.shx"), &shx).unwrap();
    let l = shp::read(&p).unwrap();
    let geoms = |l: &blockwalk_importers::Layer| -> Vec<_> {
        l.features
            .iter()
            .map(|f| (f.fid, f.geometry.clone()))
            .collect()
    };
    assert_eq!(geoms(&l), geoms(&reference));
    // The streaming reader chooses the same way: the same shapes, the same note.
    let mut chunks = Vec::new();
    shp::read_streaming(&p, &mut |_, _| true, 4, &mut |c| chunks.push(c)).unwrap();
    let streamed: Vec<_> = chunks
        .iter()
        .flat_map(|c| c.features.iter().map(|f| (f.fid, f.geometry.clone())))
        .collect();
    assert_eq!(streamed, geoms(&reference));
    assert!(chunks
        .iter()
        .flat_map(|c| &c.report.notes)
        .any(|n| n.contains("record 5: the .shx gives offset")));
    let note = l.report.notes.join("\n");
    let at5 = 2 * be(&good_shx, 100 + 8 * 5);
    let at6 = 2 * be(&good_shx, 100 + 8 * 6);
    assert!(note.contains("record 5: the .shx gives offset"), "{note}");
    assert!(
        note.contains(&format!("offset {at6}")) && note.contains(&format!("offset {at5}")),
        "{note}"
    );
    // An index one record short (its header still consistent): not a count mismatch, but the
    // index named as short; the records come from the .shp.
    let mut shx = good_shx[..good_shx.len() - 8].to_vec();
    let words = (shx.len() / 2) as i32;
    shx[24..28].copy_from_slice(&words.to_be_bytes());
    std::fs::write(dir.path().join("l.shx"), &shx).unwrap();
    let l = shp::read(&p).unwrap();
    assert_eq!(l.features.len(), n);
    let note = l.report.notes.join("\n");
    assert!(
        note.contains(&format!(
            "the .shx indexes {} records, the .shp holds {n}",
            n - 1
        )),
        "{note}"
    );
    // A record header in the .shp whose length lies (record 3 claims 8 bytes more): with the
    // index, the index is named; without it, the read error names record 3's length.
    std::fs::write(dir.path().join("l.shx"), &good_shx).unwrap();
    let mut shp_bytes = good_shp.clone();
    let at3 = 2 * be(&good_shx, 100 + 8 * 3) as usize;
    let words3 = be(&shp_bytes, at3 + 4);
    shp_bytes[at3 + 4..at3 + 8].copy_from_slice(&(words3 + 4).to_be_bytes());
    std::fs::write(dir.path().join("l.shp"), &shp_bytes).unwrap();
    std::fs::remove_file(dir.path().join("l.shx")).unwrap();
    // Read or refused, the lie is named.
    let text = match shp::read(&p) {
        Ok(l) => l.report.notes.join("\n"),
        Err(e) => e.to_string(),
    };
    assert!(text.contains("the length of record 3"), "{text}");
    assert!(!text.starts_with("shapes in"), "{text}");
}

/// Offset of record `i`'s first field in a DBF (after the deletion flag).
fn dbf_record(bytes: &[u8], i: usize) -> usize {
    let header = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    let record = u16::from_le_bytes([bytes[10], bytes[11]]) as usize;
    header + i * record + 1
}

#[test]
fn dbf_bad_number_costs_that_value_not_the_feature() {
    let dir = tempfile::tempdir().unwrap();
    let p = copy_shp("bubenec/streets", dir.path());
    let mut dbf = std::fs::read(dir.path().join("l.dbf")).unwrap();
    let at = dbf_record(&dbf, 3);
    dbf[at..at + 11].copy_from_slice(b"   12x4#!  ");
    std::fs::write(dir.path().join("l.dbf"), &dbf).unwrap();
    let l = shp::read(&p).unwrap();
    assert_eq!(l.features.len(), 35, "{:?}", l.report.refused);
    assert!(l.report.refused.is_empty());
    let f3 = l.features.iter().find(|f| f.fid == 3).unwrap();
    assert!(
        f3.attributes
            .get("FID")
            .is_none_or(|v| matches!(v, AttrValue::Null)),
        "{:?}",
        f3.attributes
    );
    let note = l.report.notes.join("\n");
    assert!(note.contains("l.dbf: 1 value(s)"), "{note}");
    assert!(note.contains("record 3 FID = \"12x4#!\""), "{note}");
}

#[test]
fn an_unparsable_height_is_read_as_empty_with_the_feature_named() {
    let dir = tempfile::tempdir().unwrap();
    let p = copy_shp("helsinki/buildings", dir.path());
    let reference = shp::read(&p).unwrap();
    let mut dbf = std::fs::read(dir.path().join("l.dbf")).unwrap();
    // osm_id N18, osm_type C80, building C80, name C80, then height N24.
    let at = dbf_record(&dbf, 7) + 18 + 80 + 80 + 80;
    dbf[at..at + 24].copy_from_slice(b"            twelve metre");
    std::fs::write(dir.path().join("l.dbf"), &dbf).unwrap();
    let l = shp::read(&p).unwrap();
    assert_eq!(l.features.len(), reference.features.len());
    assert!(l.report.refused.is_empty(), "{:?}", l.report.refused);
    let f7 = l.features.iter().find(|f| f.fid == 7).unwrap();
    assert!(
        f7.attributes
            .get("height")
            .is_none_or(|v| matches!(v, AttrValue::Null)),
        "{:?}",
        f7.attributes
    );
    // The other attributes of the feature are kept.
    let r7 = reference.features.iter().find(|f| f.fid == 7).unwrap();
    assert_eq!(f7.attributes.get("osm_id"), r7.attributes.get("osm_id"));
    let note = l.report.notes.join("\n");
    assert!(
        note.contains("record 7 height = \"twelve metre\""),
        "{note}"
    );
    assert!(note.contains("default height"), "{note}");
    // The streaming reader (what `jobs` reads with) keeps the feature too, with the same note.
    let mut streamed = Vec::new();
    let n = shp::read_streaming(&p, &mut |_, _| true, 5, &mut |c| streamed.push(c)).unwrap();
    assert_eq!(n, reference.features.len());
    let s7 = streamed
        .iter()
        .flat_map(|c| &c.features)
        .find(|f| f.fid == 7)
        .unwrap();
    assert_eq!(s7.attributes.get("height"), f7.attributes.get("height"));
    assert_eq!(s7.attributes.get("osm_id"), r7.attributes.get("osm_id"));
    let notes: Vec<&String> = streamed.iter().flat_map(|c| &c.report.notes).collect();
    assert!(
        notes
            .iter()
            .any(|n| n.contains("record 7 height = \"twelve metre\"")),
        "{notes:?}"
    );
    assert!(streamed.iter().all(|c| c.report.refused.is_empty()));
}

#[test]
fn dbf_with_another_record_count_is_a_format_error() {
    let dir = tempfile::tempdir().unwrap();
    let p = copy_shp("bubenec/streets", dir.path());
    std::fs::copy(data("bubenec/buildings.dbf"), dir.path().join("l.dbf")).unwrap();
    let e = shp::read(&p).unwrap_err();
    assert!(matches!(e, ImportError::Format { .. }), "{e:?}");
    assert!(e.to_string().contains("35 shapes"), "{e}");
}

#[test]
fn dbf_garbage_is_a_dbase_error() {
    let dir = tempfile::tempdir().unwrap();
    let p = copy_shp("bubenec/streets", dir.path());
    write(dir.path(), "l.dbf", b"\x03");
    let e = shp::read(&p).unwrap_err();
    assert!(matches!(e, ImportError::Dbase { .. }), "{e:?}");
}

#[test]
fn prj_garbage_is_a_crs_error_not_metres() {
    let dir = tempfile::tempdir().unwrap();
    let p = copy_shp("bubenec/streets", dir.path());
    write(dir.path(), "l.prj", "metres, probably");
    let e = shp::read(&p).unwrap_err();
    assert!(
        matches!(
            e,
            ImportError::Crs {
                source: CrsError::NotWkt { .. },
                ..
            }
        ),
        "{e:?}"
    );
    assert!(e.to_string().contains("l.prj"), "{e}");
    assert!(e.to_string().contains("--crs EPSG:XXXX"), "{e}");
    // A stated CRS replaces the .prj, which is then not read: the garbage stops nothing.
    let utm = Crs::from_epsg(32633).unwrap();
    let l = shp::read_with_stated_crs(&p, &blockwalk_importers::Columns::All, Some(&utm)).unwrap();
    assert_eq!(l.crs, utm);
    assert_eq!(l.features.len(), 35);
    assert!(
        l.report
            .notes
            .iter()
            .any(|n| n.contains("CRS stated") && n.contains("l.prj not read")),
        "{:?}",
        l.report.notes
    );
}

#[test]
fn prj_with_an_unknown_epsg_code_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let p = copy_shp("bubenec/streets", dir.path());
    write(
        dir.path(),
        "l.prj",
        r#"PROJCS["mystery",GEOGCS["WGS 84",DATUM["WGS_1984",SPHEROID["WGS 84",6378137,298.257223563]]],PROJECTION["Transverse_Mercator"],UNIT["metre",1],AUTHORITY["EPSG","99999"]]"#,
    );
    let e = shp::read(&p).unwrap_err();
    assert!(
        matches!(
            e,
            ImportError::Crs {
                source: CrsError::UnknownEpsg { code: 99999 },
                ..
            }
        ),
        "{e:?}"
    );
}

#[test]
fn prj_in_feet_is_read_in_its_unit() {
    let dir = tempfile::tempdir().unwrap();
    let p = copy_shp("bubenec/streets", dir.path());
    // An ESRI .prj without authority: the unit is the WKT's UNIT, whatever the converter keeps.
    write(
        dir.path(),
        "l.prj",
        r#"PROJCS["NAD_1983_StatePlane_New_York_Long_Island_FIPS_3104_Feet",GEOGCS["GCS_North_American_1983",DATUM["D_North_American_1983",SPHEROID["GRS_1980",6378137.0,298.257222101]],PRIMEM["Greenwich",0.0],UNIT["Degree",0.0174532925199433]],PROJECTION["Lambert_Conformal_Conic"],PARAMETER["False_Easting",984250.0],PARAMETER["False_Northing",0.0],PARAMETER["Central_Meridian",-74.0],PARAMETER["Standard_Parallel_1",40.66666666666666],PARAMETER["Standard_Parallel_2",41.03333333333333],PARAMETER["Latitude_Of_Origin",40.16666666666666],UNIT["Foot_US",0.3048006096012192]]"#,
    );
    let crs = shp::read_crs(&p).unwrap();
    assert!(!crs.is_metric_projected(), "{crs:?}");
    assert!((crs.metres_per_unit().unwrap() - 0.3048006096012192).abs() < 1e-12);
    // The same point as EPSG:2263 (the registry's definition of this system) is the same place.
    let reg = blockwalk_importers::Crs::from_epsg(2263).unwrap();
    let pt = [990_000.0, 200_000.0];
    let (a, b) = (crs.metric_transform(pt), reg.metric_transform(pt));
    let (la, lb) = (
        a.to_wgs84_lonlat(a.to_metric(pt)).unwrap(),
        b.to_wgs84_lonlat(b.to_metric(pt)).unwrap(),
    );
    assert!(
        (la[0] - lb[0]).abs() < 1e-8 && (la[1] - lb[1]).abs() < 1e-8,
        "{la:?} {lb:?}"
    );
}

#[test]
fn prj_missing_is_unknown_with_a_note() {
    let dir = tempfile::tempdir().unwrap();
    let p = copy_shp("bubenec/streets", dir.path());
    std::fs::remove_file(dir.path().join("l.prj")).unwrap();
    let l = shp::read(&p).unwrap();
    assert_eq!(l.crs, Crs::Unknown);
    assert!(l.report.notes.iter().any(|n| n.contains("l.prj")));
}

#[test]
fn prj_british_national_grid_without_epsg_is_read_with_its_datum() {
    let dir = tempfile::tempdir().unwrap();
    let p = copy_shp("bubenec/streets", dir.path());
    write(
        dir.path(),
        "l.prj",
        r#"PROJCS["British_National_Grid",GEOGCS["GCS_OSGB_1936",DATUM["D_OSGB_1936",SPHEROID["Airy_1830",6377563.396,299.3249646]],PRIMEM["Greenwich",0.0],UNIT["Degree",0.0174532925199433]],PROJECTION["Transverse_Mercator"],PARAMETER["False_Easting",400000.0],PARAMETER["False_Northing",-100000.0],PARAMETER["Central_Meridian",-2.0],PARAMETER["Scale_Factor",0.9996012717],PARAMETER["Latitude_Of_Origin",49.0],UNIT["Meter",1.0]]"#,
    );
    let l = shp::read(&p).unwrap();
    match &l.crs {
        Crs::Projected {
            epsg: None, proj4, ..
        } => assert!(proj4.contains("+datum=OSGB36"), "{proj4}"),
        other => panic!("{other:?}"),
    }
}

// ---- GeoJSON ---------------------------------------------------------------------------------

#[test]
fn geojson_with_a_utf8_bom_is_accepted() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read(data("bubenec/streets.geojson")).unwrap();
    let mut bom = b"\xEF\xBB\xBF".to_vec();
    bom.extend_from_slice(&text);
    let p = write(dir.path(), "s.geojson", &bom);
    let l = geojson_reader::read(&p).unwrap();
    assert_eq!(l.features.len(), 35);
    assert_eq!(l.crs, Crs::WebMercator);
}

#[test]
fn geojson_empty_file_is_empty() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "e.geojson", "  \n");
    assert!(matches!(
        geojson_reader::read(&p),
        Err(ImportError::Empty { .. })
    ));
}

#[test]
fn geojson_truncated_is_a_json_error() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read(data("bubenec/streets.geojson")).unwrap();
    let p = write(dir.path(), "t.geojson", &text[..text.len() / 2]);
    let e = geojson_reader::read(&p).unwrap_err();
    assert!(matches!(e, ImportError::Json { .. }), "{e:?}");
    assert!(std::error::Error::source(&e).is_some());
}

#[test]
fn geojson_top_level_array_is_a_format_error() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "a.geojson", "[1, 2, 3]");
    assert!(matches!(
        geojson_reader::read(&p),
        Err(ImportError::Format { .. })
    ));
}

#[test]
fn geojson_collection_without_features_is_a_format_error() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "a.geojson", r#"{"type":"FeatureCollection"}"#);
    let e = geojson_reader::read(&p).unwrap_err();
    assert!(matches!(e, ImportError::Format { .. }), "{e:?}");
    assert!(e.to_string().contains("features"), "{e}");
}

#[test]
fn geojson_unknown_type_is_a_format_error() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "a.geojson", r#"{"type":"Circle","radius":3}"#);
    assert!(matches!(
        geojson_reader::read(&p),
        Err(ImportError::Format { .. })
    ));
}

#[test]
fn geojson_crs_member_with_unknown_epsg_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(
        dir.path(),
        "a.geojson",
        format!(
            r#"{{"type":"FeatureCollection","crs":{{"type":"name","properties":{{"name":"urn:ogc:def:crs:EPSG::99999"}}}},"features":[{}]}}"#,
            square(385_000.0, 6_672_000.0, 10.0)
        ),
    );
    let e = geojson_reader::read(&p).unwrap_err();
    assert!(
        matches!(
            e,
            ImportError::Crs {
                source: CrsError::UnknownEpsg { code: 99999 },
                ..
            }
        ),
        "{e:?}"
    );
}

#[test]
fn geojson_crs_member_without_a_name_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(
        dir.path(),
        "a.geojson",
        format!(
            r#"{{"type":"FeatureCollection","crs":{{"type":"name"}},"features":[{}]}}"#,
            square(1.0, 1.0, 0.1)
        ),
    );
    assert!(matches!(
        geojson_reader::read(&p),
        Err(ImportError::Crs {
            source: CrsError::NotWkt { .. },
            ..
        })
    ));
}

#[test]
fn geojson_bad_features_are_refused_one_by_one_and_grouped() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(
        dir.path(),
        "a.geojson",
        format!(
            "{FC_START}{},{},{},{},{},{},{}]}}",
            square(24.9, 60.1, 0.001),
            r#"{"type":"Feature","properties":{},"geometry":null}"#,
            r#"{"type":"Feature","properties":{},"geometry":null}"#,
            r#"{"type":"Feature","properties":{},"geometry":{"type":"Polygon","coordinates":[[[1]]]}}"#,
            r#"{"type":"Feature","properties":{},"geometry":{"type":"MultiPolygon","coordinates":[]}}"#,
            r#"{"type":"Feature","properties":{},"geometry":{"type":"Blob","coordinates":[]}}"#,
            r#"{"type":"Feature","properties":{},"geometry":{"type":"Polygon","coordinates":[]}}"#,
        ),
    );
    let l = geojson_reader::read(&p).unwrap();
    assert_eq!((l.report.read, l.features.len()), (7, 1));
    let fids: Vec<u64> = l.report.refused.iter().map(|r| r.fid).collect();
    assert_eq!(fids, [1, 2, 3, 4, 5, 6]);
    let g = &l.report.refused_by_reason;
    assert_eq!(g[0].count, 2);
    assert_eq!(g[0].reason, "null geometry");
    assert_eq!(g.iter().map(|g| g.count).sum::<usize>(), 6);
    assert!(l.report.refused[2].reason.contains("fewer than 2"));
    assert!(l.report.refused[3].reason.contains("empty MultiPolygon"));
}

#[test]
fn geojson_in_metres_without_crs_is_unknown_with_a_note() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(
        dir.path(),
        "a.geojson",
        format!("{FC_START}{}]}}", square(385_000.0, 6_672_000.0, 10.0)),
    );
    let l = geojson_reader::read(&p).unwrap();
    assert_eq!(l.crs, Crs::Unknown);
    assert!(l.report.notes.iter().any(|n| n.contains("not degrees")));
}

// ---- OSM PBF ---------------------------------------------------------------------------------

#[test]
fn pbf_empty_file_is_empty_not_an_empty_layer() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "e.osm.pbf", b"");
    let e = osm::read(&p, &Theme::Buildings).unwrap_err();
    assert!(matches!(e, ImportError::Empty { .. }), "{e:?}");
}

#[test]
fn pbf_truncated_is_truncated_not_an_empty_layer() {
    let dir = tempfile::tempdir().unwrap();
    let b = std::fs::read(data("originals/Helsinki.osm.pbf")).unwrap();
    for cut in [b.len() / 2, b.len() - 1, 20] {
        let p = write(dir.path(), "t.osm.pbf", &b[..cut]);
        let e = osm::read(&p, &Theme::Buildings).unwrap_err();
        assert!(
            matches!(e, ImportError::Truncated { .. }),
            "cut {cut}: {e:?}"
        );
        assert!(e.to_string().contains("t.osm.pbf"));
    }
}

#[test]
fn pbf_header_only_has_no_data() {
    let dir = tempfile::tempdir().unwrap();
    let b = std::fs::read(data("originals/Helsinki.osm.pbf")).unwrap();
    let hlen = u32::from_be_bytes([b[0], b[1], b[2], b[3]]) as usize;
    // BlobHeader: field 1 "OSMHeader", field 3 datasize (varint).
    let h = &b[4..4 + hlen];
    let mut pos = 2 + h[1] as usize + 1;
    let (mut size, mut shift) = (0usize, 0);
    loop {
        let byte = h[pos];
        pos += 1;
        size |= ((byte & 0x7f) as usize) << shift;
        shift += 7;
        if byte & 0x80 == 0 {
            break;
        }
    }
    let p = write(dir.path(), "h.osm.pbf", &b[..4 + hlen + size]);
    let e = osm::read(&p, &Theme::Streets).unwrap_err();
    assert!(matches!(e, ImportError::Empty { .. }), "{e:?}");
    assert!(e.to_string().contains("no OSMData"), "{e}");
}

#[test]
fn pbf_that_does_not_start_with_a_header_is_a_format_error() {
    let dir = tempfile::tempdir().unwrap();
    // A BlobHeader of type "OSMData" with datasize 0.
    let header = [b"\x0a\x07OSMData".as_slice(), b"\x18\x00"].concat();
    let mut b = (header.len() as u32).to_be_bytes().to_vec();
    b.extend_from_slice(&header);
    let p = write(dir.path(), "d.osm.pbf", &b);
    let e = osm::read(&p, &Theme::Buildings).unwrap_err();
    assert!(matches!(e, ImportError::Format { .. }), "{e:?}");
    assert!(e.to_string().contains("OSMHeader"), "{e}");
}

#[test]
fn pbf_with_an_absurd_header_length_is_a_format_error() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "g.osm.pbf", b"\xff\xff\xff\xffgarbage");
    assert!(matches!(
        osm::read(&p, &Theme::Buildings),
        Err(ImportError::Format { .. })
    ));
}

/// Protobuf: a varint.
fn varint(mut v: u64, out: &mut Vec<u8>) {
    while v >= 0x80 {
        out.push((v as u8) | 0x80);
        v >>= 7;
    }
    out.push(v as u8);
}

/// Protobuf: field `n` as a length-delimited `bytes`.
fn bytes_field(n: u64, b: &[u8], out: &mut Vec<u8>) {
    varint((n << 3) | 2, out);
    varint(b.len() as u64, out);
    out.extend_from_slice(b);
}

/// Protobuf: field `n` as a varint.
fn varint_field(n: u64, v: u64, out: &mut Vec<u8>) {
    varint(n << 3, out);
    varint(v, out);
}

/// One PBF file block: BlobHeader of `kind`, then a Blob holding `data` uncompressed.
fn pbf_block(kind: &str, data: &[u8], out: &mut Vec<u8>) {
    let mut blob = Vec::new();
    bytes_field(1, data, &mut blob); // raw
    varint_field(2, data.len() as u64, &mut blob); // raw_size
    let mut header = Vec::new();
    bytes_field(1, kind.as_bytes(), &mut header);
    varint_field(3, blob.len() as u64, &mut header); // datasize
    out.extend_from_slice(&(header.len() as u32).to_be_bytes());
    out.extend_from_slice(&header);
    out.extend_from_slice(&blob);
}

/// A dense node whose latitude, times the block's granularity, overflows 64 bits: `osmpbf`'s
/// coordinate arithmetic panics on it where overflow checks are on (the test profile), and the
/// reader says the file is corrupt instead of ending the process. Found by the `osm_pbf` fuzz
/// target.
#[test]
fn pbf_with_coordinates_that_overflow_is_a_format_error() {
    let dir = tempfile::tempdir().unwrap();
    let mut header_block = Vec::new();
    bytes_field(4, b"OsmSchema-V0.6", &mut header_block);
    bytes_field(4, b"DenseNodes", &mut header_block);
    let zigzag = |v: i64| ((v << 1) ^ (v >> 63)) as u64;
    let mut dense = Vec::new();
    for (field, v) in [(1, 7i64), (8, 4_000_000_000_000_000_000 / 100 * 3), (9, 1)] {
        let mut packed = Vec::new();
        varint(zigzag(v), &mut packed);
        bytes_field(field, &packed, &mut dense);
    }
    let mut group = Vec::new();
    bytes_field(2, &dense, &mut group);
    let mut strings = Vec::new();
    bytes_field(1, b"", &mut strings);
    let mut block = Vec::new();
    bytes_field(1, &strings, &mut block);
    bytes_field(2, &group, &mut block);
    varint_field(17, 100, &mut block); // granularity
    let mut file = Vec::new();
    pbf_block("OSMHeader", &header_block, &mut file);
    pbf_block("OSMData", &block, &mut file);
    let p = write(dir.path(), "o.osm.pbf", &file);
    for theme in [Theme::Buildings, Theme::Streets] {
        match osm::read(&p, &theme) {
            Err(e @ ImportError::Format { .. }) => {
                assert!(e.to_string().contains("o.osm.pbf"), "{e}");
                assert!(e.to_string().contains("corrupt"), "{e}");
            }
            // Without overflow checks (a release build) the arithmetic wraps: the node is
            // read, and no way refers to it.
            Ok(l) => {
                if cfg!(debug_assertions) {
                    panic!("read with overflow checks on: {l:?}");
                }
                assert!(l.features.is_empty());
            }
            Err(e) => panic!("{e:?}"),
        }
    }
}

// ---- GeoPackage ------------------------------------------------------------------------------

#[test]
fn gpkg_empty_file_is_empty() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "e.gpkg", b"");
    assert!(matches!(
        gpkg::read(&p, &Theme::Any),
        Err(ImportError::Empty { .. })
    ));
}

#[test]
fn gpkg_not_sqlite_is_an_sqlite_error_with_its_cause() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "x.gpkg", b"SQLite format 2, not really");
    let e = gpkg::read(&p, &Theme::Any).unwrap_err();
    assert!(matches!(e, ImportError::Sqlite { .. }), "{e:?}");
    assert!(std::error::Error::source(&e).is_some());
}

#[test]
fn gpkg_truncated_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let b = std::fs::read(data("originals/bubenec.gpkg")).unwrap();
    let p = write(dir.path(), "t.gpkg", &b[..b.len() / 3]);
    let e = gpkg::read(&p, &Theme::Buildings).unwrap_err();
    assert!(matches!(e, ImportError::Sqlite { .. }), "{e:?}");
}

#[test]
fn gpkg_unknown_table_lists_the_tables() {
    let e = gpkg::read(
        &data("originals/bubenec.gpkg"),
        &Theme::Table("nope".into()),
    )
    .unwrap_err();
    assert!(matches!(e, ImportError::Format { .. }), "{e:?}");
    assert!(e.to_string().contains("buildings"), "{e}");
}

// ---- Any reader ------------------------------------------------------------------------------

#[test]
fn unknown_extension_is_unsupported() {
    assert!(matches!(
        read_layer(Path::new("city.dwg"), &Theme::Any),
        Err(ImportError::Unsupported { .. })
    ));
}

#[test]
fn missing_file_is_io() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["a.shp", "a.geojson", "a.gpkg", "a.osm.pbf"] {
        let e = read_layer(&dir.path().join(name), &Theme::Any).unwrap_err();
        assert!(matches!(e, ImportError::Io { .. }), "{name}: {e:?}");
    }
}

#[test]
fn numbers_in_text_are_read_whole() {
    let t = |s: &str| AttrValue::Text(s.into()).as_f64();
    assert_eq!(t("1e9"), Some(1e9));
    assert_eq!(t("2.5E+1 m"), Some(25.0));
    assert_eq!(t("12.13 m"), Some(12.13));
    assert_eq!(t("12,5"), Some(12.5));
    assert_eq!(t("5;6"), Some(5.0));
    assert_eq!(t("-3"), Some(-3.0));
    assert_eq!(t("1e999"), None);
    assert_eq!(t("inf"), None);
    assert_eq!(t("NaN"), None);
    assert_eq!(t("tall"), None);
    assert_eq!(t(""), None);
    assert_eq!(AttrValue::Float(f64::NAN).as_f64(), None);
}

/// A column projection gives the features of a full read with only the columns asked for, and
/// a value that cannot be read in a column not asked for costs its feature nothing, while in a
/// column asked for it refuses the feature as before.
#[test]
fn shp_column_projection_skips_other_columns() {
    use blockwalk_importers::{read_layer_with, Columns};
    let full = shp::read(&data("helsinki/buildings.shp")).unwrap();
    let cols = Columns::only(["height", "levels", "no_such_column"]);
    let part = read_layer_with(&data("helsinki/buildings.shp"), &Theme::Any, &cols).unwrap();
    assert_eq!(part.report, full.report);
    assert_eq!(part.features.len(), full.features.len());
    for (a, b) in part.features.iter().zip(&full.features) {
        assert_eq!((a.fid, &a.geometry), (b.fid, &b.geometry));
        let want: Vec<_> = b
            .attributes
            .iter()
            .filter(|(k, _)| *k == "height" || *k == "levels")
            .collect();
        assert_eq!(a.attributes.iter().collect::<Vec<_>>(), want);
    }
    assert!(full.features[0].attributes.len() > 2);

    // A numeric field of the first record overwritten with letters.
    let dir = tempfile::tempdir().unwrap();
    let shp_path = copy_shp("helsinki/buildings", dir.path());
    let dbf = dir.path().join("l.dbf");
    let mut bytes = std::fs::read(&dbf).unwrap();
    let reader = shapefile::dbase::Reader::from_path(&dbf).unwrap();
    let (mut off, mut target) = (0usize, None);
    for f in reader.fields() {
        if f.name() == "levels" {
            target = Some((off, f.length() as usize));
        }
        off += f.length() as usize;
    }
    let (off, len) = target.expect("a levels field");
    let header_len = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    let start = header_len + 1 + off;
    bytes[start..start + len].fill(b'x');
    std::fs::write(&dbf, bytes).unwrap();
    // The bad value costs that value (read as empty, with a note naming the record), not the
    // feature; in a column not asked for it is not even looked at.
    let bad_all = shp::read(&shp_path).unwrap();
    assert!(
        bad_all.report.refused.is_empty(),
        "{:?}",
        bad_all.report.refused
    );
    assert_eq!(bad_all.features.len(), full.features.len());
    let names_it = |l: &blockwalk_importers::Layer| {
        l.report
            .notes
            .iter()
            .any(|n| n.contains("record 0 levels = \"xxxx"))
    };
    assert!(names_it(&bad_all), "{:?}", bad_all.report.notes);
    let skipped = shp::read_with(&shp_path, &Columns::only(["height"])).unwrap();
    assert!(skipped.report.refused.is_empty());
    assert!(!names_it(&skipped), "{:?}", skipped.report.notes);
    assert_eq!(skipped.features.len(), full.features.len());
    let asked = shp::read_with(&shp_path, &Columns::only(["levels"])).unwrap();
    assert!(asked.report.refused.is_empty());
    assert!(names_it(&asked), "{:?}", asked.report.notes);
}
