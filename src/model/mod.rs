//! The four colour-correction models: their terms ([`mod@terms`]), the least-squares fit, the
//! [`Model`] value with its JSON file ([`mod@file`]), and the f64 CPU reference apply path.
//!
//! Every apply path follows one pixel policy (NaN/Inf propagate, NSRM `s ≤ 0 → 0`, sign-preserving
//! roots, nothing clamped), described once as a pixel program in [`pixel`] (`pixel::Program`:
//! the steps of a kind over its term list), from which the f64 reference, the fast kernels, the
//! WGSL and the DCTL are evaluated or printed.
//! Input gains (white-balanced NSRM, [`Model::input_gains`]): every path multiplies R, G, B by the
//! gains first; the policy then holds for the gained pixel (`s = g_R·R + g_G·G + g_B·B`). Gains
//! are positive, so exposure invariance is kept.

pub(crate) mod dual_illuminant;
#[cfg(test)]
mod dual_illuminant_tests;
pub(crate) mod fast;
#[cfg(test)]
mod fast_tests;
pub(crate) mod file;
pub(crate) mod fit;
pub(crate) mod highlights;
pub(crate) mod output;
pub(crate) mod pixel;
#[cfg(test)]
mod policy_tests;
mod refine;
pub(crate) mod terms;

pub(crate) use terms::MAX_ORDER;
pub(crate) use terms::{term_name, terms, Term};

use crate::training::{Provenance, TrainingSet};

/// Errors from fitting, loading or validating a model.
#[derive(Debug, thiserror::Error)]
pub enum ModelError {
    /// A model kind name (held here) that is not lrm, prm, rprm or nsrm.
    #[error("unknown model kind `{0}` (expected lrm, prm, rprm or nsrm)")]
    UnknownKind(String),
    /// A model order (held here) outside 1..=4.
    #[error("order {0} is out of range (1..=4)")]
    Order(u8),
    /// Fewer training patches than the model has terms.
    #[error("{kind} order {order} has {terms} terms but only {patches} patches were given: a least-squares fit needs at least as many patches as terms")]
    TooFewPatches {
        /// The model kind.
        kind: Kind,
        /// The model order.
        order: u8,
        /// The number of terms of that kind and order.
        terms: usize,
        /// The number of training patches given.
        patches: usize,
    },
    /// A training patch with a NaN or infinite RGB or XYZ value.
    #[error("training patch `{label}` has non-finite data (RGB {rgb:?}, XYZ {xyz:?})")]
    NonFinite {
        /// The patch's label.
        label: String,
        /// The patch's camera RGB.
        rgb: [f64; 3],
        /// The patch's reference XYZ.
        xyz: [f64; 3],
    },
    /// A training patch whose R+G+B is not positive (NSRM cannot use it).
    #[error("training patch `{label}`: R+G+B = {sum} ≤ 0, so NSRM's chromaticities are undefined")]
    NonPositiveSignal {
        /// The patch's label.
        label: String,
        /// The patch's R+G+B.
        sum: f64,
    },
    /// The fit produced a non-finite matrix (degenerate training data).
    #[error("the fit produced a non-finite matrix (the training data is degenerate)")]
    Degenerate,
    /// No ridge λ makes the model's f32 evaluation (fast CPU path, shaders) reproduce its f64
    /// in-sample ΔE00: the terms are too nearly collinear on this data.
    #[error("{kind} order {order}: evaluating the fitted model in f32 (as apply does) moves its output by up to {bound:.3} ΔE00 (measured on the training patches and an in-gamut probe set), more than {tolerance}, and no ridge λ up to 100 brings it within: the terms are too nearly collinear on this data (choose a lower order)")]
    F32Unstable {
        /// The model kind.
        kind: Kind,
        /// The model order.
        order: u8,
        /// The largest ΔE00 between f32 and f64 evaluation measured (training patches, probe set).
        bound: f64,
        /// The largest change accepted.
        tolerance: f64,
    },
    /// A training value too large or too small (but not 0) for a fit.
    #[error("training patch `{label}`: {what} = {value:.3e} is outside the range a fit accepts (0, or 1e-100 ≤ |v| ≤ 1e100): check the data's scale")]
    OutOfRange {
        /// The patch's label.
        label: String,
        /// Which of the patch's values is out of range.
        what: String,
        /// The value.
        value: f64,
    },
    /// An iterative computation (e.g. an SVD) did not converge.
    #[error("the {what} did not converge within {iterations} iterations")]
    NotConverged {
        /// The computation that did not converge.
        what: &'static str,
        /// The iteration limit reached.
        iterations: usize,
    },
    /// Training data, a fit option or a model (file) that cannot be used (the message says why).
    #[error("{0}")]
    Invalid(String),
    /// A clip level for the highlight policy that is not finite and positive (held here).
    #[error("the clip level {0:?} is not finite and positive in every channel")]
    ClipLevel([f64; 3]),
    /// The model maps no positive camera RGB to its white (the solve did not converge, or found
    /// the RGB held here with a channel at or below 0): clipped highlights have no neutral to go to.
    #[error("the model maps no positive camera RGB to its white (found {0:?}): its clipped highlights have no neutral to go to")]
    NoNeutral([f64; 3]),
    /// Highlights were to be clipped in a frame whose clip level is not known (not a camera raw
    /// file) and none was given.
    #[error("the frame records no clip level (only camera raw files do): give one, or keep the highlights' raw mapping")]
    NoClipLevel,
    /// A malformed fit option (objective, ridge, normalisation): a usage error.
    #[error("{0}")]
    Spec(String),
    /// The fit needs the camera response of the training white, and measured data has none:
    /// name a neutral patch ([`White::Patch`](fit::White::Patch)).
    #[error("the training data has no camera response of its white (measured data): name a neutral patch to take it from")]
    NoWhite,
    /// A model file could not be read.
    #[error("{path}: cannot read: {err}")]
    Io {
        /// Where the model came from (its file's path).
        path: String,
        /// The I/O error.
        err: std::io::Error,
    },
    /// A model file is not valid model JSON.
    #[error("{path}: not a model file: {err}")]
    Parse {
        /// Where the model came from (its file's path).
        path: String,
        /// The JSON error.
        err: serde_json::Error,
    },
}

