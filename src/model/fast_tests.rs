//! The fast CPU path ([`Model::apply_frame`] and the crate's own entry points into `super::fast`)
//! against the f64 reference (`Model::apply_frame_f64`), for every kind, order and layout, on
//! frames full of awkward pixels. (Once `tests/all/fast.rs`; here since the fast path's internals
//! are crate-private. The frames and the bound are the shared test kit's, `tests/all/common/kit.rs`.)
//!
//! Accuracy criterion, per pixel and output channel `k` (`ref` = the f64 reference rounded to f32):
//! * reference NaN ⇒ fast NaN; reference ±∞ ⇒ fast the same ±∞; reference finite ⇒ fast finite and
//!   `|fast_k − ref_k| ≤ 1e-5·max(|ref_k|, T_k, 1e-30)` — the one f32 bound of the GPU tests too
//!   (the test kit's `f32_bound`):
//!   - `T_k = |s|·Σ_j |m_kj·p_j|` (f64), the size of the summands of output `k`. Where the model
//!     cancels (summands much larger than the result: PRM extrapolating HDR values, the fitted
//!     RPRM 3/4 and PRM 3/4 whose coefficients run into the thousands), no f32 evaluation can be
//!     within 1e-5 of the result — rounding the coefficients alone to f32 moves it by 6e-8·T_k —
//!     so the bound is relative to `T_k` there (measured worst: 4.5e-7·T_k);
//!   - the floor 1e-30 only matters for pixels whose reference is exactly 0 (all-zero input;
//!     NSRM with `s ≤ 0`).
//!
//!   `cargo test --lib fast_tests -- --nocapture` prints the worst `err/max|ref|` and `err/T_k` per model.
//! * Alpha is bit-for-bit unchanged.
//! * One thread, all threads, in place and into a second frame give bit-identical results; the
//!   baseline clone without FMA (`FastModel::apply_baseline`) meets the same bounds.

use super::fast::{apply_frame_single, FastModel, Threads};
use super::terms;
use crate::kit as common;
use crate::{fit, fit_with, FitOptions, Frame, Kind, Layout, Model, Normalise, MAX_ORDER};
use common::{
    awkward_frame as random_frame, f32_bound, summands as term_magnitude, training, Rng, F32_REL,
};

/// The public CPU frame path.
fn apply_frame(model: &Model, frame: &mut Frame) {
    model.apply_frame(frame)
}

/// Every kind at every order ([`common::fitted_models`]) and white-balanced NSRM (input gains) at
/// every order.
fn fitted_models() -> Vec<Model> {
    let mut v = common::fitted_models();
    v.extend(white_balanced_nsrm());
    v
}

/// White-balanced NSRM at orders 1–4: non-unit input gains on every path.
fn white_balanced_nsrm() -> Vec<Model> {
    let opts = FitOptions {
        normalise: Normalise::WhiteBalanced,
        ..Default::default()
    };
    (1..=MAX_ORDER)
        .map(|order| {
            let m = fit_with(Kind::Nsrm, order, training(), &opts)
                .unwrap()
                .model;
            assert!(!m.has_unit_gains(), "{:?}", m.input_gains());
            m
        })
        .collect()
}

