//! Two `#[ignore]` diagnostics of the DCP export, run by hand (`cargo test -p nsrm-export --lib
//! diag -- --ignored --nocapture`): where a one-illuminant DCP's worst patch is (`diag`), and
//! where a two-illuminant DCP's error comes from (`diag_dual`). Not judges: the tests beside
//! `dcp.rs` and `dcp_tests.rs` are.

use super::*;

mod diag {
    use super::*;
    #[test]
    #[ignore]
    fn where_is_the_worst() {
        use nsrm::{fit_with, FitOptions};
        let d = nsrm::simulate_named(
            "nikon-d5100",
            "D65",
            "rawtoaces-190",
            &nsrm::Grid::default(),
        )
        .unwrap();
        let o = FitOptions {
            preserve_white: true,
            ..Default::default()
        };
        let m = fit_with(Kind::Nsrm, 3, &d, &o).unwrap().model;
        let p = Profile::single(m).unwrap();
        for (hd, sd) in [(360, 92), (240, 138), (480, 69), (600, 55)] {
            let dcp = build(
                &p,
                &[d.rgb.as_slice()],
                DcpOptions {
                    hue_divisions: hd,
                    sat_divisions: sd,
                },
            )
            .unwrap();
            let w = p.calibrations()[0].white_rgb;
            let c = p.combine(FrameWhite::Neutral(w)).unwrap();
            let adapt =
                temperature::bradford_between(c.white_xyz, d50()).map(|r| r.map(|v| v / 100.0));
            let bal: Vec<[f64; 3]> = d
                .rgb
                .iter()
                .map(|x| [0, 1, 2].map(|k| x[k] / w[k]))
                .collect();
            let chroma = crate::dense_chromaticities(&bal, 0.005);
            let mut worst = (0.0, [0.0; 3]);
            for (r, g) in chroma {
                let b = [r, g, 1.0 - r - g];
                let rgb = [0, 1, 2].map(|j| b[j] * c.neutral[j]);
                let exact = spaces::apply(&adapt, c.apply_f64(rgb));
                let approx = dcp.eval_weighted(rgb, c.neutral, 1.0);
                let de = nsrm::delta_e00_xyz(exact, approx, d50());
                if de > worst.0 {
                    worst = (de, b);
                }
            }
            let b = worst.1;
            let fm = dcp.sides[0].forward_matrix;
            let pp = spaces::apply(&spaces::invert(&prophoto_to_xyz()), spaces::apply(&fm, b));
            let hsv = rgb_to_hsv(pp);
            println!("{hd}x{sd}: worst {:.4} at b {b:?} pp hsv {hsv:?}", worst.0);
        }
    }
}

mod diag_dual {
    use super::*;
    use nsrm::{fit_with, FitOptions};