impl ModelError {
    /// True for an unknown model kind, an order outside 1..=4 and a malformed fit option.
    pub fn is_usage(&self) -> bool {
        matches!(
            self,
            ModelError::UnknownKind(_)
                | ModelError::Order(_)
                | ModelError::Spec(_)
                | ModelError::ClipLevel(_)
                | ModelError::NoClipLevel
        )
    }

    /// A fit that needs the camera response of a white the data lacks: naming a neutral patch
    /// ([`crate::Param::WhitePatch`]) is the way out.
    pub fn concern(&self) -> Option<crate::error::Concern> {
        match self {
            ModelError::NoWhite => Some(crate::error::Concern::Remedy(
                crate::error::Param::WhitePatch,
            )),
            _ => None,
        }
    }
}

/// The model families of the paper.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Kind {
    /// Linear regression, `p = (R, G, B)`.
    #[cfg_attr(feature = "clap", value(name = "lrm"))]
    Lrm,
    /// Polynomial regression.
    #[cfg_attr(feature = "clap", value(name = "prm"))]
    Prm,
    /// Root-polynomial regression (Finlayson, Mackiewicz & Hurlbert 2015).
    #[cfg_attr(feature = "clap", value(name = "rprm"))]
    Rprm,
    /// Normalised-signal polynomial regression.
    #[cfg_attr(feature = "clap", value(name = "nsrm"))]
    Nsrm,
}

impl Kind {
    /// The four kinds, in the paper's order.
    pub const ALL: [Kind; 4] = [Kind::Lrm, Kind::Prm, Kind::Rprm, Kind::Nsrm];

