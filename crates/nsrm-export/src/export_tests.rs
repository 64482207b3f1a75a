//! The unit tests of `export` (moved beside it to keep the file short).

#[test]
fn an_unmeasurable_error_passes_no_limit() {
    use super::{ErrorReport, ErrorStats, ExportError};
    let stats = |mean: f64, max: f64| ErrorStats {
        count: 10,
        mean,
        max,
    };
    let report = |training: ErrorStats| ErrorReport {
        training,
        dense: stats(0.1, 0.2),
        exposures: vec![0.0],
        out_of_range: 0,
    };
    assert!(report(stats(0.1, 0.3)).check_limit(Some(1.0)).is_ok());
    assert!(report(stats(f64::NAN, 0.0)).check_limit(None).is_ok());
    for bad in [
        stats(f64::NAN, 0.0),
        stats(0.1, f64::NAN),
        stats(0.1, f64::INFINITY),
    ] {
        let e = report(bad).check_limit(Some(1.0)).unwrap_err();
        assert!(matches!(e, ExportError::TooInaccurate { .. }));
        let text = e.to_string();
        assert!(
            text.contains("not measurable on the training patches"),
            "{text}"
        );
    }
}

use super::*;
use nsrm::{simulate_named, Grid};

#[test]
fn an_error_that_could_not_be_measured_fails_any_limit() {
    let stats = ErrorStats::from(&[0.1, f64::NAN, 0.2]);
    assert!(stats.max.is_nan());
    let r = ErrorReport {
        training: ErrorStats::from(&[0.1, 0.2]),
        dense: stats,
        exposures: vec![0.0],
        out_of_range: 0,
    };
    assert!(r.max().is_nan());
    assert!(matches!(
        r.check_limit(Some(1e9)),
        Err(ExportError::TooInaccurate { .. })
    ));
    assert!(r.check_limit(None).is_ok());
    // The worse of two measurements keeps the NaN.
    let fine = ErrorReport {
        dense: ErrorStats::from(&[0.3]),
        ..r.clone()
    };
    assert!(fine.worst(&r).max().is_nan());
    assert!(fine.check_limit(Some(0.5)).is_ok());
}

fn data() -> nsrm::TrainingSet {
    simulate_named("nikon-d5100", "D65", "rawtoaces-190", &Grid::default()).unwrap()
}

#[test]
fn lrm_is_one_exact_matrix() {
    let d = data();
    let m = nsrm::fit(Kind::Lrm, 1, &d).unwrap();
    for (space, _) in OutputSpace::ALL {
        let e = LutExport::clf(&m, space, LutOptions::default(), &d.rgb).unwrap();
        assert!(e.exact);
        assert_eq!(e.nodes.len(), 1);
        let r = e.measure(&d.rgb).unwrap();
        assert!(r.max() < 1e-9, "{space:?} {}", r.summary());
        let x = [0.3, 0.5, 0.2];
        let a = e.eval(x);
        let b = e.folded.apply_f64(x);
        for k in 0..3 {
            assert!((a[k] - b[k]).abs() <= 1e-12);
        }
    }
}

#[test]
fn nsrm3_default_lut_is_within_a_tenth_of_a_de00() {
    let d = data();
    let m = nsrm::fit(Kind::Nsrm, 3, &d).unwrap();
    let e = LutExport::clf(&m, OutputSpace::Acescg, LutOptions::default(), &d.rgb).unwrap();
    let r = e.measure(&d.rgb).unwrap();
    assert!(r.dense.count > 1000, "{}", r.summary());
    assert!(r.max() <= 0.1, "{}", r.summary());
    assert!(r.max() > 0.0);
}

#[test]
fn white_balanced_nsrm_luts_evaluate_the_model_with_its_gains() {
    use nsrm::{fit_with, FitOptions, Normalise};
    let d = data();
    let opts = FitOptions {
        normalise: Normalise::WhiteBalanced,
        ..Default::default()
    };
    let wb = fit_with(Kind::Nsrm, 3, &d, &opts).unwrap().model;
    assert!(!wb.has_unit_gains());
    let raw = wb.clone().with_input_gains([1.0; 3]).unwrap();
    let e = LutExport::clf(&wb, OutputSpace::Acescg, LutOptions::default(), &d.rgb).unwrap();
    assert_eq!(e.folded.input_gains(), wb.input_gains());
    let r = e.measure(&d.rgb).unwrap();
    assert!(r.max() <= 0.1, "{}", r.summary());
    // The chain follows the gained model, not the same matrix without gains.
    let raw_folded = fold(&raw, OutputSpace::Acescg).unwrap();
    let (mut to_wb, mut to_raw) = (0.0f64, 0.0f64);
    for &c in &d.rgb {
        let got = e.eval(c);
        let (a, b) = (e.folded.apply_f64(c), raw_folded.apply_f64(c));
        for k in 0..3 {
            to_wb = to_wb.max((got[k] - a[k]).abs());
            to_raw = to_raw.max((got[k] - b[k]).abs());
        }
    }
    assert!(to_raw > 10.0 * to_wb, "{to_wb} vs {to_raw}");
    let cube = LutExport::cube(&wb, OutputSpace::Xyz, LutOptions::default()).unwrap();
    assert_eq!(cube.folded.input_gains(), wb.input_gains());
}

#[test]
fn a_coarse_lut_is_measured_as_coarse() {
    let d = data();
    let m = nsrm::fit(Kind::Rprm, 3, &d).unwrap();
    let fine = LutExport::clf(&m, OutputSpace::Xyz, LutOptions::default(), &d.rgb).unwrap();
    let coarse = LutExport::clf(
        &m,
        OutputSpace::Xyz,
        LutOptions {
            size: 9,
            ..Default::default()
        },
        &d.rgb,
    )
    .unwrap();
    let (f, c) = (
        fine.measure(&d.rgb).unwrap(),
        coarse.measure(&d.rgb).unwrap(),
    );
    assert!(
        c.max() > 4.0 * f.max(),
        "{} vs {}",
        c.summary(),
        f.summary()
    );
}

#[test]
fn bad_options_are_refused() {
    let d = data();
    let m = nsrm::fit(Kind::Nsrm, 2, &d).unwrap();
    for size in [0, 1, 130, 1_000_000] {
        let o = LutOptions {
            size,
            ..Default::default()
        };
        let e = LutExport::clf(&m, OutputSpace::Xyz, o, &d.rgb).unwrap_err();
        assert!(matches!(e, ExportError::Usage(_)), "{e}");
        assert!(e.to_string().contains("LUT size"), "{e}");
    }
    let o = LutOptions {
        stops: [3.0, 2.0],
        ..Default::default()
    };
    assert!(LutExport::cube(&m, OutputSpace::Xyz, o).is_err());
}

#[test]
fn dense_set_lies_inside_the_hull() {
    let d = data();
    let pts = dense_chromaticities(&d.rgb, 0.02);
    assert!(pts.len() > 50);
    for (r, g) in pts {
        assert!(r > 0.0 && g > 0.0 && r + g < 1.0);
    }
}