    /// Where the two-illuminant DCP's error comes from: per frame white, the DCP's weight (DNG
    /// rule on its own matrices and light-source temperatures) against the model's, and the
    /// error at either weight. `cargo test --lib diag_dual -- --ignored --nocapture`.
    #[test]
    #[ignore]
    fn decompose() {
        let sim = |ill: &str| {
            nsrm::simulate_named("nikon-d5100", ill, "rawtoaces-190", &nsrm::Grid::default())
                .unwrap()
        };
        let (da, dd) = (sim("A"), sim("D65"));
        let o = FitOptions {
            preserve_white: true,
            ..Default::default()
        };
        for kind in [Kind::Lrm, Kind::Nsrm] {
            let p = Profile::dual(
                fit_with(kind, 3, &da, &o).unwrap().model,
                fit_with(kind, 3, &dd, &o).unwrap().model,
            )
            .unwrap();
            let t0 = std::time::Instant::now();
            let dcp = build(
                &p,
                &[da.rgb.as_slice(), dd.rgb.as_slice()],
                DcpOptions::default(),
            )
            .unwrap();
            let t_build = t0.elapsed();
            let t0 = std::time::Instant::now();
            let whites: Vec<FrameWhite> = p
                .calibrations()
                .iter()
                .map(|c| FrameWhite::Neutral(c.white_rgb))
                .collect();
            let r = measure(&dcp, &p, &whites, &da.rgb, [-5.0, 4.0]).unwrap();
            println!(
                "{kind}: build {:.2} s, measure at two whites {:.2} s ({} dense samples): {}",
                t_build.as_secs_f64(),
                t0.elapsed().as_secs_f64(),
                r.dense.count,
                r.summary()
            );
            let d50 = d50();
            let [t1, t2] = p.temperatures();
            let mid = 2.0 / (1.0 / t1 + 1.0 / t2);
            let w0 = p.calibrations()[0].white_rgb;
            let bal: Vec<[f64; 3]> = da
                .rgb
                .iter()
                .map(|c| [0, 1, 2].map(|k| c[k] / w0[k]))
                .collect();
            let chroma = crate::dense_chromaticities(&bal, 0.005);
            for white in [
                FrameWhite::Neutral(p.calibrations()[0].white_rgb),
                FrameWhite::Neutral(p.calibrations()[1].white_rgb),
                FrameWhite::Xy(temperature::temperature_xy(mid).unwrap()),
            ] {
                let c = p.combine(white).unwrap();
                let adapt =
                    temperature::bradford_between(c.white_xyz, d50).map(|r| r.map(|v| v / 100.0));
                let xy = dcp.neutral_to_xy(c.neutral).unwrap();
                let wd = dcp.weight_at(xy);
                let mut worst = [(0.0f64, [0.0; 3]); 2];
                let (mut in_gamut_max, mut outside, mut total) = (0.0f64, 0usize, 0usize);
                let fmd = dcp.mix(wd, |s| s.forward_matrix);
                let to_pp = spaces::mul(&spaces::invert(&prophoto_to_xyz()), &fmd);
                let s_ref = bal.iter().map(|c| c[0] + c[1] + c[2]).fold(0.0, f64::max);
                for &(r, g) in &chroma {
                    let b = [r * s_ref, g * s_ref, (1.0 - r - g) * s_ref];
                    let rgb = [0, 1, 2].map(|j| b[j] * c.neutral[j]);
                    let exact = spaces::apply(&adapt, c.apply_f64(rgb));
                    let bn = [0, 1, 2].map(|j| rgb[j] / (c.neutral[j] / c.neutral[1]));
                    let inside = spaces::apply(&to_pp, bn).iter().all(|v| *v >= 0.0);
                    total += 1;
                    if !inside {
                        outside += 1;
                    }
                    for (slot, w) in [(0, wd), (1, c.weight)] {
                        let approx = dcp.eval_weighted(rgb, c.neutral, w);
                        let de = nsrm::delta_e00_xyz(exact, approx, d50);
                        if slot == 0 && inside {
                            in_gamut_max = in_gamut_max.max(de);
                        }
                        if de > worst[slot].0 {
                            worst[slot] = (de, b);
                        }
                    }
                }
                let b = worst[1].1;
                let fm = dcp.mix(c.weight, |s| s.forward_matrix);
                let pp = spaces::apply(&spaces::invert(&prophoto_to_xyz()), spaces::apply(&fm, b));
                println!(
                    "{kind} white {:.0} K: weight model {:.4} dcp {wd:.4} (xy model {:.5},{:.5} dcp {:.5},{:.5}); max dE00 at dcp weight {:.4}, at model weight {:.4} (worst b {b:?}, ProPhoto {pp:?} hsv {:?})",
                    c.cct, c.weight, c.xy[0], c.xy[1], xy[0], xy[1], worst[0].0, worst[1].0, rgb_to_hsv(pp)
                );
                println!(
                    "    {outside} of {total} chromaticities outside ProPhoto after the ForwardMatrix; max ΔE00 of those inside {in_gamut_max:.4}"
                );
            }
        }
    }
}