    /// Lower-case name: `lrm`, `prm`, `rprm`, `nsrm` (what `fit --kind` takes).
    pub fn name(self) -> &'static str {
        match self {
            Kind::Lrm => "lrm",
            Kind::Prm => "prm",
            Kind::Rprm => "rprm",
            Kind::Nsrm => "nsrm",
        }
    }

    /// Parses a name, case-insensitively.
    pub fn parse(s: &str) -> Result<Kind, ModelError> {
        Kind::ALL
            .into_iter()
            .find(|k| k.name().eq_ignore_ascii_case(s.trim()))
            .ok_or_else(|| ModelError::UnknownKind(s.to_string()))
    }

    /// The order a model of this kind really has when `order` is asked for: LRM is always 1.
    pub fn effective_order(self, order: u8) -> u8 {
        if self == Kind::Lrm {
            1
        } else {
            order
        }
    }

    /// The names of the terms a model of this kind and (effective) order weighs, in the order of
    /// its matrix's columns (`R`, `G·B`, `r²`, `√(R·G)`, …): what `nsrm terms` lists.
    pub fn term_names(self, order: u8) -> Vec<String> {
        terms(self, order)
            .iter()
            .map(|t| term_name(self, t))
            .collect()
    }
}

/// Parses `lrm`, `prm`, `rprm` or `nsrm`, case-insensitively.
///
/// ```
/// let kind: nsrm::Kind = "NSRM".parse()?;
/// assert_eq!(kind, nsrm::Kind::Nsrm);
/// assert!("ccm".parse::<nsrm::Kind>().is_err());
/// # Ok::<(), nsrm::ModelError>(())
/// ```
impl std::str::FromStr for Kind {
    type Err = ModelError;
    fn from_str(s: &str) -> Result<Kind, ModelError> {
        Kind::parse(s)
    }
}

impl std::fmt::Display for Kind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.name().to_uppercase())
    }
}

/// A fitted model: kind, order, and the 3×L matrix over its terms.
///
/// Valid by construction: a `Model` is made only by [`fit`], [`Model::load`] /
/// [`Model::from_json`] or [`Model::from_matrix`], each of which checks the order, the matrix
/// shape and that every coefficient is finite, and the input gains wherever they are set. The term list is derived from (kind, order), never
/// given, so every apply path (f64, fast CPU, shaders) can rely on it without re-checking.
#[derive(Debug, Clone, PartialEq)]
pub struct Model {
    kind: Kind,
    order: u8,
    /// The terms, from [`terms::terms`] (cached here).
    terms: Vec<Term>,
    /// Row-major 3×L: `matrix[i * L + j]` weighs term `j` for output channel `i`.
    matrix: Vec<f64>,
    /// The Lab reference white of the training data (XYZ, same scale as the output).
    white_xyz: [f64; 3],
    /// Where the training data came from.
    provenance: Provenance,
    /// The training patch labels.
    patches: Vec<String>,
    /// How the matrix was fitted (objective, ridge λ, coefficient norm, condition number), when
    /// known: [`fit::fit_with`] sets it, the model file carries it.
    fit_report: Option<fit::FitReport>,
    /// Per-channel gains multiplied into camera RGB before the terms: `[1, 1, 1]` except for a
    /// white-balanced NSRM (the training white's response becomes `(1, 1, 1)`). Finite, `> 0`
    /// and finite in f32 (checked wherever they are set: the fit, the model file, a combination).
    input_gains: [f64; 3],
    /// Whether `white_xyz` is a frame's white that the model was combined for
    /// ([`dual_illuminant::Profile::combine`]) rather than its own training white: the output
    /// space then adapts from it exactly, never by the "counts as D65" shortcut of
    /// [`crate::colorimetry::spaces::OutputSpace::from_xyz`] (which is for a training white
    /// integrated on a coarse grid). Not stored in the model file.
    frame_white: bool,
    /// The highlight policy every apply path runs before the pixel program, when set
    /// ([`with_highlights`](Self::with_highlights)); not stored in the model file (the clip level
    /// is the frame's).
    highlights: Option<highlights::Highlights>,
}

