//! Parameters are checked where they are built: each refusal names the parameter and the problem.

use blockwalk::blockmap::select::{SelectError, SelectOptions};
use blockwalk::blockmap::BuildOptions;

#[test]
fn tau_must_be_a_finite_positive_number_of_pixels() {
    for tau in [f64::NAN, -1.0, 0.0, f64::INFINITY] {
        let e = SelectOptions::new(tau, 0.25).unwrap_err();
        assert!(matches!(e, SelectError::BadTau(_)), "{tau}: {e}");
        assert!(e.to_string().starts_with("tau "), "{e}");
    }
    let o = SelectOptions::new(2.0, 0.25).unwrap();
    assert_eq!((o.tau_px, o.hysteresis), (2.0, 0.25));
}

#[test]
fn the_hysteresis_must_be_in_zero_to_one() {
    for h in [f64::NAN, -0.1, 1.0, 3.0, f64::INFINITY] {
        let e = SelectOptions::new(1.0, h).unwrap_err();
        assert!(matches!(e, SelectError::BadHysteresis(_)), "{h}: {e}");
        assert!(e.to_string().contains("[0, 1)"), "{e}");
    }
    assert!(SelectOptions::new(1.0, 0.0).is_ok());
}

fn refused(o: BuildOptions, needle: &str) {
    let e = o.validate().unwrap_err().to_string();
    assert!(e.contains(needle), "{needle}: {e}");
}

#[test]
fn blockmap_options_are_checked() {
    let d = BuildOptions::default();
    assert!(d.validate().is_ok());
    refused(BuildOptions { k: 48, ..d }, "not a power of two");
    refused(BuildOptions { k: 256, ..d }, "out of range");
    refused(BuildOptions { k: 16, ..d }, "k = 16");
    refused(
        BuildOptions {
            min_slice_rows: 1,
            ..d
        },
        "min_slice_rows",
    );
    refused(
        BuildOptions {
            fill_samples: 0,
            ..d
        },
        "fill_samples = 0",
    );
    refused(
        BuildOptions {
            fill_samples: 9,
            ..d
        },
        "fill_samples = 9",
    );
    refused(
        BuildOptions {
            fill_share: 0.0,
            ..d
        },
        "fill_share",
    );
    refused(
        BuildOptions {
            fill_share: f64::NAN,
            ..d
        },
        "fill_share",
    );
    refused(
        BuildOptions {
            fill_share: 1.5,
            ..d
        },
        "fill_share",
    );
    refused(
        BuildOptions {
            ao: true,
            ao_radius_m: -1.0,
            ..d
        },
        "ao_radius_m",
    );
}
