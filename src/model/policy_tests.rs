//! The pixel policy (`super::pixel`) held on the f64 reference and on the fast CPU kernels, on
//! the pixels the policy is about (the GPU's share is `tests/all/pixel_policy.rs`; the pixels and
//! the check are the shared test kit's, `tests/all/common/kit.rs`). Moved here from the
//! integration tests when the fast path's internals became crate-private.

use super::fast::{FastModel, Threads};
use super::{pixel, Kind};
use crate::kit::{
    check_policy as check, fitted_models as models, policy_frame as frame_of, policy_pixels,
};

#[test]
fn the_policy_module_is_what_the_f64_reference_does() {
    for model in models() {
        let pixels = policy_pixels(model.kind());
        for (name, x) in &pixels {
            let x64 = x.map(|v| v as f64);
            let out = model.apply_f64(x64);
            if model.kind() == Kind::Nsrm {
                match pixel::nsrm_signal(x64) {
                    None => assert_eq!(out, [0.0; 3], "{name}"),
                    Some((s, r, g)) => {
                        // (α, β, γ) = M·p(r, g), XYZ = s·(α, β, γ).
                        let mut p = vec![0.0; model.terms().len()];
                        super::terms::expand(model.terms(), [r, g, 0.0], &mut p);
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
