//! Chart capture, step by step: synthetic scenes with known truth, read back by corners and by
//! detection, with the flat-field estimates; the synthetic chart's layout file. (Once
//! `tests/all/chart.rs` and a test of `tests/all/io.rs`; here since detection, extraction, the
//! flat field and the layout file's reader are crate-private.)

use super::detect::{detect, DetectOptions};
use super::extract::{extract, verify, ExtractOptions, Extraction};
use super::flat::from_neutrals as flat_from_neutrals;
use super::flat::{apply as apply_flat, from_flat_frame as flat_from_frame};
use super::scene::{self, render, ChartColours, Family, SceneOptions, SceneTruth};
use super::{homography_from_corners, ChartKind, Reference};
use crate::kit::skip_or_fail;
use nsrm::Kind;
use nsrm::TrainingSet;
// Evaluation sits above `chart`: through the public API, as an integration test would.
use nsrm::{evaluate, Protocol};

const SG_SPECTRA: &str = "../../../shared/data/colorchecker_sg_140.csv";

fn cc24() -> ChartColours {
    ChartColours::simulate(ChartKind::Cc24, "nikon-d5100", "D65", None).unwrap()
}

/// The SG simulated from [`SG_SPECTRA`], or from `$NSRM_SHARED/data/` (a worktree elsewhere)
/// when that is absent.
fn sg() -> Option<ChartColours> {
    let mut path = std::path::PathBuf::from(SG_SPECTRA);
    if let (false, Some(shared)) = (path.exists(), std::env::var_os("NSRM_SHARED")) {
        path = std::path::PathBuf::from(shared).join("data/colorchecker_sg_140.csv");
    }
    if !path.exists() {
        skip_or_fail(&format!("{SG_SPECTRA} not found"));
        return None;
    }
    let path = path.to_str().expect("a UTF-8 path");
    Some(ChartColours::simulate(ChartKind::Sg, "nikon-d5100", "D65", Some(path)).unwrap())
}

/// The true pitch (frame pixels from one cell to the next along the rows) at the chart's centre:
/// the unit of "a quarter pitch off".
fn centre_pitch(kind: ChartKind, truth: &SceneTruth) -> f64 {
    let c = [kind.columns() as f64 / 2.0, kind.rows() as f64 / 2.0];
    let (a, b) = (
        truth.homography.apply(c),
        truth.homography.apply([c[0] + 1.0, c[1]]),
    );
    (a[0] - b[0]).hypot(a[1] - b[1])
}

/// Panics unless every patch of `ex` was read within a quarter pitch of its true centre.
fn assert_placed(ex: &Extraction, truth: &SceneTruth, what: &str) {
    let pitch = centre_pitch(ex.chart, truth);
    for (p, t) in ex.patches.iter().zip(&truth.patches) {
        let off = (p.centre[0] - t.centre[0]).hypot(p.centre[1] - t.centre[1]);
        assert!(off < 0.25 * pitch, "{what}: {} is {off:.1} px off", p.label);
    }
}

/// Detection without the second, coarser search.
fn first_search_only() -> DetectOptions {
    DetectOptions {
        retry_side: DetectOptions::default().max_side,
        coarse_side: DetectOptions::default().max_side,
        ..DetectOptions::default()
    }
}

/// Detects the chart (default options), reads it and checks every patch against the truth
/// ([`assert_placed`]); the detection.
fn found_in_place(
    frame: &nsrm::Frame,
    reference: &Reference,
    truth: &SceneTruth,
    what: &str,
) -> super::detect::Detection {
    let d = detect(frame, reference, &DetectOptions::default())
        .unwrap_or_else(|e| panic!("{what}: {}", e.error));
    let ex = extract(frame, reference, &d.homography, &ExtractOptions::default()).unwrap();
    assert_placed(&ex, truth, what);
    d
}

/// A CC24 scene of `family` that the first search refuses and the full detection (with the
/// second, coarser search) reads with every patch in place: the first search's refusal and the
/// detection.
fn missed_first_found_second(
    family: Family,
    seed: u64,
) -> (super::detect::DetectFailure, super::detect::Detection) {
    let what = format!("{} seed {seed}", family.name());
    let reference = Reference::load("cc24-after2014", ChartKind::Cc24, None).unwrap();
    let (c, opts) = family.scene(&cc24(), 1200, 800, seed);
    let (frame, _, truth) = render(&c, &opts).unwrap();
    let refused = detect(&frame, &reference, &first_search_only())
        .map(|d| d.score)
        .expect_err(&what);
    (refused, found_in_place(&frame, &reference, &truth, &what))
}

/// The perspective limit for charts with cells of the outer ring unseen until the jackknife's
/// limit was tightened (2026-12-03): scenes beyond it are read now when those cells are pinned.
const PERSPECTIVE_LIMIT_BEFORE_PINNING: f64 = 1.6;