impl Model {
    /// A model from a matrix, checking its shape and values.
    pub fn from_matrix(kind: Kind, order: u8, matrix: Vec<f64>) -> Result<Model, ModelError> {
        if !(1..=MAX_ORDER).contains(&order) {
            return Err(ModelError::Order(order));
        }
        let order = kind.effective_order(order);
        let terms = terms(kind, order);
        if matrix.len() != 3 * terms.len() {
            return Err(ModelError::Invalid(format!(
                "{kind} order {order} needs a 3×{} matrix, got {} values",
                terms.len(),
                matrix.len()
            )));
        }
        if let Some(v) = matrix.iter().find(|v| !finite_in_f32(**v)) {
            return Err(ModelError::Invalid(format!(
                "the matrix holds {v}, which is not a finite f32 (the fast CPU path and the shaders compute in f32)"
            )));
        }
        Ok(Model {
            kind,
            order,
            terms,
            matrix,
            white_xyz: crate::colorimetry::D65_WHITE_XYZ,
            provenance: Provenance::default(),
            patches: Vec::new(),
            fit_report: None,
            input_gains: UNIT_GAINS,
            frame_white: false,
            highlights: None,
        })
    }

    /// The model family.
    pub fn kind(&self) -> Kind {
        self.kind
    }

    /// The order (LRM is always 1).
    pub fn order(&self) -> u8 {
        self.order
    }

    /// The terms, derived from (kind, order).
    pub(crate) fn terms(&self) -> &[Term] {
        &self.terms
    }

    /// Row-major 3×L: `matrix()[i * L + j]` weighs term `j` for output channel `i`.
    pub fn matrix(&self) -> &[f64] {
        &self.matrix
    }

    /// The Lab reference white of the training data (XYZ, same scale as the output).
    pub fn white_xyz(&self) -> [f64; 3] {
        self.white_xyz
    }

    /// Where the training data came from.
    pub fn provenance(&self) -> &Provenance {
        &self.provenance
    }

    /// The training patch labels.
    pub fn patches(&self) -> &[String] {
        &self.patches
    }

    /// The per-channel gains multiplied into camera RGB before the terms (`[1, 1, 1]` unless the
    /// model is a white-balanced NSRM).
    pub fn input_gains(&self) -> [f64; 3] {
        self.input_gains
    }

    /// Whether the input gains are all 1 (every model but a white-balanced NSRM).
    pub fn has_unit_gains(&self) -> bool {
        self.input_gains == UNIT_GAINS
    }

    /// The model with per-channel input gains: only NSRM may have gains other than `[1, 1, 1]`
    /// (for LRM and RPRM they fold into the matrix; PRM's are not defined), and each must be
    /// finite, `> 0` and finite in f32 (the fast CPU path and the shaders take them in f32).
    pub fn with_input_gains(mut self, gains: [f64; 3]) -> Result<Model, ModelError> {
        check_gains(self.kind, gains)?;
        self.input_gains = gains;
        Ok(self)
    }

    /// The term values of `rgb` (input gains applied first) written into `p` (length L), and the
    /// output scale (`s` for NSRM, 1 otherwise), or `None` when NSRM's `s ≤ 0`: `features` for
    /// this model.
    pub fn features_of(&self, rgb: [f64; 3], p: &mut [f64]) -> Option<f64> {
        self.program().features(self.input_gains, rgb, p)
    }

