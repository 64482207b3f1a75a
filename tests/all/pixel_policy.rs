//! Every apply path against the one pixel policy (`nsrm::model::pixel`), on the pixels the policy
//! is about: black, `s < 0`, `s = 0` with non-zero channels, negative channels, NaN, ±Inf, huge,
//! tiny and subnormal values.
//!
//! Every path is a printer or evaluator of the one pixel program (`nsrm::model::pixel`): the f64
//! reference (its evaluator), the fast CPU kernels (the clone detected for this CPU and the
//! baseline clone without FMA, called directly through `FastModel::apply_baseline`; the
//! hand-written kernel at order 3 and the generic plan at the other orders), the GPU's printed
//! WGSL (lavapipe here; skipped with a loud line when there is no adapter, failed under
//! `CI=true`) and the printed DCTL (compiled as C by `cc`, as `export_dctl` does). Models: every
//! kind at every order 1–4, and white-balanced NSRM (non-unit input gains) at every order.
//!
//! The rules checked directly, on every path:
//! * NSRM with `s ≤ 0` (`pixel::nsrm_signal` of the pixel times the input gains is `None`) gives
//!   exactly `(0, 0, 0)`;
//! * a NaN input channel gives a NaN output on every channel it reaches (every kind: all three);
//! * RPRM of finite negative channels is finite (sign-preserving roots);
//! * otherwise the output is the f64 reference within `1e-5·max(max|ref|, T_k) + 1e-30`, with
//!   `T_k = |s|·Σ_j |m_kj·p_j|` the size of the summands (where a fitted model cancels, f32 cannot
//!   do better); a non-finite reference needs a non-finite output (NaN for NaN).

use nsrm::gpu::{Engine, GpuError, GpuOptions};
use nsrm::model::fast::{FastModel, Threads};
use nsrm::model::{pixel, Kind, Model};
use nsrm::{Frame, Layout};

use crate::common;
use common::summands;

/// Every kind at every order ([`common::fitted_models`]) and white-balanced NSRM (the program's
/// gain step with gains other than 1) at every order.
fn models() -> Vec<Model> {
    use nsrm::model::fit::{fit_with, FitOptions, Normalise};
    let mut v = common::fitted_models();
    let opts = FitOptions {
        normalise: Normalise::WhiteBalanced,
        ..Default::default()
    };
    for order in 1..=nsrm::model::MAX_ORDER {
        let m = fit_with(Kind::Nsrm, order, common::training(), &opts)
            .unwrap()
            .model;
        assert!(!m.has_unit_gains(), "{:?}", m.input_gains());
        v.push(m);
    }
    v
}

/// The policy's pixels, by name. `huge` only where the model is exposure-invariant (PRM's cubes and
/// fourth powers of 1e30 overflow f32 as they would in any f32 evaluation).
fn policy_pixels(kind: Kind) -> Vec<(&'static str, [f32; 3])> {
    let mut v = vec![
        ("black", [0.0, 0.0, 0.0]),
        ("negative zero", [-0.0, -0.0, -0.0]),
        ("s < 0", [-0.01, -0.02, 0.0]),
        ("s < 0, one positive", [0.1, -0.2, 0.05]),
        ("s = 0, channels non-zero", [0.5, -0.5, 0.0]),
        ("negative channel, s > 0", [0.4, -0.05, 0.3]),
        ("two negative channels, s > 0", [-0.1, -0.05, 0.6]),
        ("NaN R", [f32::NAN, 0.2, 0.3]),
        ("NaN G", [0.2, f32::NAN, 0.3]),
        ("NaN B", [0.2, 0.3, f32::NAN]),
        ("+Inf", [f32::INFINITY, 0.2, 0.3]),
        ("-Inf", [0.2, f32::NEG_INFINITY, 0.3]),
        ("+Inf and -Inf", [f32::INFINITY, f32::NEG_INFINITY, 0.3]),
        ("tiny", [1e-30, 2e-30, 3e-30]),
        ("subnormal", [1e-40, 2e-40, 1e-40]),
        ("single channel", [0.7, 0.0, 0.0]),
        ("ordinary", [0.2, 0.3, 0.25]),
        ("highlight ×1e4", [2e3, 3e3, 2.5e3]),
    ];
    if kind.exposure_invariant() {
        v.push(("huge", [1e30, 2e30, 1.5e30]));
        v.push(("huge, negative channel", [1e30, -1e29, 1.5e30]));
    }
    v
}

/// `x` times the model's input gains (its program's gain step).
fn gained(model: &Model, x: [f64; 3]) -> [f64; 3] {
    let g = model.input_gains();
    [x[0] * g[0], x[1] * g[1], x[2] * g[2]]
}

fn frame_of(pixels: &[(&str, [f32; 3])]) -> Frame {
    let data = pixels.iter().flat_map(|(_, p)| *p).collect();
    Frame::from_data(pixels.len(), 1, Layout::Rgb, data).unwrap()
}

