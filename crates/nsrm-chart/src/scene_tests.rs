//! The unit tests of `scene.rs` (moved beside it to keep the file short).

use super::*;

/// A CC24 whose patch `i` has colour `[i, i, i] / 100`, white `[1, 1, 1]`.
fn colours() -> ChartColours {
    ChartColours {
        chart: ChartKind::Cc24,
        rgb: (0..24).map(|i| [i as f64 / 100.0; 3]).collect(),
        xyz: (0..24).map(|i| [i as f64; 3]).collect(),
        white_rgb: [1.0; 3],
        camera: "c".into(),
        illuminant: "i".into(),
        reflectances: "r".into(),
    }
}

/// Ten pixels per chart unit, the chart's top-left body corner at (10, 10).
fn pose() -> (Homography, Homography) {
    let hom = Homography([10.0, 0.0, 14.0, 0.0, 10.0, 14.0, 0.0, 0.0, 1.0]);
    (hom, hom.inverse().unwrap())
}

fn opts(w: usize, h: usize) -> SceneOptions {
    SceneOptions {
        width: w,
        height: h,
        ..SceneOptions::default()
    }
}

#[test]
fn light_is_normalised_over_the_centres_and_falls_off_at_the_corners() {
    let o = SceneOptions {
        vignetting: 0.4,
        gradient: 0.2,
        ..opts(100, 100)
    };
    let centres = [[20.0, 30.0], [50.0, 50.0], [90.0, 10.0]];
    let light = Light::new(&o, 0.25, &centres).unwrap();
    let mean = centres.iter().map(|c| light.at(c[0], c[1])).sum::<f64>() / 3.0;
    assert!((mean - 1.0).abs() < 1e-12, "{mean}");
    let flat = Light::new(
        &SceneOptions {
            gradient: 0.0,
            ..o.clone()
        },
        0.25,
        &centres,
    );
    let flat = flat.unwrap();
    assert!(flat.at(0.0, 0.0) < flat.at(50.0, 50.0));
    // With the gradient pointing down (τ/4), the bottom is brighter than the top.
    assert!(light.raw(50.0, 90.0) > light.raw(50.0, 10.0));
    let dark = SceneOptions {
        vignetting: 3.0,
        ..opts(100, 100)
    };
    assert!(Light::new(&dark, 0.5, &[[0.0, 0.0]]).is_err());
}

#[test]
fn background_is_a_gradient_under_the_last_shape_drawn() {
    let mut g = Gaussian::new(7);
    let mut bg = Background::new([1.0; 3], 100, 50, 0, &mut g);
    assert_eq!(bg.at(0.0, 0.0), bg.from);
    let mid = bg.at(50.0, 25.0);
    for k in 0..3 {
        assert!((mid[k] - 0.5 * (bg.from[k] + bg.to[k])).abs() < 1e-12);
        assert!(bg.from[k] < 0.95 + 1e-12 && bg.from[k] > 0.0);
    }
    let square = |c: [f64; 2]| Shape::Rect {
        c,
        half: [5.0, 5.0],
        cos: 1.0,
        sin: 0.0,
    };
    bg.shapes.push((square([20.0, 20.0]), [0.1; 3]));
    bg.shapes.push((square([24.0, 20.0]), [0.2; 3]));
    assert_eq!(bg.at(16.0, 20.0), [0.1; 3]);
    assert_eq!(bg.at(22.0, 20.0), [0.2; 3]);
    assert_ne!(bg.at(40.0, 20.0), [0.2; 3]);
}

#[test]
fn the_drawing_shows_patches_body_occluder_and_background() {
    let c = colours();
    let (hom, hinv) = pose();
    let o = opts(100, 80);
    let bg = [0.7; 3];
    let drawing = ChartDrawing::new(&c, hom, hinv, None, None, &o);
    // Patch 7 (column 1, row 1) at chart (1.5, 1.5).
    assert_eq!(drawing.at(hom.apply([1.5, 1.5]), bg), c.rgb[7]);
    // Between two patches and in the margin: the body.
    assert_eq!(drawing.at(hom.apply([1.0, 1.5]), bg), [0.035; 3]);
    assert_eq!(drawing.at(hom.apply([-0.2, 0.5]), bg), [0.035; 3]);
    // Beyond the body.
    assert_eq!(drawing.at(hom.apply([-0.6, 0.5]), bg), bg);
    assert!(drawing.near(12.0, 12.0) && !drawing.near(95.0, 5.0));
    // A pixel inside a patch averages to the patch; one on its edge (the patch starts at
    // x = 24.8) mixes: three samples of body, one of patch.
    assert!((drawing.supersampled(29, 29, bg)[0] - c.rgb[7][0]).abs() < 1e-15);
    let edge = drawing.supersampled(24, 29, bg)[0];
    assert!((edge - (3.0 * 0.035 + 0.07) / 4.0).abs() < 1e-12, "{edge}");
    let occ = (
        Shape::Ellipse {
            c: hom.apply([1.5, 1.5]),
            half: [3.0, 3.0],
            cos: 1.0,
            sin: 0.0,
        },
        [0.5; 3],
    );
    let drawing = ChartDrawing::new(&c, hom, hinv, Some(&occ), None, &o);
    assert_eq!(drawing.at(hom.apply([1.5, 1.5]), bg), [0.5; 3]);
    assert!(drawing.near(95.0, 5.0));
}

