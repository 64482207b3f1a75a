//! The printed DCTL of whole exports (`dctl::generate` of a model with its output space folded
//! in): Resolve is not available here, so it is compiled as C by the one harness of the test kit
//! (`kit::cc`, `kit::run_dctl`: a shim for the DCTL built-ins) and run on test pixels; its output
//! must match the f64 model to the f32 accuracy of the GPU shaders, and the pixel policy.
//! (Moved from `tests/all/export_dctl.rs`: `dctl::generate` is crate-private; the CLI test stayed
//! in `tests/all/gpu_export.rs`.)

use crate::kit::{
    cc, check_dctl as check, check_policy, dctl_pixels as pixels, policy_models, policy_pixels,
    run_dctl,
};
use nsrm::{fit, fit_with, simulate_named, FitOptions, Grid, Kind, Normalise, OutputSpace};

#[test]
fn dctl_compiles_as_c_and_matches_the_f64_model() {
    let Some(cc) = cc() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let data = simulate_named("nikon-d5100", "D65", "rawtoaces-190", &Grid::default()).unwrap();
    let px = pixels(&data);
    let wb = FitOptions {
        normalise: Normalise::WhiteBalanced,
        ..Default::default()
    };
    let mut models = Vec::new();
    for kind in Kind::ALL {
        for order in 1..=4u8 {
            if kind == Kind::Lrm && order > 1 {
                continue;
            }
            models.push((String::new(), fit(kind, order, &data).unwrap()));
        }
    }
    // White-balanced NSRM: the input gains are written into the DCTL.
    for order in 1..=4u8 {
        let m = fit_with(Kind::Nsrm, order, &data, &wb).unwrap().model;
        assert_ne!(m.input_gains(), [1.0; 3]);
        models.push(("_wb".into(), m));
    }
    {
        for (suffix, model) in models {
            let (kind, order) = (model.kind(), model.order());
            for space in [OutputSpace::Xyz, OutputSpace::Acescg] {
                let folded = nsrm::output_model(&model, space).unwrap();
                let dctl = super::dctl::generate(&folded, &["test".into()]).unwrap();
                assert!(dctl.contains("__DEVICE__ float3 transform(int p_Width"));
                let name = format!(
                    "{}{order}{suffix}_{}",
                    kind.name(),
                    space.name().replace('-', "_")
                );
                // The gain step is printed where the gains are not 1.
                assert_eq!(dctl.contains("x0 = x0 * "), !suffix.is_empty());
                let got = run_dctl(&cc, dir.path(), &name, &dctl, &px);
                check(&folded, &px, &got, &name);
                if kind == Kind::Nsrm {
                    // The pixel policy: R+G+B <= 0 (after the input gains) is black.
                    let mut p = vec![0.0; folded.matrix().len() / 3];
                    let black: Vec<usize> = (0..px.len())
                        .filter(|&i| {
                            folded.features_of(px[i], &mut p).is_none() && px[i] != [0.0; 3]
                        })
                        .collect();
                    assert!(!black.is_empty(), "{name}: no pixel with s < 0");
                    for i in black {
                        assert_eq!(got[i], [0.0; 3], "{name}: pixel {:?}", px[i]);
                    }
                }
            }
        }
    }
}

/// The printed DCTL follows the one pixel policy on the policy's pixels, every kind at every
/// order and white-balanced NSRM (from `tests/all/pixel_policy.rs`, whose other paths stayed).
#[test]
fn printed_dctl_follows_the_policy() {
    let Some(cc) = cc() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    for (i, model) in policy_models().into_iter().enumerate() {
        let pixels = policy_pixels(model.kind());
        let dctl = super::dctl::generate(&model, &[]).unwrap();
        let px: Vec<[f64; 3]> = pixels.iter().map(|(_, p)| p.map(|v| v as f64)).collect();
        let name = format!("policy{i}_{}{}", model.kind().name(), model.order());
        let got = run_dctl(&cc, dir.path(), &name, &dctl, &px);
        let out = nsrm::Frame::from_data(
            got.len(),
            1,
            nsrm::Layout::Rgb,
            got.iter().flat_map(|p| p.map(|v| v as f32)).collect(),
        )
        .unwrap();
        check_policy(&model, "printed DCTL (cc)", &out);
    }
}