/// Renders a CC24 scene and checks it is read with every patch in place
/// ([`found_in_place`]) at a perspective beyond [`PERSPECTIVE_LIMIT_BEFORE_PINNING`].
fn found_beyond_the_old_limit(colours: &ChartColours, opts: &SceneOptions, what: &str) {
    let reference = Reference::load("cc24-after2014", ChartKind::Cc24, None).unwrap();
    let (frame, _, truth) = render(colours, opts).unwrap();
    let d = found_in_place(&frame, &reference, &truth, what);
    assert!(
        d.perspective > PERSPECTIVE_LIMIT_BEFORE_PINNING,
        "{what}: {}",
        d.perspective
    );
}

/// Largest |measured / truth − 1| over patches brighter than `min_g`.
fn worst_ratio(ex: &Extraction, truth: &SceneTruth, min_g: f64) -> f64 {
    ex.patches
        .iter()
        .zip(&truth.patches)
        .filter(|(_, t)| t.rgb[1] > min_g)
        .flat_map(|(p, t)| (0..3).map(move |k| (p.rgb[k] / t.rgb[k] - 1.0).abs()))
        .fold(0.0, f64::max)
}

#[test]
fn corners_and_flat_frame_give_means_within_half_a_percent() {
    let colours = cc24();
    let reference = Reference::load("cc24-after2014", ChartKind::Cc24, None).unwrap();
    let opts = SceneOptions {
        width: 900,
        height: 600,
        corners: Some([
            [150.0, 120.0],
            [760.0, 90.0],
            [780.0, 500.0],
            [130.0, 470.0],
        ]),
        exposure: 0.8,
        noise: 0.0005,
        blur: 0.8,
        vignetting: 0.35,
        gradient: 0.2,
        ..Default::default()
    };
    let (frame, flat_frame, truth) = render(&colours, &opts).unwrap();
    let h = homography_from_corners(ChartKind::Cc24, &truth.corners, 900, 600).unwrap();
    let eo = ExtractOptions::default();
    let mut ex = extract(&frame, &reference, &h, &eo).unwrap();
    assert_eq!(ex.patches.len(), 24);
    assert_eq!(ex.patches[0].label, "01 dark skin");
    // Uneven light is visible before compensation …
    let before = worst_ratio(&ex, &truth, 0.01);
    assert!(before > 0.05, "the light should be uneven: {before}");
    let f = flat_from_frame(&flat_frame, (900, 600), &ex, &eo).unwrap();
    assert!(
        (f.nonuniformity / truth.light_nonuniformity - 1.0).abs() < 0.01,
        "{} vs {}",
        f.nonuniformity,
        truth.light_nonuniformity
    );
    apply_flat(&mut ex, &f);
    // … and gone after it: every patch within 0.5 % of the noise-free truth.
    let after = worst_ratio(&ex, &truth, 0.01);
    assert!(after < 0.005, "worst patch off by {:.3} %", 100.0 * after);
    assert!(ex.patches.iter().all(|p| p.usable()), "{:?}", ex.flagged());
    assert!(verify(&ex, &reference).unwrap() < 3.0);
}

#[test]
fn neutral_patches_estimate_the_light_on_an_sg() {
    let Some(colours) = sg() else { return };
    let reference = Reference::load("sg-before2014", ChartKind::Sg, None).unwrap();
    let opts = SceneOptions {
        width: 900,
        height: 640,
        corners: Some([[80.0, 70.0], [820.0, 90.0], [800.0, 580.0], [100.0, 560.0]]),
        exposure: 0.9,
        noise: 0.0005,
        vignetting: 0.3,
        gradient: 0.25,
        ..Default::default()
    };
    let (frame, _, truth) = render(&colours, &opts).unwrap();
    let h = homography_from_corners(ChartKind::Sg, &truth.corners, 900, 640).unwrap();
    let mut ex = extract(&frame, &reference, &h, &ExtractOptions::default()).unwrap();
    let before = worst_ratio(&ex, &truth, 0.02);
    let f = flat_from_neutrals(&ex, &reference).unwrap();
    assert!(f.fitted_on >= 30, "{}", f.fitted_on);
    apply_flat(&mut ex, &f);
    let after = worst_ratio(&ex, &truth, 0.02);
    // The SG's neutrals are not perfectly neutral to the camera (G/Y varies a little between
    // them), so the surface is a few per cent from the light, against over 20 % uncompensated.
    assert!(
        after < before / 4.0 && after < 0.05,
        "before {before}, after {after}"
    );
    let (est, real) = (f.nonuniformity, truth.light_nonuniformity);
    assert!(
        (est / real - 1.0).abs() < 0.05,
        "non-uniformity {est} estimated, {real} true"
    );
}

