//! Reading only the footprint columns the buildings are made from (`footprint_columns`, what
//! `blockwalk import` does without `--cityjson`) gives the same buildings and the same meshes
//! as reading every column, on the bundled data and on a generated city.

mod support;
use std::path::{Path, PathBuf};
use support::data::data;

use blockwalk::city::build::{footprint_columns, BuildOptions};
use blockwalk::city::extrude::extrude_city;
use blockwalk::city::generate::{generate_city, write_city, GenerateParams};
use blockwalk::importers::Columns;
use blockwalk::scene::CitySource;

fn same_city(input: &Path, streets: Option<PathBuf>) {
    let source = CitySource::parse(input, streets, None, &[], 0).unwrap();
    let opts = BuildOptions::default();
    let all = source
        .load_with_columns(&opts, &Columns::All, &mut |_| {})
        .unwrap()
        .city;
    let some = source
        .load_with_columns(&opts, &footprint_columns(&opts.heights), &mut |_| {})
        .unwrap()
        .city;
    assert_eq!(all.buildings.len(), some.buildings.len());
    assert_eq!(all.frame, some.frame);
    assert_eq!(all.streets.len(), some.streets.len());
    let mut dropped = 0;
    for (a, b) in all.buildings.iter().zip(&some.buildings) {
        assert_eq!(
            (&a.source_id, &a.footprint, a.height_m, a.min_height_m),
            (&b.source_id, &b.footprint, b.height_m, b.min_height_m)
        );
        assert_eq!(a.height_source, b.height_source);
        // The kept columns are the full read's, restricted.
        assert!(b
            .attributes
            .iter()
            .all(|(k, v)| a.attributes.get(k) == Some(v)));
        dropped += a.attributes.len() - b.attributes.len();
    }
    assert_eq!(
        serde_json::to_value(&all.report).unwrap(),
        serde_json::to_value(&some.report).unwrap()
    );
    assert_eq!(
        extrude_city(&all),
        extrude_city(&some),
        "{}",
        input.display()
    );
    assert!(dropped > 0, "{}: no column was left out", input.display());
}

#[test]
fn helsinki_buildings_are_the_same_with_fewer_columns() {
    same_city(
        &data("helsinki/buildings.shp"),
        Some(data("helsinki/streets_blockclass.shp")),
    );
}

#[test]
fn bubenec_buildings_are_the_same_with_fewer_columns() {
    same_city(
        &data("bubenec/buildings.shp"),
        Some(data("bubenec/streets.shp")),
    );
}

#[test]
fn generated_buildings_are_the_same_with_fewer_columns() {
    let dir = tempfile::tempdir().unwrap();
    let city = generate_city(&GenerateParams {
        buildings: 3000,
        seed: 5,
        ..Default::default()
    })
    .unwrap();
    write_city(&city, dir.path()).unwrap();
    same_city(dir.path(), None);
}