/// Worst error measures over the finite pixels; panics on any violation.
fn compare(model: &Model, input: &Frame, fast: &Frame, what: &str) -> Worst {
    let mut reference = input.clone();
    model.apply_frame_f64(&mut reference);
    let ch = input.layout.channels();
    let mut worst = Worst::default();
    for (i, ((r, f), x)) in reference
        .data
        .chunks_exact(ch)
        .zip(fast.data.chunks_exact(ch))
        .zip(input.data.chunks_exact(ch))
        .enumerate()
    {
        let ctx = || {
            format!(
                "{what}: {} {} pixel {i} input {x:?}: reference {r:?}, fast {f:?}",
                model.kind(),
                model.order()
            )
        };
        if ch == 4 {
            assert_eq!(f[3].to_bits(), x[3].to_bits(), "alpha changed: {}", ctx());
        }
        let scale = r[..3].iter().map(|v| (*v as f64).abs()).fold(0.0, f64::max);
        let tm = term_magnitude(model, [x[0] as f64, x[1] as f64, x[2] as f64]);
        for k in 0..3 {
            let (rv, fv) = (r[k] as f64, f[k] as f64);
            if rv.is_nan() {
                assert!(fv.is_nan(), "expected NaN: {}", ctx());
            } else if rv.is_infinite() {
                assert_eq!(fv, rv, "expected {rv}: {}", ctx());
            } else {
                assert!(fv.is_finite(), "expected finite: {}", ctx());
                let err = (fv - rv).abs();
                assert!(
                    err <= f32_bound(rv, tm[k], F32_REL),
                    "error {err:e} > bound (summands T_k = {:e}): {}",
                    tm[k],
                    ctx()
                );
                if scale > 0.0 {
                    worst.to_ref = worst.to_ref.max(err / scale);
                }
                if tm[k] > 0.0 {
                    worst.to_terms = worst.to_terms.max(err / tm[k]);
                }
            }
        }
    }
    worst
}

#[derive(Debug, Default, Clone, Copy)]
struct Worst {
    to_ref: f64,
    to_terms: f64,
}

impl Worst {
    fn max(self, o: Worst) -> Worst {
        Worst {
            to_ref: self.to_ref.max(o.to_ref),
            to_terms: self.to_terms.max(o.to_terms),
        }
    }
}

/// All paths (all threads, one thread, in place, into) agree bit for bit; returns the in-place,
/// all-threads result.
fn run_all_paths(model: &Model, input: &Frame) -> Frame {
    let mut all = input.clone();
    apply_frame(model, &mut all);
    let mut single = input.clone();
    apply_frame_single(model, &mut single);
    let fast = FastModel::new(model);
    let mut into = Frame::new(input.width, input.height, input.layout);
    into.data.iter_mut().for_each(|v| *v = 7.0);
    fast.apply_into(input, &mut into, Threads::Single).unwrap();
    let mut into_all = Frame::new(input.width, input.height, input.layout);
    fast.apply_into(input, &mut into_all, Threads::All).unwrap();
    let bits = |f: &Frame| f.data.iter().map(|v| v.to_bits()).collect::<Vec<u32>>();
    let b = bits(&all);
    assert_eq!(
        b,
        bits(&single),
        "{} {}: one thread vs all",
        model.kind(),
        model.order()
    );
    assert_eq!(
        b,
        bits(&into),
        "{} {}: into vs in place",
        model.kind(),
        model.order()
    );
    assert_eq!(
        b,
        bits(&into_all),
        "{} {}: into (all threads)",
        model.kind(),
        model.order()
    );
    all
}

#[test]
fn every_kind_order_and_layout_matches_the_f64_reference() {
    let sizes = [(1, 1), (7, 13), (4097, 3), (5, 1), (300, 257)];
    let mut report = Vec::new();
    for model in fitted_models() {
        let mut worst = Worst::default();
        for layout in [Layout::Rgb, Layout::Rgba] {
            for (n, &(w, h)) in sizes.iter().enumerate() {
                let input = random_frame(w, h, layout, 1000 + n as u64);
                let out = run_all_paths(&model, &input);
                let what = format!("{w}×{h} {}", layout.name());
                worst = worst.max(compare(&model, &input, &out, &what));
                // The baseline clone (no FMA), called directly: the same bounds.
                let mut baseline = input.clone();
                FastModel::new(&model).apply_baseline(&mut baseline, Threads::All);
                worst = worst.max(compare(
                    &model,
                    &input,
                    &baseline,
                    &format!("{what} baseline"),
                ));
            }
        }
        report.push(format!(
            "{} {}{}: {} kernel, worst error / max|ref| = {:.2e}, / T_k = {:.2e}",
            model.kind(),
            model.order(),
            if model.has_unit_gains() {
                ""
            } else {
                " white-balanced"
            },
            FastModel::new(&model).kernel_name(),
            worst.to_ref,
            worst.to_terms
        ));
    }
    // Visible with --nocapture; BENCHMARKS.md quotes these.
    println!("{}", report.join("\n"));
}