#[test]
fn detection_in_the_envelope_is_right_or_refuses() {
    // A few seeded scenes of each chart (the README's rate comes from `nsrm chart rate`).
    let mut charts = vec![(cc24(), 6u64)];
    if let Some(s) = sg() {
        charts.push((s, 3));
    }
    for (colours, n) in charts {
        let kind = colours.chart;
        let reference = Reference::load(kind.default_reference(), kind, None).unwrap();
        let mut correct = 0;
        for seed in 100..100 + n {
            let opts = SceneOptions::envelope(&colours, 960, 640, seed);
            let (frame, _, truth) = render(&colours, &opts).unwrap();
            let Ok(d) = detect(&frame, &reference, &DetectOptions::default()) else {
                continue;
            };
            let Ok(ex) = extract(
                &frame,
                &reference,
                &d.homography,
                &ExtractOptions::default(),
            ) else {
                continue;
            };
            assert_placed(&ex, &truth, &format!("{} seed {seed}", kind.name()));
            correct += 1;
        }
        assert!(
            correct * 3 >= n * 2,
            "{}: {correct} of {n} found",
            kind.name()
        );
    }
}

#[test]
fn outside_the_envelope_old_wrong_answers_are_read_right_or_refused() {
    // The two wrong answers `nsrm chart rate` found outside the envelope: a CC24 tilted 54°
    // (one patch extrapolated 0.30 pitch off) and an SG under blur σ 4.6 px (a placement shifted
    // on a 22-patch lattice, median ΔE00 7.6; now refused by the stricter match limit for found
    // charts). Same scenes as `chart rate --seed 2032 --min-tilt 30.5 --max-tilt 55` and
    // `--seed 4002 --min-blur 1.5 --max-blur 5`. The CC24 was first refused for its
    // perspective; since the fit drops lattice points outside the chart (`refit_inside`) it is
    // read, every patch in place (perspective 1.67, its unseen cells pinned: the jackknife
    // moves them 0.002 pitch).
    let colours = cc24();
    let mut opts = SceneOptions::envelope(&colours, 1200, 800, 2032);
    opts.min_tilt_deg = 30.5;
    opts.max_tilt_deg = 55.0;
    found_beyond_the_old_limit(&colours, &opts, "tilt seed 2032");
    let Some(colours) = sg() else {
        return;
    };
    let kind = colours.chart;
    let reference = Reference::load(kind.default_reference(), kind, None).unwrap();
    let mut opts = SceneOptions::envelope(&colours, 1200, 800, 4002);
    opts.blur = 1.5 + 3.5 * (opts.blur / 1.2);
    let (frame, _, _) = render(&colours, &opts).unwrap();
    let e = detect(&frame, &reference, &DetectOptions::default())
        .map(|d| d.score)
        .expect_err("refused");
    let msg = e.error.to_string();
    // (The SG's blurred lattice now also splits at an empty line, so its part may be refused
    // for its colours instead: either is a refusal, never the shifted placement.)
    assert!(
        ["only loosely", "do not match"]
            .iter()
            .any(|w| msg.contains(w)),
        "sg seed 4002: {msg}"
    );
}

#[test]
fn cells_extrapolated_uncertainly_are_refused() {
    // Misread scenes, each a lattice whose fit got the perspective wrong, with cells of the outer
    // ring unseen and placed by extrapolation; refused by the jackknife over the lattice
    // (EXTRAPOLATION_LIMIT) in the first search, then found by the second, coarser one, which
    // links more of the chart, and read correctly. `chart rate --family passport --seed 59`: a
    // lattice of 12 fitted with perspective 1.46 where the chart's was 1.20, read with 12
    // patches in the wrong cells (worst 0.82 pitch) before the jackknife was asked; it moves
    // them 0.84. `--family wide --seed 1494`: a lattice of 20 fitted with perspective 1.57 where
    // the truth was 2.08, read with 3 patches up to 0.44 pitch off while the limit was 0.25; the
    // jackknife moves them 0.18. `--family tilt --seed 205`: perspective 1.66 fitted, 1.49 true,
    // one patch 0.34 off when the perspective limit was raised; the jackknife 0.17.
    for (family, seed) in [
        (Family::Passport, 59),
        (Family::Wide, 1494),
        (Family::Tilt, 205),
    ] {
        let (refused, _) = missed_first_found_second(family, seed);
        assert!(
            refused.error.to_string().contains("uncertain"),
            "{} seed {seed}: {}",
            family.name(),
            refused.error
        );
    }
    // Strong perspective with the unseen cells pinned is read: `--family tilt --seed 402`,
    // perspective 1.73 (over the limit of 1.6 that held until the jackknife's was tightened),
    // the black patch unseen, the jackknife 0.04: every patch in place.
    let (c, opts) = Family::Tilt.scene(&cc24(), 1200, 800, 402);
    found_beyond_the_old_limit(&c, &opts, "tilt seed 402");
}