/// Checks `out` (one path's result on `policy_pixels`) against the policy and the reference.
fn check(model: &Model, path: &str, out: &Frame) {
    let pixels = policy_pixels(model.kind());
    let mut reference = frame_of(&pixels);
    model.apply_frame_f64(&mut reference);
    for (i, (name, x)) in pixels.iter().enumerate() {
        let got = &out.data[3 * i..3 * i + 3];
        let want = &reference.data[3 * i..3 * i + 3];
        let ctx = format!(
            "{} {} on {path}, pixel `{name}` {x:?}: got {got:?}, reference {want:?}",
            model.kind(),
            model.order()
        );
        let x64 = x.map(|v| v as f64);
        if model.kind() == Kind::Nsrm && pixel::nsrm_signal(gained(model, x64)).is_none() {
            assert!(got.iter().all(|v| *v == 0.0), "s ≤ 0 must give 0: {ctx}");
            continue;
        }
        if x.iter().any(|v| v.is_nan()) {
            assert!(got.iter().all(|v| v.is_nan()), "NaN must propagate: {ctx}");
            continue;
        }
        if model.kind() == Kind::Rprm && x.iter().all(|v| v.is_finite()) {
            assert!(
                got.iter().all(|v| v.is_finite()),
                "RPRM must stay finite: {ctx}"
            );
        }
        let t = summands(model, x64);
        let scale = want.iter().map(|v| (*v as f64).abs()).fold(0.0, f64::max);
        for k in 0..3 {
            let (g, w) = (got[k] as f64, want[k] as f64);
            if w.is_nan() {
                assert!(g.is_nan(), "expected NaN: {ctx}");
            } else if w.is_infinite() {
                assert!(!g.is_finite(), "expected non-finite: {ctx}");
            } else {
                let bound = 1e-5 * scale.max(t[k]) + 1e-30;
                assert!(
                    g.is_finite() && (g - w).abs() <= bound,
                    "channel {k}: error {:e} > {bound:e}: {ctx}",
                    (g - w).abs()
                );
            }
        }
    }
}

#[test]
fn the_policy_module_is_what_the_f64_reference_does() {
    for model in models() {
        let pixels = policy_pixels(model.kind());
        for (name, x) in &pixels {
            let x64 = x.map(|v| v as f64);
            let out = model.apply_f64(x64);
            if model.kind() == Kind::Nsrm {
                // The gain step first (1, 1, 1 unless white-balanced), then the signal.
                match pixel::nsrm_signal(gained(&model, x64)) {
                    None => assert_eq!(out, [0.0; 3], "{name}"),
                    Some((s, r, g)) => {
                        // (α, β, γ) = M·p(r, g), XYZ = s·(α, β, γ).
                        let mut p = vec![0.0; model.terms().len()];
                        nsrm::model::terms::expand(model.terms(), [r, g, 0.0], &mut p);
                        for (k, o) in out.iter().enumerate() {
                            let want =
                                s * model.row(k).iter().zip(&p).map(|(m, v)| m * v).sum::<f64>();
                            assert!(
                                o.to_bits() == want.to_bits() || (o.is_nan() && want.is_nan()),
                                "{name}: {o} vs {want}"
                            );
                        }
                    }
                }
            }
        }
        check(&model, "f64 reference", &{
            let mut f = frame_of(&pixels);
            model.apply_frame_f64(&mut f);
            f
        });
    }
}

#[test]
fn fast_kernels_follow_the_policy_detected_and_baseline_clones() {
    for model in models() {
        let pixels = policy_pixels(model.kind());
        let fast = FastModel::new(&model);
        for threads in [Threads::Single, Threads::All] {
            let mut detected = frame_of(&pixels);
            fast.apply(&mut detected, threads);
            check(
                &model,
                &format!("fast {} (detected)", fast.kernel_name()),
                &detected,
            );
            let mut baseline = frame_of(&pixels);
            fast.apply_baseline(&mut baseline, threads);
            check(
                &model,
                &format!("fast {} (baseline, no FMA)", fast.kernel_name()),
                &baseline,
            );
        }
    }
}

#[test]
fn gpu_shaders_follow_the_policy_including_negative_signal() {
    let opts = GpuOptions {
        adapter: None,
        tile_pixels: None,
    };
    let mut engine = match Engine::new(&opts) {
        Ok(e) => e,
        Err(e @ GpuError::NoAdapter { .. }) => {
            crate::common::skip(&format!(
                "no GPU adapter (install mesa-vulkan-drivers libvulkan1): {e}"
            ));
            return;
        }
        Err(e) => panic!("cannot open the GPU engine: {e}"),
    };
    for model in models() {
        let mut f = frame_of(&policy_pixels(model.kind()));
        engine.apply(&model, &mut f).unwrap();
        check(&model, &format!("GPU {}", engine.adapter_name()), &f);
    }
}

#[cfg(feature = "cli")]
#[test]
fn printed_dctl_follows_the_policy() {
    let Some(cc) = crate::export_dctl::cc() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    for (i, model) in models().into_iter().enumerate() {
        let pixels = policy_pixels(model.kind());
        let dctl = nsrm::export::dctl::generate(&model, &[]).unwrap();
        let px: Vec<[f64; 3]> = pixels.iter().map(|(_, p)| p.map(|v| v as f64)).collect();
        let name = format!("policy{i}_{}{}", model.kind().name(), model.order());
        let got = crate::export_dctl::run_dctl(&cc, dir.path(), &name, &dctl, &px);
        let out = Frame::from_data(
            got.len(),
            1,
            Layout::Rgb,
            got.iter().flat_map(|p| p.map(|v| v as f32)).collect(),
        )
        .unwrap();
        check(&model, "printed DCTL (cc)", &out);
    }
}