    /// The model's pixel program: its kind's steps over its terms (the one description every
    /// apply path and printer follows, [`pixel::Program`]).
    pub fn program(&self) -> pixel::Program<'_> {
        pixel::Program::new(self.kind, &self.terms)
    }

    /// How the matrix was fitted, when known (see [`fit::FitReport`]).
    pub fn fit_report(&self) -> Option<&fit::FitReport> {
        self.fit_report.as_ref()
    }

    /// The model with another Lab reference white (XYZ, finite, `Y > 0`): for a matrix made with
    /// [`from_matrix`](Self::from_matrix), whose white is D65 with `Y = 100`.
    pub(crate) fn with_white_xyz(mut self, white_xyz: [f64; 3]) -> Result<Model, ModelError> {
        check_white(white_xyz)?;
        self.white_xyz = white_xyz;
        Ok(self)
    }

    /// The model with `white_xyz` as its white, marked as a frame's white (see `frame_white`).
    pub(crate) fn with_frame_white(mut self, white_xyz: [f64; 3]) -> Result<Model, ModelError> {
        check_white(white_xyz)?;
        self.white_xyz = white_xyz;
        self.frame_white = true;
        Ok(self)
    }

    /// Whether the model's white is a frame's white it was combined for (not its training white).
    pub(crate) fn has_frame_white(&self) -> bool {
        self.frame_white
    }

    /// The model with a record of its training data (where it came from, the patch labels).
    pub(crate) fn with_training(mut self, provenance: Provenance, patches: Vec<String>) -> Model {
        self.provenance = provenance;
        self.patches = patches;
        self
    }

    /// Number of terms L.
    pub fn len_terms(&self) -> usize {
        self.terms.len()
    }

    /// Term names in order.
    pub fn term_names(&self) -> Vec<String> {
        self.terms.iter().map(|t| term_name(self.kind, t)).collect()
    }

    /// Row `i` (output channel) of the matrix.
    pub(crate) fn row(&self, i: usize) -> &[f64] {
        let l = self.terms.len();
        &self.matrix[i * l..(i + 1) * l]
    }

    /// Replaces the matrix (same kind and order), e.g. to swap a model at run time.
    pub fn set_matrix(&mut self, matrix: Vec<f64>) -> Result<(), ModelError> {
        let m = Model::from_matrix(self.kind, self.order, matrix)?;
        self.matrix = m.matrix;
        Ok(())
    }

    /// Applies the model to one camera RGB in f64 (the input gains first, then the terms): the
    /// reference every faster path is checked against. Follows the pixel policy (the README's *Pixel policy*).
    pub fn apply_f64(&self, rgb: [f64; 3]) -> [f64; 3] {
        let mut p = vec![0.0; self.terms.len()];
        self.apply_f64_with(rgb, &mut p)
    }

    /// [`apply_f64`](Self::apply_f64) with a caller-provided term buffer (length L).
    pub(crate) fn apply_f64_with(&self, rgb: [f64; 3], p: &mut [f64]) -> [f64; 3] {
        let rgb = match &self.highlights {
            Some(h) => h.map(rgb),
            None => rgb,
        };
        self.program().eval(&self.matrix, self.input_gains, rgb, p)
    }

    /// The pixel program alone, without the highlight policy.
    pub(crate) fn apply_f64_plain(&self, rgb: [f64; 3]) -> [f64; 3] {
        let mut p = vec![0.0; self.terms.len()];
        self.program()
            .eval(&self.matrix, self.input_gains, rgb, &mut p)
    }

    /// The model with a highlight policy for clip levels `clip` (camera RGB, per channel), or
    /// without one (`None`: the raw mapping is kept). Set it on the model in XYZ, before an output
    /// space is folded in ([`output::output_model`] keeps it): the neutral is found from the
    /// model's white. See [`highlights`].
    pub fn with_highlights(mut self, clip: Option<[f64; 3]>) -> Result<Model, ModelError> {
        self.highlights = match clip {
            Some(c) => Some(highlights::Highlights::for_model(&self, c)?),
            None => None,
        };
        Ok(self)
    }

    /// The model with the highlight policy `policy` (made for this model in XYZ, or for the
    /// models it was folded or combined from: see [`highlights::FrameHighlights`]).
    pub fn with_policy(mut self, policy: Option<highlights::Highlights>) -> Model {
        self.highlights = policy;
        self
    }

    /// The highlight policy, when set.
    #[cfg(any(feature = "gpu", test))]
    pub(crate) fn highlights(&self) -> Option<&highlights::Highlights> {
        self.highlights.as_ref()
    }

    /// Corrects a frame in place on the CPU (alpha untouched): the CPU frame back end.
    ///
    /// Computes in f32 with vectorised kernels, on every thread of rayon's current pool (the
    /// global pool; call it inside `rayon::ThreadPool::install` to choose the threads). Follows
    /// the pixel policy and agrees with [`apply_f64`](Self::apply_f64) to f32 precision.
    ///
    /// ```
    /// use nsrm::{fit, simulate_named, Frame, Grid, Kind, Layout};
    /// let data = simulate_named("nikon-d5100", "D65", "cc24", &Grid::default())?;
    /// let model = fit(Kind::Rprm, 2, &data)?;
    /// let rgb = data.rgb[5];
    /// let mut frame = Frame::new(1, 1, Layout::Rgb);
    /// frame.data.copy_from_slice(&rgb.map(|v| v as f32));
    /// model.apply_frame(&mut frame);
    /// let want = model.apply_f64(rgb);
    /// for c in 0..3 {
    ///     assert!((f64::from(frame.data[c]) - want[c]).abs() <= 1e-4 * want[c].abs());
    /// }
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn apply_frame(&self, frame: &mut crate::frame::Frame) {
        fast::apply_frame(self, frame)
    }

    /// Applies the f64 reference to every pixel of a frame in place (alpha untouched): the oracle
    /// for the fast CPU path and the GPU shaders. Each pixel is widened to f64, corrected, and
    /// rounded once to f32.
    #[cfg(test)]
    pub(crate) fn apply_frame_f64(&self, frame: &mut crate::frame::Frame) {
        let ch = frame.layout.channels();
        let mut p = vec![0.0; self.terms.len()];
        for px in frame.data.chunks_exact_mut(ch) {
            let out = self.apply_f64_with([px[0] as f64, px[1] as f64, px[2] as f64], &mut p);
            for k in 0..3 {
                px[k] = out[k] as f32;
            }
        }
    }
}