#[test]
fn charts_covering_one_percent_of_the_frame_are_found() {
    // Phone photographs of a chart at arm's length: 1–1.5 % of a 2400 × 1600 frame (patches of
    // about 8 pixels in the 1200-pixel image searched, below the regions looked at when a chart
    // had to cover 5 %).
    let colours = cc24();
    let reference = Reference::load("cc24-after2014", ChartKind::Cc24, None).unwrap();
    let mut found = 0;
    for seed in 1..4 {
        let mut opts = SceneOptions::envelope(&colours, 2400, 1600, seed);
        opts.min_area = 0.01;
        opts.max_area = 0.015;
        let (frame, _, truth) = render(&colours, &opts).unwrap();
        let Ok(d) = detect(&frame, &reference, &DetectOptions::default()) else {
            continue;
        };
        let pitch = centre_pitch(ChartKind::Cc24, &truth);
        // Patches 01 and 24 (opposite corners: a rotated placement moves both).
        for cell in [[0.5, 0.5], [5.5, 3.5]] {
            let (t, q) = (truth.homography.apply(cell), d.homography.apply(cell));
            assert!(
                (t[0] - q[0]).hypot(t[1] - q[1]) < 0.25 * pitch,
                "seed {seed}"
            );
        }
        found += 1;
    }
    assert!(found >= 2, "{found} of 3 found");
}

#[test]
fn model_from_extraction_matches_model_from_truth() {
    let colours = cc24();
    let reference = Reference::load("cc24-after2014", ChartKind::Cc24, None).unwrap();
    let opts = SceneOptions {
        noise: 0.001,
        blur: 0.6,
        vignetting: 0.3,
        ..SceneOptions::envelope(&colours, 960, 640, 7)
    };
    let (frame, flat_frame, truth) = render(&colours, &opts).unwrap();
    let d = detect(&frame, &reference, &DetectOptions::default()).unwrap();
    let eo = ExtractOptions::default();
    let mut ex = extract(&frame, &reference, &d.homography, &eo).unwrap();
    let f = flat_from_frame(&flat_frame, (960, 640), &ex, &eo).unwrap();
    apply_flat(&mut ex, &f);
    let measured = ex.training_set(&reference);
    let keep: Vec<usize> = measured
        .labels
        .iter()
        .map(|l| truth.patches.iter().position(|t| &t.label == l).unwrap())
        .collect();
    let from_truth = TrainingSet {
        rgb: keep.iter().map(|&i| truth.patches[i].rgb).collect(),
        ..measured.clone()
    };
    for (kind, order) in [(Kind::Lrm, 1), (Kind::Nsrm, 3), (Kind::Rprm, 2)] {
        let a = evaluate(kind, order, &measured, Protocol::LeaveOneOut, "x").unwrap();
        let b = evaluate(kind, order, &from_truth, Protocol::LeaveOneOut, "x").unwrap();
        assert!(
            (a.stats.mean - b.stats.mean).abs() < 0.05,
            "{kind:?}{order}: LOO ΔE00 {} from the capture vs {} from the truth",
            a.stats.mean,
            b.stats.mean
        );
    }
}

#[test]
fn bad_scenes_fail_clearly() {
    let colours = cc24();
    let reference = Reference::load("cc24-after2014", ChartKind::Cc24, None).unwrap();
    // No chart in the frame: it is placed far outside.
    let nothing = SceneOptions {
        width: 640,
        height: 480,
        corners: Some([
            [5000.0, 5000.0],
            [5600.0, 5000.0],
            [5600.0, 5400.0],
            [5000.0, 5400.0],
        ]),
        clutter: 30,
        ..Default::default()
    };
    let (frame, _, _) = render(&colours, &nothing).unwrap();
    let e = detect(&frame, &reference, &DetectOptions::default()).unwrap_err();
    assert!(
        e.error.to_string().contains("no chart found"),
        "{}",
        e.error
    );
    // Half the chart outside the frame.
    let half = SceneOptions {
        width: 640,
        height: 480,
        corners: Some([
            [300.0, 100.0],
            [900.0, 100.0],
            [900.0, 400.0],
            [300.0, 400.0],
        ]),
        ..Default::default()
    };
    let (frame, _, _) = render(&colours, &half).unwrap();
    let e = detect(&frame, &reference, &DetectOptions::default()).unwrap_err();
    let msg = e.error.to_string();
    assert!(msg.contains("outside") || msg.contains("no chart"), "{msg}");
    // Every patch clipped.
    let hot = SceneOptions {
        width: 640,
        height: 480,
        corners: Some([
            [100.0, 100.0],
            [500.0, 100.0],
            [500.0, 370.0],
            [100.0, 370.0],
        ]),
        exposure: 200.0,
        ..Default::default()
    };
    let (frame, _, truth) = render(&colours, &hot).unwrap();
    let h = homography_from_corners(ChartKind::Cc24, &truth.corners, 640, 480).unwrap();
    let e = extract(&frame, &reference, &h, &ExtractOptions::default()).unwrap_err();
    assert!(e.to_string().contains("clipped"), "{e}");
    // The wrong reference: an SG reference cannot be read off a CC24 (label check), and
    // corners in the wrong order do not match the reference colours.
    let ok = SceneOptions {
        exposure: 0.7,
        ..hot
    };
    let (frame, _, truth) = render(&colours, &ok).unwrap();
    let mut rotated = truth.corners;
    rotated.rotate_left(2);
    let h = homography_from_corners(ChartKind::Cc24, &rotated, 640, 480).unwrap();
    let ex = extract(&frame, &reference, &h, &ExtractOptions::default()).unwrap();
    let e = verify(&ex, &reference).unwrap_err();
    assert!(e.to_string().contains("do not match"), "{e}");
}

