//! Every apply path against the one pixel policy (`nsrm::pixel`), on the pixels the policy
//! is about: black, `s < 0`, `s = 0` with non-zero channels, negative channels, NaN, ±Inf, huge,
//! tiny and subnormal values.
//!
//! Every path is a printer or evaluator of the one pixel program (`src/model/pixel.rs`). Paths
//! here: the GPU's printed WGSL (lavapipe; skipped with a loud line when there is no adapter,
//! failed under `CI=true`) and, in `crates/nsrm-export/src/dctl_tests.rs`, the printed DCTL (compiled as C by the kit's harness),
//! on every kind at every order 1–4 and white-balanced NSRM (non-unit input gains) at every order;
//! the f64 reference and the fast CPU kernels (the clone detected for this CPU and the baseline
//! clone without FMA, the hand-written kernel at order 3 and the generic plan at the other orders)
//! are held to the same check by the unit tests in `src/model/policy_tests.rs`. The pixels and the
//! check live in `tests/all/common/kit.rs`, shared by both.
//!
//! The rules checked directly, on every path:
//! * NSRM with `s ≤ 0` (`s` of the pixel times the input gains) gives exactly `(0, 0, 0)`;
//! * a NaN input channel gives a NaN output on every channel it reaches (every kind: all three);
//! * RPRM of finite negative channels is finite (sign-preserving roots);
//! * otherwise the output is the f64 reference within `1e-5·max(max|ref|, T_k) + 1e-30`, with
//!   `T_k = |s|·Σ_j |m_kj·p_j|` the size of the summands (where a fitted model cancels, f32 cannot
//!   do better); a non-finite reference needs a non-finite output (NaN for NaN).

use nsrm::gpu::{Engine, GpuError, GpuOptions};

use crate::common;
use common::{
    check_policy as check, policy_frame as frame_of, policy_models as models, policy_pixels,
};

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
        check(&model, "GPU", &f);
    }
}
