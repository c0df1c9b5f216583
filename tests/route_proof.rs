//! Culling checked over whole routes (`blockwalk cull-proof`'s library call) on Bubeneč: a few
//! frames of every generated route, the corner walk included, through every block structure at
//! three cull map resolutions, with the per-building test. No false cull, the counts add up,
//! and a deliberately broken culler (one visible block dropped per cull) is caught on every
//! checked frame.

mod support;
use blockwalk::index::Structure;
use blockwalk::route::RouteChoice;
use blockwalk::scene::CitySource;
use blockwalk::visibility::route_proof::{Dropped, ProofOptions, Sabotage};
use blockwalk::walk::{run_route_proof, Quiet, RouteProofJob, RouteProofReport};
use std::collections::BTreeSet;
use support::data::data;

/// Frames per route.
const FRAMES: usize = 6;

fn job(sabotage: Option<Sabotage>) -> RouteProofJob {
    let source = CitySource::parse(
        &data("bubenec/buildings.shp"),
        Some(data("bubenec/streets.shp")),
        None,
        &[],
        0,
    )
    .unwrap();
    RouteProofJob {
        cities: vec![(source, FRAMES)],
        routes: RouteChoice::GENERATED.to_vec(),
        proof: ProofOptions {
            sabotage,
            ..ProofOptions::default()
        },
    }
}

/// Every route, structure and resolution present once, with every frame counted once.
fn check_counts(report: &RouteProofReport) {
    let resolutions = ProofOptions::default().resolutions;
    assert_eq!(report.cities.len(), 1);
    let city = &report.cities[0];
    let names: Vec<&str> = city.routes.iter().map(|r| r.route.as_str()).collect();
    assert_eq!(names, RouteChoice::NAMES);
    let want: BTreeSet<(Structure, u32)> = Structure::ALL
        .iter()
        .flat_map(|&s| resolutions.iter().map(move |&r| (s, r)))
        .collect();
    for r in &city.routes {
        assert_eq!(r.frames, FRAMES as u64, "{}", r.route);
        assert_eq!(r.checked + r.vacuous.total(), r.frames, "{}", r.route);
        let got: BTreeSet<(Structure, u32)> = r
            .tallies
            .iter()
            .map(|t| (t.structure, t.resolution))
            .collect();
        assert_eq!(got, want, "{}", r.route);
        assert_eq!(r.tallies.len(), want.len(), "{}", r.route);
        for t in &r.tallies {
            assert_eq!(t.frames, r.frames, "{} {:?}", r.route, t.structure);
            assert!(t.blocks_culled <= t.blocks_in_frustum);
            assert!(t.buildings_culled <= t.buildings_in_frustum);
        }
    }
    assert_eq!(report.frames, (FRAMES * RouteChoice::NAMES.len()) as u64);
    let vacuous: u64 = city.routes.iter().map(|r| r.vacuous.total()).sum();
    assert_eq!(report.vacuous, vacuous);
}

#[test]
fn bubenec_routes_cull_nothing_the_oracle_sees() {
    let report = run_route_proof(&job(None), &Quiet).unwrap();
    check_counts(&report);
    let city = &report.cities[0];
    assert_eq!(
        report.false_culls, 0,
        "false culls: {:#?}",
        city.false_cull_examples
    );
    assert!(report.passed());
    assert!(city.false_cull_examples.is_empty());
    // Not vacuous: most frames see something, and the cull maps hide blocks on some route.
    let checked: u64 = city.routes.iter().map(|r| r.checked).sum();
    assert!(
        checked * 2 > report.frames,
        "{checked} of {}",
        report.frames
    );
    for r in &city.routes {
        assert!(r.visible_blocks > 0, "{} sees nothing", r.route);
    }
    let culled: u64 = city
        .routes
        .iter()
        .flat_map(|r| &r.tallies)
        .map(|t| t.blocks_culled)
        .sum();
    assert!(culled > 0, "the cull maps never hid a block");
}

#[test]
fn a_culler_that_drops_a_visible_block_is_caught() {
    let report = run_route_proof(&job(Some(Sabotage::DropVisibleBlock)), &Quiet).unwrap();
    check_counts(&report);
    assert!(!report.passed());
    let city = &report.cities[0];
    for r in &city.routes {
        for t in &r.tallies {
            // Every checked frame sees a block, and the broken culler drops one of them.
            assert!(
                t.false_block_culls >= r.checked,
                "{} {:?} {}: {} false culls over {} checked frames",
                r.route,
                t.structure,
                t.resolution,
                t.false_block_culls,
                r.checked
            );
        }
    }
    let first = city.false_cull_examples.first().expect("examples");
    assert_eq!(first.city, city.city);
    assert!(matches!(first.dropped, Dropped::Block(_)), "{first:?}");
    assert!(RouteChoice::NAMES.contains(&first.route.as_str()));
    assert!(city.false_cull_examples.len() <= ProofOptions::default().max_examples);
}
