//! The fit-variant flags shared by `nsrm fit` and `nsrm eval`.

use super::common::UsageError;
use anyhow::{Context, Result};
use nsrm::{FitOptions, FitWhite as White, Normalise, Objective, Ridge};

/// How the matrix is fitted (the paper: least squares, raw input, no constraint, no ridge).
#[derive(Debug, Clone, clap::Args)]
pub(crate) struct FitVariantArgs {
    /// What the fit minimises: `ls` (least squares in XYZ, the paper), `de00` (Σ ΔE00² over the
    /// training patches, Levenberg–Marquardt from the least-squares solution) or `de00:P`
    /// (Σ ΔE00^P, 2 ≤ P ≤ 64: a larger P trades mean error for maximum error).
    #[arg(
        help_heading = "Fit",
        long,
        default_value = "ls",
        value_name = "OBJECTIVE"
    )]
    pub(crate) objective: String,
    /// Map the reference white exactly to its XYZ (an equality constraint, kept by `de00`): the
    /// perfect white of the training illuminant, or the patch named by `--white-patch`.
    #[arg(help_heading = "Fit", long)]
    pub(crate) preserve_white: bool,
    /// A neutral training patch to use as the white (for `--preserve-white` and
    /// `--normalise white-balanced`); needed with measured data, which has no perfect white.
    /// Its full label (`"19 white 9.5"`), its number (`19`) or its name (`white`).
    #[arg(help_heading = "Fit", long, value_name = "PATCH")]
    pub(crate) white_patch: Option<String>,
    /// Tikhonov regularisation of the matrix on standardised terms: λ ≥ 0, `auto` (λ chosen by
    /// generalised cross-validation on a log grid 1e-12..10; also `auto-gcv`) or `auto-loo` (by
    /// exact, closed-form leave-one-out of the ridge solve on the same grid). `0` means no ridge
    /// at all: not even the f32 guard's.
    #[arg(help_heading = "Fit", long, value_name = "RIDGE")]
    pub(crate) ridge: Option<String>,
    /// NSRM's input: `raw` (the paper) or `white-balanced` (R, G, B divided by the training white's
    /// camera response before forming s, r, g; the gains go into the model file).
    #[arg(help_heading = "Fit", long, value_enum, ignore_case = true, default_value_t = nsrm::Normalise::Raw)]
    pub(crate) normalise: nsrm::Normalise,
}

/// The GPU shader as the f32 guard's second measurement ([`nsrm::FitOptions::f32_also`]), where
/// `apply --device auto` would find a GPU: a hardware adapter, or the one `NSRM_ADAPTER` names
/// (lavapipe, say); `None` without one (the CPU kernel alone is measured).
pub(crate) fn gpu_check() -> Option<std::sync::Arc<dyn nsrm::F32Evaluator>> {
    nsrm::gpu::ShaderCheck::open(&nsrm::gpu::GpuOptions::default())
        .ok()
        .map(|c| std::sync::Arc::new(c) as std::sync::Arc<dyn nsrm::F32Evaluator>)
}

impl FitVariantArgs {
    /// The options these flags name.
    pub(crate) fn options(&self) -> Result<FitOptions> {
        let objective = Objective::parse(&self.objective).context("--objective")?;
        let ridge = match &self.ridge {
            Some(s) => Ridge::parse(s).context("--ridge")?,
            None => Ridge::None,
        };
        let normalise = self.normalise;
        if self.white_patch.is_some() && !self.preserve_white && normalise == Normalise::Raw {
            return Err(UsageError(
                "--white-patch needs --preserve-white or --normalise white-balanced".into(),
            )
            .into());
        }
        Ok(FitOptions {
            objective,
            preserve_white: self.preserve_white,
            white: match &self.white_patch {
                Some(l) => White::Patch(l.clone()),
                None => White::Perfect,
            },
            ridge,
            normalise,
            // An explicit `--ridge 0` means no ridge anywhere: not even the f32 guard's.
            f32_guard: !self.ridge_is_zero(),
            // The GPU is opened by the commands that write a model (`fit`, `calibrate`).
            f32_also: None,
        })
    }

    /// Whether `--ridge` names λ = 0 explicitly.
    pub(crate) fn ridge_is_zero(&self) -> bool {
        self.ridge
            .as_deref()
            .is_some_and(|s| Ridge::parse(s).is_ok_and(|r| r == Ridge::None))
    }

    /// `opts` with `--white-patch` resolved to the full label of one of `labels` (it may name
    /// the patch by its number or name).
    pub(crate) fn resolved(&self, opts: &FitOptions, labels: &[String]) -> Result<FitOptions> {
        let mut o = opts.clone();
        if let White::Patch(spec) = &opts.white {
            let l = nsrm::resolve_patch(labels, spec).context("--white-patch")?;
            o.white = White::Patch(l);
        }
        Ok(o)
    }

    /// The fit in a few words: `least squares` (the paper's), or the objective and options.
    pub(crate) fn method_name(&self) -> String {
        let mut parts = vec![if self.objective == "ls" {
            "least squares".to_string()
        } else {
            format!("objective {}", self.objective)
        }];
        if self.preserve_white {
            parts.push("white preserved".into());
        }
        if let Some(r) = &self.ridge {
            parts.push(format!("ridge {r}"));
        }
        if self.normalise != nsrm::Normalise::Raw {
            parts.push("white-balanced input".into());
        }
        parts.join(", ")
    }

    /// Whether any flag differs from the paper's fit.
    pub(crate) fn is_default(&self) -> bool {
        self.objective == "ls"
            && !self.preserve_white
            && self.white_patch.is_none()
            && self.ridge.is_none()
            && self.normalise == nsrm::Normalise::Raw
    }
}