/// Scenes of one family (`chart rate --family`) of the chart of `colours`, 720 × 480: (found
/// correctly, refused); panics on a wrong answer — a label off its true cell, or any chart
/// reported in a negative scene.
fn family_outcomes(
    colours: &ChartColours,
    family: Family,
    seeds: std::ops::Range<u64>,
) -> (u32, u32) {
    let kind = colours.chart;
    let reference = Reference::load(kind.default_reference(), kind, None).unwrap();
    let (mut ok, mut refused) = (0, 0);
    for seed in seeds {
        let (c, opts) = family.scene(colours, 720, 480, seed);
        let (frame, _, truth) = render(&c, &opts).unwrap();
        let found = detect(&frame, &reference, &DetectOptions::default());
        let Ok(d) = found else {
            refused += 1;
            continue;
        };
        assert!(
            !family.negative(),
            "{} seed {seed}: a {} reported (score {:.2} vs {:.2}, lattice {})",
            family.name(),
            kind.name(),
            d.score,
            d.runner_up,
            d.lattice
        );
        let Ok(ex) = extract(
            &frame,
            &reference,
            &d.homography,
            &ExtractOptions::default(),
        ) else {
            refused += 1;
            continue;
        };
        assert_placed(&ex, &truth, &format!("{} seed {seed}", family.name()));
        ok += 1;
    }
    (ok, refused)
}

/// What the unit tests ask of each family of CC24 scenes at 720 × 480: the seeds run and the
/// fewest found correctly (never a wrong answer, whatever the family). An exhaustive match, so
/// that a new family cannot go unguarded; `nsrm chart rate --family F` measures the rates
/// (README).
fn family_guard(f: Family) -> (std::ops::Range<u64>, u32) {
    match f {
        Family::Envelope
        | Family::Jpeg
        | Family::Fill
        | Family::Small
        | Family::Passport
        | Family::Tilt
        | Family::BlackFrame => (1..5, 3),
        // Perspective 1.6–2.2: at 720 × 480, seeds 1–40 give 36 found, 4 refused (two beyond
        // the perspective limit, two for unseen cells placed uncertainly), 0 wrong; seeds 1–16,
        // the ones run here, 13 found (1, 6 and 15 refused). Until the jackknife limit replaced
        // the perspective limit of 1.6 for charts with ring cells unseen: 14 of 40, 6 of 16.
        Family::Wide => (1..17, 12),
        // New families (2026-12-06), measured with `chart rate` at 1200 × 800 only: here every
        // answer must be right, none need be given.
        Family::Graded | Family::Noisy | Family::Litter => (1..4, 0),
        // Negatives: every scene refused (`family_outcomes` panics on a chart reported).
        Family::Spyder | Family::Random | Family::Shuffled | Family::Nested | Family::Spyder24 => {
            (1..5, 0)
        }
    }
}

#[test]
fn real_photo_families_are_found_or_refused_never_wrong() {
    for f in Family::ALL.into_iter().filter(|f| !f.negative()) {
        let (seeds, min) = family_guard(f);
        let n = seeds.end - seeds.start;
        let (ok, refused) = family_outcomes(&cc24(), f, seeds);
        assert!(
            ok >= min,
            "{}: {ok} of {n} found, {refused} refused",
            f.name()
        );
    }
}

#[test]
fn other_charts_and_random_grids_are_refused() {
    for f in Family::ALL.into_iter().filter(|f| f.negative()) {
        let (ok, _) = family_outcomes(&cc24(), f, family_guard(f).0);
        assert_eq!(ok, 0, "{}", f.name());
    }
}

/// The negatives in the SG's layout (`chart rate --chart sg --family F`): another make's
/// 14 × 10 chart, random grids, and the SG's own colours deranged around its greys — all
/// refused.
#[test]
fn other_charts_and_random_grids_are_refused_as_an_sg() {
    let Some(colours) = sg() else { return };
    for f in Family::ALL.into_iter().filter(|f| f.negative()) {
        let (ok, _) = family_outcomes(&colours, f, 1..4);
        assert_eq!(ok, 0, "{}", f.name());
    }
}