/// The input gains of every model but a white-balanced NSRM.
pub(crate) const UNIT_GAINS: [f64; 3] = [1.0; 3];

/// Input gains: finite, `> 0`, finite in f32; other than 1 for NSRM only.
fn check_gains(kind: Kind, g: [f64; 3]) -> Result<(), ModelError> {
    if !g
        .iter()
        .all(|v| finite_in_f32(*v) && *v > 0.0 && (*v as f32) > 0.0)
    {
        return Err(ModelError::Invalid(format!(
            "invalid input gains {g:?}: each must be finite and > 0 in f32"
        )));
    }
    if kind != Kind::Nsrm && g != UNIT_GAINS {
        return Err(ModelError::Invalid(format!(
            "input gains {g:?} on a {kind} model: only NSRM takes input gains (white-balanced normalisation)"
        )));
    }
    Ok(())
}

/// A reference white must be finite with a positive Y (the output is scaled by it).
fn check_white(w: [f64; 3]) -> Result<(), ModelError> {
    if w.iter().all(|v| v.is_finite()) && w[1] > 0.0 {
        Ok(())
    } else {
        Err(ModelError::Invalid(format!(
            "invalid reference white {w:?}"
        )))
    }
}

/// Whether `v` is finite and stays finite when rounded to f32 (the precision of every apply path
/// but the f64 reference).
fn finite_in_f32(v: f64) -> bool {
    v.is_finite() && (v as f32).is_finite()
}

/// Writes the term values of `rgb` into `p` and returns the output scale (`s` for NSRM, 1
/// otherwise), or `None` when NSRM's `s ≤ 0` (the output is then 0 by the pixel policy).
/// `rgb` is taken as already multiplied by any input gains: this is the kind's
/// [`pixel::Program`] evaluated with unit gains.
pub(crate) fn features(kind: Kind, terms: &[Term], rgb: [f64; 3], p: &mut [f64]) -> Option<f64> {
    pixel::Program::new(kind, terms).features(UNIT_GAINS, rgb, p)
}