#[test]
fn random_matrices_on_every_kind_and_order() {
    // Matrices with entries of both signs, independent of any training data.
    let mut rng = Rng(77);
    for kind in Kind::ALL {
        for order in 1..=MAX_ORDER {
            let order = kind.effective_order(order);
            let l = terms(kind, order).len();
            let matrix: Vec<f64> = (0..3 * l)
                .map(|_| (rng.unit() as f64 - 0.3) * 50.0)
                .collect();
            let model = Model::from_matrix(kind, order, matrix).unwrap();
            let input = random_frame(31, 9, Layout::Rgb, 5 + order as u64);
            let out = run_all_paths(&model, &input);
            compare(&model, &input, &out, "random matrix");
            if kind == Kind::Nsrm {
                // Random input gains over three decades.
                let gains = [0, 1, 2].map(|_| 10f64.powf(3.0 * rng.unit() as f64 - 1.5));
                let model = model.with_input_gains(gains).unwrap();
                let out = run_all_paths(&model, &input);
                compare(&model, &input, &out, "random matrix and gains");
            }
        }
    }
}

#[test]
fn white_balanced_nsrm_takes_its_gains_on_the_fast_path() {
    // The gains change the result (so the comparison above would catch a path that drops them),
    // and the white's camera response maps to the same value as the white-balanced white (1,1,1).
    let w = training().white_rgb.unwrap();
    for model in white_balanced_nsrm() {
        let mut f = Frame::from_data(
            2,
            1,
            Layout::Rgb,
            vec![w[0] as f32, w[1] as f32, w[2] as f32, 1.0, 1.0, 1.0],
        )
        .unwrap();
        apply_frame(&model, &mut f);
        let raw = model.clone().with_input_gains([1.0; 3]).unwrap();
        let unbalanced = raw.apply_f64([1.0, 1.0, 1.0]);
        for k in 0..3 {
            let want = unbalanced[k];
            assert!(
                (f.data[k] as f64 - want).abs() <= 1e-5 * want.abs(),
                "order {}: white {} vs {want}",
                model.order(),
                f.data[k]
            );
        }
        assert_ne!(f.data[0..3], f.data[3..6], "order {}", model.order());
    }
}

#[test]
fn nsrm_policy_and_exposure_scaling() {
    let model = fit(Kind::Nsrm, 3, training()).unwrap();
    let mut f = Frame::from_data(
        5,
        1,
        Layout::Rgb,
        vec![
            0.0,
            0.0,
            0.0, // black → 0
            0.1,
            -0.2,
            0.05, // s < 0 → 0
            f32::NAN,
            0.1,
            0.1, // NaN propagates
            0.2,
            0.3,
            0.4, // ordinary
            20.0,
            30.0,
            40.0, // ×100: NSRM scales exactly with exposure
        ],
    )
    .unwrap();
    apply_frame(&model, &mut f);
    assert_eq!(&f.data[0..6], &[0.0; 6]);
    assert!(f.data[6..9].iter().all(|v| v.is_nan()));
    for k in 0..3 {
        let (lo, hi) = (f.data[9 + k] as f64, f.data[12 + k] as f64);
        assert!((hi - 100.0 * lo).abs() <= 1e-5 * hi.abs(), "{lo} {hi}");
    }
}

#[test]
fn empty_frame_is_fine() {
    let model = fit(Kind::Rprm, 3, training()).unwrap();
    let mut f = Frame::new(0, 0, Layout::Rgba);
    apply_frame(&model, &mut f);
    apply_frame_single(&model, &mut f);
    assert!(f.data.is_empty());
}