/// Writes a file through an encoder of the library.
fn written(
    path: &std::path::Path,
    write: impl FnOnce(&mut dyn nsrm_io::WriteSeek) -> Result<(), nsrm_io::IoError>,
) -> Result<(), nsrm_io::IoError> {
    let mut w = std::io::BufWriter::new(std::fs::File::create_new(path).unwrap());
    write(&mut w)
}

/// The synthetic chart's frame and layout file (`render-chart`) read back as written.
#[test]
fn chart_layout_round_trips() {
    use super::synthetic::{layout_json, layout_path, render, write, ChartLayout, ChartOptions};
    use nsrm::{simulate_named, Grid};
    let data = simulate_named("nikon-d5100", "D65", "cc24", &Grid::default()).unwrap();
    let (frame, layout) = render(
        &data,
        &ChartOptions {
            patch_size: 10,
            columns: Some(6),
            noise: 0.001,
            seed: 3,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(layout.columns, 6);
    let dir = tempfile::tempdir().unwrap();
    for name in ["cc24.exr", "cc24_tiff.tif"] {
        let path = dir.path().join(name);
        written(&path, |w| write(&frame, &layout, &path, w)).unwrap();
        std::fs::write(layout_path(&path), layout_json(&layout).unwrap()).unwrap();
        let back = ChartLayout::read(&layout_path(&path)).unwrap();
        // serde_json (without its float_roundtrip feature) may be 1 ulp off.
        let close = |a: &[f64], b: &[f64]| {
            a.iter()
                .zip(b)
                .all(|(x, y)| (x - y).abs() <= 1e-12 * x.abs().max(1.0))
        };
        assert_eq!(
            (back.width, back.height, back.columns),
            (layout.width, layout.height, 6)
        );
        assert!(close(&back.white_xyz, &layout.white_xyz));
        assert_eq!(back.patches.len(), layout.patches.len());
        for (b, l) in back.patches.iter().zip(&layout.patches) {
            assert_eq!(
                (&b.label, b.x, b.y, b.width, b.height),
                (&l.label, l.x, l.y, l.width, l.height)
            );
            assert!(close(&b.rgb, &l.rgb) && close(&b.xyz, &l.xyz));
        }
        let f = nsrm_io::read_frame(&path, &nsrm_io::ReadOptions::default()).unwrap();
        assert_eq!(f, frame);
        for i in 0..layout.patches.len() {
            let m = layout.patch_mean(&f, i);
            for k in 0..3 {
                assert!((m[k] - layout.patches[i].rgb[k]).abs() < 1e-3);
            }
        }
    }
}

/// A small chart in a camera JPEG: the patches' quadrants differ by a few codes of colour
/// mottle and JPEG block error shared by every patch (measured on real phone JPEGs: 1–3.5 code
/// steps, and up to 14 of 24 patches flagged `nonuniform` when one code step was the limit, so
/// that charts were refused; the mottled scenes here: 10 to 16 of 24). That floor is not a
/// defect; a speck on one patch, or a mark printed on every patch, is.
#[test]
fn jpeg_noise_is_not_taken_for_nonuniform_patches_but_marks_are() {
    use super::extract::{sample_side, Flag, Quantisation};
    let colours = cc24();
    let reference = Reference::load("cc24-after2014", ChartKind::Cc24, None).unwrap();
    let opts = ExtractOptions {
        quantisation: Some(Quantisation {
            max_code: 255.0,
            srgb: true,
        }),
        ..Default::default()
    };
    let half = sample_side(ChartKind::Cc24, &opts) / 2.0;
    // Multiplies the pixels at (du, dv) ∈ `area` (in half sample sides from the centre of the
    // sampled area of the patches chosen by `which`) by `gain`.
    let paint = |frame: &mut nsrm::Frame,
                 truth: &SceneTruth,
                 which: &dyn Fn(usize) -> bool,
                 area: [f64; 4],
                 gain: f32| {
        let hinv = truth.homography.inverse().unwrap();
        for y in 0..frame.height {
            for x in 0..frame.width {
                let q = hinv.apply([x as f64 + 0.5, y as f64 + 0.5]);
                let (c, r) = (q[0].floor(), q[1].floor());
                if !(0.0..6.0).contains(&c) || !(0.0..4.0).contains(&r) {
                    continue;
                }
                let i = r as usize * 6 + c as usize;
                let (du, dv) = ((q[0] - c - 0.5) / half, (q[1] - r - 0.5) / half);
                if which(i) && du >= area[0] && du < area[1] && dv >= area[2] && dv < area[3] {
                    for v in &mut frame.data[(y * frame.width + x) * 3..][..3] {
                        *v *= gain;
                    }
                }
            }
        }
    };
    let nonuniform = |ex: &Extraction| -> Vec<usize> {
        (0..ex.patches.len())
            .filter(|&i| ex.patches[i].flags.contains(&Flag::Nonuniform))
            .collect()
    };
    for (seed, quality, mottle, side) in [
        (1, 85, 0.03, 200.0),
        (2, 80, 0.03, 180.0),
        (3, 90, 0.04, 200.0),
    ] {
        let scene = SceneOptions {
            width: 640,
            height: 480,
            corners: Some([
                [100.0, 100.0],
                [100.0 + side, 110.0],
                [100.0 + side, 110.0 + side / 1.5],
                [100.0, 100.0 + side / 1.5],
            ]),
            seed,
            exposure: 0.8,
            ..Default::default()
        };
        let look = super::scene::CameraLook {
            contrast: 2.0,
            saturation: 1.3,
            quality,
        };
        let h =
            homography_from_corners(ChartKind::Cc24, &scene.corners.unwrap(), 640, 480).unwrap();
        let read = |marks: &dyn Fn(&mut nsrm::Frame, &SceneTruth)| {
            let (mut frame, _, truth) = render(&colours, &scene).unwrap();
            marks(&mut frame, &truth);
            mottle_frame(&mut frame, mottle, 8, seed);
            super::scene::apply_look(&mut frame, look, 1.0).unwrap();
            extract(&frame, &reference, &h, &opts).unwrap()
        };
        let plain = read(&|_, _| {});
        assert!(
            nonuniform(&plain).len() <= 1,
            "seed {seed}: {:?}",
            nonuniform(&plain)
        );
        assert!(verify(&plain, &reference).is_ok(), "seed {seed}");
        // A dark speck over part of one quadrant of patch 02.
        let speck = read(&|f, t| paint(f, t, &|i| i == 1, [-0.9, -0.4, -0.9, -0.4], 0.3));
        assert!(
            nonuniform(&speck).contains(&1),
            "seed {seed}: {:?}",
            nonuniform(&speck)
        );
        // A label printed on every patch (a dark stroke left of centre, as on a chart graphic
        // with the cells' names drawn on): it raises every patch's spread, but the floor stops
        // at `CODE_NOISE_LIMIT` code steps; caught where it moves a quadrant by more (the
        // darkest patches' codes, and a thin stroke blurred by a coarser JPEG, move less:
        // 17, 9 and 18 of 24 at seeds 1–3; without the limit, 0).
        let labels = read(&|f, t| paint(f, t, &|_| true, [-0.7, -0.1, -0.7, 0.7], 0.1));
        assert!(
            nonuniform(&labels).len() >= 8,
            "seed {seed}: {:?}",
            nonuniform(&labels)
        );
    }
}

/// Multiplies each channel of `frame` by 1 + a smooth random field of standard deviation
/// `sigma` that varies over `cell` pixels (values drawn on a grid, bilinearly interpolated):
/// the low-frequency colour mottle a camera's noise reduction leaves.
fn mottle_frame(frame: &mut nsrm::Frame, sigma: f64, cell: usize, seed: u64) {
    let mut g = super::synthetic::Gaussian::new(seed);
    let (gw, gh) = (frame.width / cell + 2, frame.height / cell + 2);
    let grid: Vec<[f64; 3]> = (0..gw * gh)
        .map(|_| [0, 1, 2].map(|_| sigma * g.next()))
        .collect();
    let ch = frame.layout.channels();
    for y in 0..frame.height {
        for x in 0..frame.width {
            let (u, v) = (x as f64 / cell as f64, y as f64 / cell as f64);
            let (i, j) = (u.floor() as usize, v.floor() as usize);
            let (fu, fv) = (u - i as f64, v - j as f64);
            let at = |a: usize, b: usize, k: usize| grid[b * gw + a][k];
            for k in 0..3 {
                let n = (1.0 - fv) * ((1.0 - fu) * at(i, j, k) + fu * at(i + 1, j, k))
                    + fv * ((1.0 - fu) * at(i, j + 1, k) + fu * at(i + 1, j + 1, k));
                let px = &mut frame.data[(y * frame.width + x) * ch + k];
                *px = (*px as f64 * (1.0 + n)).max(0.0) as f32;
            }
        }
    }
}

/// A chart the search at the finer scale misses (black-framed charts at 1200 × 800, seeds 49 and
/// 51: too few of the candidate patches link into a grid) is found by the search again on the
/// coarser image, and found correctly; with that second search disabled the scenes are refused.
#[test]
fn a_second_search_at_a_coarser_scale_finds_what_the_first_missed() {
    for seed in [49, 51] {
        let (_, d) = missed_first_found_second(Family::BlackFrame, seed);
        assert_eq!(d.downsample, 2, "seed {seed}");
    }
}

/// The hue check of the decisive rule (`detect::hues_hold`): a chart's own colours, even through
/// a steep per-channel tone curve and a saturation gain, keep their hues; the same colours one
/// cell along (a placement shifted across the lattice) or in another order do not.
#[test]
fn graded_colours_keep_their_hues_and_misplaced_ones_do_not() {
    use super::detect::hues_hold;
    use super::extract::hue_errors;
    let colours = cc24();
    let reference =
        Reference::load(ChartKind::Cc24.default_reference(), ChartKind::Cc24, None).unwrap();
    let own: Vec<Option<[f64; 3]>> = colours.rgb.iter().map(|v| Some(*v)).collect();
    let errs = hue_errors(&own, &reference).unwrap();
    assert!(errs.len() >= 16 && hues_hold(&errs), "{errs:?}");
    // A camera look: gamma 1/2.4 per channel, then saturation ×2 around the mean.
    let graded: Vec<Option<[f64; 3]>> = colours
        .rgb
        .iter()
        .map(|v| {
            let e = v.map(|x| (x / colours.white_rgb[1]).powf(1.0 / 2.4));
            let m = (e[0] + e[1] + e[2]) / 3.0;
            Some(e.map(|x| (m + 2.0 * (x - m)).max(0.0)))
        })
        .collect();
    let errs = hue_errors(&graded, &reference).unwrap();
    assert!(hues_hold(&errs), "{errs:?}");
    // Shifted by one cell along the rows, and reversed.
    let shifted: Vec<Option<[f64; 3]>> = (0..24).map(|i| own[(i + 1) % 24]).collect();
    let reversed: Vec<Option<[f64; 3]>> = own.iter().rev().copied().collect();
    for (what, rgb) in [("shifted", shifted), ("reversed", reversed)] {
        let errs = hue_errors(&rgb, &reference).unwrap();
        assert!(!hues_hold(&errs), "{what}: {errs:?}");
    }
}

/// The SpyderCHECKR 24 simulated from the classic's spectra in its layout.
fn spyder24() -> ChartColours {
    ChartColours::simulate(ChartKind::Spyder24, "nikon-d5100", "D65", None).unwrap()
}

#[test]
fn the_spyderchecker_layout_labels_and_reference_agree() {
    let k = ChartKind::Spyder24;
    assert_eq!((k.columns(), k.rows()), (6, 4));
    assert_eq!(k.label(0, 0), "D1 bluish green");
    assert_eq!(k.label(0, 3), "A1 white");
    assert_eq!(k.label(5, 3), "A6 black");
    for (spec, i) in [
        ("A1", 18),
        ("a1 white", 18),
        ("white", 18),
        ("D6", 5),
        ("cyan", 12),
    ] {
        assert_eq!(k.index_of(spec), Some(i), "{spec}");
    }
    assert_eq!(k.index_of("19"), None);
    assert_eq!(ChartKind::parse("SPYDER24").unwrap(), k);
    // The map from the classic's cells is its own inverse and a permutation.
    let mut seen = [false; 24];
    for i in 0..24 {
        let j = scene::spyder24_cell(i);
        assert_eq!(scene::spyder24_cell(j), i);
        seen[j] = true;
    }
    assert!(seen.iter().all(|&s| s));
    // Its colours are the classic's: the classic's published values, put in the SpyderCHECKR's
    // cells by that map, are within a few ΔE00 of the SpyderCHECKR's on every cell (a wrong
    // map would put a red where a blue is).
    let r = Reference::load(k.default_reference(), k, None).unwrap();
    let cc = Reference::load("cc24-after2014", ChartKind::Cc24, None).unwrap();
    let worst = (0..24)
        .map(|i| nsrm::delta_e00_xyz(cc.xyz[scene::spyder24_cell(i)], r.xyz[i], r.white))
        .fold(0.0, f64::max);
    assert!(
        worst < 6.0,
        "worst cell {worst:.2} ΔE00 from the classic's colour"
    );
    assert_eq!(spyder24().rgb.len(), 24);
}

#[test]
fn the_spyderchecker_is_read_as_itself_in_real_photo_families() {
    let c = spyder24();
    for f in [Family::Envelope, Family::Jpeg, Family::Tilt, Family::Small] {
        let (ok, refused) = family_outcomes(&c, f, 1..4);
        assert!(ok >= 2, "{}: {ok} of 3 found, {refused} refused", f.name());
    }
}

/// Never another make for the SpyderCHECKR: a classic ColorChecker (the `spyder24` family's
/// swap undone), random grids, the SpyderCHECKR's colours shuffled — all refused when a
/// SpyderCHECKR is asked for.
#[test]
fn other_charts_are_refused_as_a_spyderchecker() {
    let c = spyder24();
    for f in Family::ALL.into_iter().filter(|f| f.negative()) {
        let (ok, _) = family_outcomes(&c, f, 1..4);
        assert_eq!(ok, 0, "{}", f.name());
    }
}