/// Least-squares fit of `kind` at `order` to a training set, by SVD (never the normal equations).
///
/// LRM, PRM and RPRM fit `XYZ ≈ M·p(RGB)`. NSRM fits the normalised targets
/// `(α, β, γ) = XYZ / s ≈ M·p(r, g)`, `s = R+G+B`, as in the paper. The variants (ΔE00 objective,
/// white preservation, ridge, white-balanced NSRM) are [`fit::fit_with`].
pub fn fit(kind: Kind, order: u8, data: &TrainingSet) -> Result<Model, ModelError> {
    fit::fit_with(kind, order, data, &fit::FitOptions::default()).map(|f| f.model)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn synthetic(n: usize) -> TrainingSet {
        // A deterministic spread of positive RGBs and an XYZ that no model reproduces exactly.
        let mut rgb = Vec::new();
        let mut xyz = Vec::new();
        let mut labels = Vec::new();
        let mut state = 12345u64;
        let mut rnd = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 11) as f64) / ((1u64 << 53) as f64)
        };
        for i in 0..n {
            let c = [0.05 + rnd(), 0.05 + rnd(), 0.05 + rnd()];
            let x = [
                40.0 * c[0] + 30.0 * c[1] + 10.0 * c[2] + 5.0 * (c[0] * c[1]).sqrt(),
                20.0 * c[0] + 70.0 * c[1] + 5.0 * c[2],
                2.0 * c[0] + 10.0 * c[1] + 90.0 * c[2] + 3.0 * c[2] * c[2],
            ];
            rgb.push(c);
            xyz.push(x);
            labels.push(format!("p{i}"));
        }
        TrainingSet {
            labels,
            rgb,
            xyz,
            white_xyz: [95.0, 100.0, 108.0],
            white_rgb: None,
            provenance: Provenance::default(),
        }
    }

    #[test]
    fn lrm_recovers_an_exact_linear_map() {
        let mut ts = synthetic(30);
        let m = [[41.0, 35.8, 18.0], [21.3, 71.5, 7.2], [1.9, 11.9, 95.0]];
        ts.xyz = ts
            .rgb
            .iter()
            .map(|c| crate::colorimetry::spaces::apply(&m, *c))
            .collect();
        let model = fit(Kind::Lrm, 3, &ts).unwrap();
        assert_eq!(model.order, 1);
        for i in 0..3 {
            for j in 0..3 {
                assert!((model.row(i)[j] - m[i][j]).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn too_few_patches_and_bad_data_are_refused() {
        let ts = synthetic(12);
        let e = fit(Kind::Prm, 3, &ts).unwrap_err();
        assert!(
            matches!(
                e,
                ModelError::TooFewPatches {
                    terms: 19,
                    patches: 12,
                    ..
                }
            ),
            "{e}"
        );
        assert!(e.to_string().contains("19 terms"));
        let mut bad = synthetic(30);
        bad.xyz[3][1] = f64::NAN;
        assert!(matches!(
            fit(Kind::Lrm, 1, &bad),
            Err(ModelError::NonFinite { .. })
        ));
        let mut bad = synthetic(30);
        bad.rgb[5] = [0.0, 0.0, 0.0];
        assert!(matches!(
            fit(Kind::Nsrm, 3, &bad),
            Err(ModelError::NonPositiveSignal { .. })
        ));
        assert!(matches!(
            fit(Kind::Nsrm, 5, &bad),
            Err(ModelError::Order(5))
        ));
    }

    #[test]
    fn every_kind_and_order_fits_and_beats_lrm_in_sample() {
        let ts = synthetic(60);
        let err = |m: &Model| -> f64 {
            ts.rgb
                .iter()
                .zip(&ts.xyz)
                .map(|(c, x)| {
                    let y = m.apply_f64(*c);
                    (0..3).map(|k| (y[k] - x[k]).powi(2)).sum::<f64>()
                })
                .sum()
        };
        let lrm = err(&fit(Kind::Lrm, 1, &ts).unwrap());
        for kind in [Kind::Prm, Kind::Rprm] {
            for order in 2..=4 {
                let m = fit(kind, order, &ts).unwrap();
                assert!(err(&m) < lrm, "{kind} {order}");
            }
        }
        for order in 1..=4 {
            fit(Kind::Nsrm, order, &ts).unwrap();
        }
    }

    #[test]
    fn from_matrix_validates_once_and_derives_the_terms() {
        for kind in Kind::ALL {
            for order in 1..=MAX_ORDER {
                let l = terms(kind, kind.effective_order(order)).len();
                let m = Model::from_matrix(kind, order, vec![0.5; 3 * l]).unwrap();
                assert_eq!(
                    m.terms(),
                    terms(kind, kind.effective_order(order)).as_slice()
                );
                assert_eq!(m.order(), kind.effective_order(order));
                let short = Model::from_matrix(kind, order, vec![0.5; 3 * l - 1]).unwrap_err();
                assert!(short.to_string().contains("matrix"), "{short}");
            }
        }
        // Finite in f64 but not in f32 (the precision of the fast path and the shaders).
        let mut v = vec![0.5; 9];
        v[4] = 1e300;
        let e = Model::from_matrix(Kind::Lrm, 1, v.clone()).unwrap_err();
        assert!(e.to_string().contains("not a finite f32"), "{e}");
        v[4] = f64::NAN;
        assert!(Model::from_matrix(Kind::Lrm, 1, v).is_err());
        assert!(matches!(
            Model::from_matrix(Kind::Prm, 0, vec![0.5; 9]),
            Err(ModelError::Order(0))
        ));
        let mut m = Model::from_matrix(Kind::Lrm, 1, vec![0.5; 9]).unwrap();
        assert!(m.set_matrix(vec![0.5; 10]).is_err());
        assert!(m.set_matrix(vec![f64::INFINITY; 9]).is_err());
        assert_eq!(m.matrix(), &[0.5; 9]);
        let m = m.with_white_xyz([95.0, 100.0, 108.0]).unwrap();
        assert_eq!(m.white_xyz(), [95.0, 100.0, 108.0]);
        assert!(m.clone().with_white_xyz([95.0, 0.0, 108.0]).is_err());
        assert!(m.with_white_xyz([f64::NAN, 100.0, 108.0]).is_err());
    }

    #[test]
    fn input_gains_are_validated_and_applied_first() {
        let ts = synthetic(30);
        let m = fit(Kind::Nsrm, 3, &ts).unwrap();
        assert!(m.has_unit_gains());
        let g = [1.7, 1.0, 0.6];
        let wb = m.clone().with_input_gains(g).unwrap();
        assert_eq!(wb.input_gains(), g);
        for c in &ts.rgb {
            assert_eq!(
                wb.apply_f64(*c),
                m.apply_f64([c[0] * g[0], c[1] * g[1], c[2] * g[2]])
            );
        }
        assert_ne!(wb.apply_f64(ts.rgb[0]), m.apply_f64(ts.rgb[0]));
        // set_matrix keeps the gains.
        let mut s = wb.clone();
        s.set_matrix(m.matrix().to_vec()).unwrap();
        assert_eq!(s.input_gains(), g);
        for bad in [
            [0.0, 1.0, 1.0],
            [1.0, -1.0, 1.0],
            [1.0, 1.0, f64::NAN],
            [f64::INFINITY, 1.0, 1.0],
            [1e300, 1.0, 1.0],
            [1e-300, 1.0, 1.0],
        ] {
            let e = m.clone().with_input_gains(bad).unwrap_err();
            assert!(
                e.to_string().contains("invalid input gains"),
                "{bad:?}: {e}"
            );
        }
        for kind in [Kind::Lrm, Kind::Prm, Kind::Rprm] {
            let other = fit(kind, 2, &ts).unwrap();
            let e = other.clone().with_input_gains(g).unwrap_err();
            assert!(e.to_string().contains("only NSRM"), "{kind}: {e}");
            assert!(other.with_input_gains(UNIT_GAINS).is_ok());
        }
    }

    #[test]
    fn nsrm_policy_for_non_positive_signal() {
        let ts = synthetic(30);
        let m = fit(Kind::Nsrm, 3, &ts).unwrap();
        assert_eq!(m.apply_f64([0.0, 0.0, 0.0]), [0.0; 3]);
        assert_eq!(m.apply_f64([0.1, -0.2, 0.05]), [0.0; 3]);
        assert!(m.apply_f64([f64::NAN, 0.1, 0.1])[0].is_nan());
        assert!(!m.apply_f64([f64::INFINITY, 0.1, 0.1])[0].is_finite());
        let r = fit(Kind::Rprm, 3, &ts).unwrap();
        assert!(r.apply_f64([-0.01, 0.2, 0.3]).iter().all(|v| v.is_finite()));
    }
}