#[test]
fn noise_free_frames_are_clipped_at_the_white_level_and_floored_at_zero() {
    let o = SceneOptions {
        noise: 0.0,
        shot_noise: 0.0,
        white_level: 0.5,
        ..opts(2, 1)
    };
    let mut f = Frame::from_data(2, 1, Layout::Rgb, vec![-1.0, 0.25, 0.5, 0.75, 2.0, 0.1]).unwrap();
    add_noise(&mut f, &o, 0);
    assert_eq!(f.data, [0.0, 0.25, 0.5, 0.5, 0.5, 0.1]);
    let noisy = SceneOptions {
        noise: 0.01,
        white_level: 10.0,
        ..o
    };
    let (mut a, mut b) = (f.clone(), f.clone());
    add_noise(&mut a, &noisy, 0);
    add_noise(&mut b, &noisy, 1);
    assert_ne!(a.data, f.data);
    assert_ne!(a.data, b.data, "the salt tells the frames apart");
}

#[test]
fn rasterised_frames_are_lit_background_away_from_the_chart() {
    let c = colours();
    let (hom, hinv) = pose();
    let o = SceneOptions {
        exposure: 2.0,
        ..opts(120, 80)
    };
    let mut g = Gaussian::new(3);
    let bg = Background::new([1.0; 3], 120, 80, 0, &mut g);
    let drawing = ChartDrawing::new(&c, hom, hinv, None, None, &o);
    let light = Light::new(&o, 0.1, &[[10.0, 10.0]]).unwrap();
    let data = rasterise(120, 80, &bg, &drawing, &light, o.exposure);
    let (x, y) = (110, 70);
    let want = bg.at(110.5, 70.5)[0] * (light.at(110.5, 70.5) * 2.0);
    assert_eq!(data[(y * 120 + x) * 3], want as f32);
    let (x, y) = (29, 29);
    let patch = data[(y * 120 + x) * 3] as f64;
    assert!((patch - c.rgb[7][0] * 2.0).abs() < 1e-7, "{patch}");
    let flat = flat_frame(120, 80, [1.0; 3], &light, 2.0);
    assert_eq!(flat.data[0], 1.0);
}

#[test]
fn true_patches_flag_occlusion_and_clipping() {
    let c = colours();
    let (hom, _) = pose();
    let o = SceneOptions {
        exposure: 4.0,
        white_level: 0.9,
        ..opts(100, 80)
    };
    let light = Light::new(&o, 0.1, &[[10.0, 10.0]]).unwrap();
    let occ = (
        Shape::Ellipse {
            c: hom.apply([0.5, 0.5]),
            half: [1.0, 1.0],
            cos: 1.0,
            sin: 0.0,
        },
        [0.5; 3],
    );
    let p = true_patches(&c, &hom, &light, Some(&occ), &o);
    assert_eq!(p.len(), 24);
    assert!(p[0].occluded && !p[1].occluded);
    assert_eq!(p[7].centre, [29.0, 29.0]);
    assert_eq!(p[7].rgb, c.rgb[7].map(|v| v * 4.0));
    assert!(!p[22].clipped && p[23].clipped, "0.88 < 0.9 ≤ 0.92");
    let truth = scene_truth(&c, &o, hom, (1.0, 2.0), &light, &[[1.0, 1.0]], p);
    assert_eq!((truth.rotation_deg, truth.tilt_deg), (1.0, 2.0));
    assert_eq!(truth.light_nonuniformity, 1.0);
    assert_eq!(truth.patches[0].label, ChartKind::Cc24.label(0, 0));
}