/// NSRM 3 and PRM 3 on packed RGB through the explicit-vector kernels (`fast/explicit.rs`) give
/// the per-pixel kernels' bits (NaN payloads aside: NaN where they give NaN), for the detected
/// code, the AVX2 + FMA kernels wherever the CPU has AVX2 + FMA (forced on an AVX-512 CPU, where
/// they are not chosen) and the baseline (SSE2): every size around their 8-pixel blocks and the chunk edge, awkward pixels
/// (NaN, ±∞, subnormals, `s ≤ 0`, huge values: the PRM 3 blocks that take the exact path), unit
/// and white-balance gains, in place and into, one thread and all.
#[test]
fn explicit_vectors_give_the_per_pixel_kernels_bits() {
    // Every NaN one value: where two different NaNs meet, which comes out is the compiler's
    // choice on either path.
    let bits = |f: &Frame| {
        f.data
            .iter()
            .map(|v| if v.is_nan() { u32::MAX } else { v.to_bits() })
            .collect::<Vec<u32>>()
    };
    let mixed = [
        [f32::INFINITY, f32::NEG_INFINITY, f32::NAN],
        [f32::NAN, -f32::NAN, 1.0],
        [f32::NEG_INFINITY, f32::NAN, -f32::NAN],
        [f32::INFINITY, f32::INFINITY, f32::NEG_INFINITY],
    ];
    let models = [
        fit(Kind::Nsrm, 3, training()).unwrap(),
        white_balanced_nsrm().remove(2),
        fit(Kind::Prm, 3, training()).unwrap(),
    ];
    let chunk = super::fast::CHUNK_PIXELS;
    let sizes = [
        1,
        7,
        8,
        9,
        15,
        16,
        17,
        24,
        25,
        1000,
        chunk - 1,
        chunk + 5,
        3 * chunk + 13,
    ];
    for model in &models {
        let fast = FastModel::new(model);
        assert!(["nsrm3", "prm3"].contains(&fast.kernel_name()));
        println!(
            "{} {}: explicit vectors for the detected code here: {:?}",
            model.kind(),
            model.order(),
            fast.explicit_vectors()
        );
        // Awkward pixels throughout, and ordinary ones (camera values, some negative, with one
        // awkward pixel in about 50, some with two or three different non-finite values) so that
        // most blocks take the register path.
        let frames = sizes.iter().enumerate().flat_map(|(n, &w)| {
            let awkward = random_frame(w, 1, Layout::Rgb, 7000 + n as u64);
            let mut rng = Rng(9000 + n as u64);
            let mut ordinary = awkward.clone();
            for p in ordinary.data.chunks_exact_mut(3) {
                if rng.below(50) != 0 {
                    for v in p.iter_mut() {
                        *v = rng.range(-0.05, 4.0);
                    }
                } else if rng.below(2) == 0 {
                    p.copy_from_slice(&mixed[rng.below(mixed.len() as u64)]);
                }
            }
            [awkward, ordinary]
        });
        for input in frames {
            let w = input.width;
            let mut want = input.clone();
            fast.apply_pixel_loop(&mut want, Threads::Single);
            let mut want_baseline = input.clone();
            fast.apply_baseline_pixel_loop(&mut want_baseline, Threads::Single);
            for threads in [Threads::Single, Threads::All] {
                let mut got = input.clone();
                fast.apply(&mut got, threads);
                assert_eq!(bits(&got), bits(&want), "in place, {w} pixels");
                let mut into = Frame::new(w, 1, Layout::Rgb);
                fast.apply_into(&input, &mut into, threads).unwrap();
                assert_eq!(bits(&into), bits(&want), "into, {w} pixels");
                let mut baseline = input.clone();
                fast.apply_baseline(&mut baseline, threads);
                assert_eq!(
                    bits(&baseline),
                    bits(&want_baseline),
                    "baseline, {w} pixels"
                );
                let mut forced = input.clone();
                if fast.apply_forced_avx2(&mut forced, threads) {
                    assert_eq!(bits(&forced), bits(&want), "AVX2 + FMA, {w} pixels");
                }
            }
        }
    }
}

mod properties {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        /// Any finite pixel, any kind and order: within the bound of the reference.
        #[test]
        fn any_finite_pixel(
            r in -1.0f32..200.0, g in -1.0f32..200.0, b in -1.0f32..200.0,
            k in 0usize..4, order in 1u8..=4,
        ) {
            let kind = Kind::ALL[k];
            let model = fit(kind, order, training()).unwrap();
            let input = Frame::from_data(1, 1, Layout::Rgb, vec![r, g, b]).unwrap();
            let out = run_all_paths(&model, &input);
            compare(&model, &input, &out, "proptest");
        }
    }
}