#[test]
fn a_close_camera_shows_the_perspective_asked_for() {
    let kind = ChartKind::Cc24;
    let seen = |o: &SceneOptions, seed| {
        let (h, _, _) = random_pose(kind, o, &mut Gaussian::new(seed)).unwrap();
        super::super::detect::perspective(kind, &h)
    };
    let far = SceneOptions {
        min_tilt_deg: 35.0,
        max_tilt_deg: 35.0,
        ..opts(1200, 800)
    };
    for seed in 1..6 {
        let p_far = seen(&far, seed);
        assert!(p_far > 1.0 && p_far < 1.6, "seed {seed}: {p_far}");
        for target in [1.6, 1.9, 2.2] {
            let close = SceneOptions {
                perspective: Some(target),
                ..far.clone()
            };
            let p = seen(&close, seed);
            assert!((p - target).abs() < 1e-9, "seed {seed}: {p} for {target}");
        }
    }
    // Beyond what the closest camera shows (a tilt of 5°), it is that camera.
    let flat = SceneOptions {
        max_tilt_deg: 5.0,
        perspective: Some(3.0),
        ..opts(1200, 800)
    };
    let p = seen(&flat, 1);
    assert!(p > 1.0 && p < 1.5, "{p}");
    for bad in [0.9, 4.5, f64::NAN] {
        let o = SceneOptions {
            perspective: Some(bad),
            ..opts(100, 100)
        };
        assert!(render(&colours(), &o).is_err(), "{bad}");
    }
    // The wide family draws its perspective within 1.6..2.2.
    for seed in 1..20 {
        let (_, o) = Family::Wide.scene(&colours(), 1200, 800, seed);
        let p = o.perspective.unwrap();
        assert!((1.6..=2.2).contains(&p) && o.min_tilt_deg == 30.0, "{p}");
    }
}

/// An SG of greys in its even columns and reds in its odd ones, cell `i` at level
/// `0.05 + i / 200`.
fn sg_colours() -> ChartColours {
    let kind = ChartKind::Sg;
    let rgb = (0..kind.cells())
        .map(|i| {
            let v = 0.05 + i as f64 / 200.0;
            if kind.cell(i).0.is_multiple_of(2) {
                [v; 3]
            } else {
                [v, 0.5 * v, 0.3 * v]
            }
        })
        .collect();
    ChartColours {
        chart: kind,
        rgb,
        xyz: vec![[0.0; 3]; kind.cells()],
        ..colours()
    }
}

#[test]
fn sg_impostors_keep_the_layout_and_change_the_chart() {
    let sg = sg_colours();
    let kind = ChartKind::Sg;
    let grey = |i: usize| near_neutral(sg.rgb[i], sg.white_rgb);
    assert_eq!((0..kind.cells()).filter(|&i| grey(i)).count(), 70);
    for seed in 1..6 {
        // Shuffled: every grey in place, every colour moved (to another colour's cell).
        let (c, _) = Family::Shuffled.scene(&sg, 720, 480, seed);
        assert_eq!((c.chart, c.rgb.len()), (kind, kind.cells()));
        for i in 0..kind.cells() {
            if grey(i) {
                assert_eq!(c.rgb[i], sg.rgb[i], "seed {seed}: grey {i} moved");
            } else {
                assert_ne!(c.rgb[i], sg.rgb[i], "seed {seed}: colour {i} stayed");
                assert!(!near_neutral(c.rgb[i], sg.white_rgb));
            }
        }
        // Spyder: a falling grey ramp down the two right columns, the SG's colours elsewhere.
        let (c, _) = Family::Spyder.scene(&sg, 720, 480, seed);
        let ramp: Vec<f64> = (12..14)
            .flat_map(|col| (0..10).map(move |r| r * 14 + col))
            .map(|i| c.rgb[i][1])
            .collect();
        assert!(ramp.windows(2).all(|w| w[1] < w[0]), "{ramp:?}");
        assert!((ramp[0] - 0.9).abs() < 1e-12 && (ramp[19] - 0.03).abs() < 1e-12);
        for i in (0..kind.cells()).filter(|&i| kind.cell(i).0 < 12) {
            assert!(
                !near_neutral(c.rgb[i], sg.white_rgb),
                "seed {seed}: cell {i}"
            );
            assert!(sg.rgb.contains(&c.rgb[i]));
        }
        // Random: its own colours in every cell.
        let (c, _) = Family::Random.scene(&sg, 720, 480, seed);
        assert_eq!(c.rgb.len(), kind.cells());
        assert!(c.rgb.iter().zip(&sg.rgb).all(|(a, b)| a != b));
    }
}
