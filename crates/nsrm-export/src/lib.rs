//! Files other tools read: the Academy/SMPTE Common LUT Format (CLF v3), Resolve/OCIO `.cube`
//! and a minimal OpenColorIO v2 config ([`render`] with a [`Format`]), DaVinci Resolve DCTL
//! (`nsrm export-shader --lang dctl`), an Adobe DNG camera profile ([`dcp::render`]), an ICC
//! input profile ([`icc::render`]) and, with the `gpu` feature, baked shaders (`export_shader`).
//! Each is built and measured in memory and returned as bytes: where they are written is the
//! caller's (the `nsrm` command stages them in its output session).
//!
//! # What is written
//! Every export maps linear camera RGB (the training white at `G = 1`) to the output space exactly
//! as `nsrm apply` writes it: scene-linear, the training white at `Y = 1`, the output-space matrix
//! folded into the model ([`nsrm::output_model`]).
//!
//! * **LRM** is linear: one CLF `Matrix` node, exact (up to the f32 the readers compute in).
//! * **PRM, RPRM, NSRM** have no closed form in CLF (no division, no channel products), so they
//!   travel as a per-channel **shaper** followed by a **3D LUT** sampled from the f64 model:
//!   - CLF: `Range` (clamp each channel to `[0, 2^hi]`), `Log` (`cameraLinToLog`, base 2: `0 → 0`,
//!     `2^hi → 1`, logarithmic from one stop below `2^lo`, a straight line below that), `LUT3D`
//!     (default 65³, `interpolation="tetrahedral"`) sampled at the exact inverse of the shaper and
//!     holding the same log encoding of `L⁻¹·f(S)`, where `L` is the model's least-squares linear
//!     part on the training patches, then `Log` (`cameraLogToLin`) and `Matrix` `L`. The LUT so
//!     interpolates a function that is nearly the identity in log space (exactly so along the grey
//!     axis for the exposure-invariant models), which cuts the error about fourfold against
//!     storing `f(S)` directly.
//!   - `.cube`: a 1D shaper table sampled from the same curve over `[0, 2^hi]` and the 3D table
//!     sampled at the exact inverse of the *interpolated* 1D table. The format declares no
//!     interpolation: the table is measured for the one asked for (default tetrahedral, what
//!     OpenColorIO's `ocioconvert --lut` uses; Resolve's default is trilinear). Without a
//!     decoding step after the LUT, it holds `f(S)` itself and is less accurate than the CLF.
//!
//!   The range is in camera units: `lo = −6`, `hi = 4` by default, i.e. 2⁻⁶ to 2⁴ of the
//!   training white's green (10 stops; wider ranges cost accuracy, see the README). Outside it the LUT clamps: channels above `2^hi`
//!   saturate, negative channels are taken as 0, and below `2^(lo−1)` the lattice is linear in
//!   the signal (black stays black).
//!
//! # Measured error
//! [`LutExport::measure`] evaluates the written nodes (with the declared interpolation)
//! against the exact f64 model on the training patches and on a dense grid of chromaticities inside
//! the training patches' convex hull (camera `r, g`) at several exposures across the range, and
//! reports mean and max ΔE00. At exposure `k` the ΔE00 is taken against the training white × `k`
//! (each sample is judged as if exposed normally), so the figure does not shrink for dark samples.
#![forbid(unsafe_code)]
#![deny(unreachable_pub)]
#![warn(missing_docs)]

/// The unit tests' kit, shared with the integration tests (the corrector's public API only).
#[cfg(test)]
#[path = "../../../tests/all/common/kit.rs"]
#[allow(unreachable_pub, dead_code)]
mod kit;

pub(crate) mod clf;
pub(crate) mod cube;
pub mod dcp;
#[cfg(test)]
mod dcp_tests;
// DCTL is printed from the pixel program, as the shaders are (`nsrm export-shader --lang dctl`).
#[cfg(any(feature = "gpu", test))]
pub mod dctl;
#[cfg(test)]
mod dctl_tests;
pub mod icc;
pub mod nodes;
pub(crate) mod ocio;
#[cfg(test)]
mod ocio_tests;
#[cfg(feature = "gpu")]
pub mod shader;

pub use self::{
    dcp::{DcpOptions, DcpTraining, DcpWritten},
    icc::{IccOptions, IccWritten},
    nodes::Interpolation,
};
#[cfg(feature = "gpu")]
pub use shader::{export as export_shader, ShaderLang};

use nsrm::{Kind, Mat3, Model, OutputSpace};

/// The corrector's 3×3 matrix helpers, under the short names the exports use.
mod spaces {
    pub(crate) use nsrm::{apply_mat3 as apply, invert_mat3 as invert, mul_mat3 as mul};
    pub(crate) use nsrm::{primaries_to_xyz as rgb_to_xyz, xy_to_xyz, Mat3};
}

/// The corrector's correlated-colour-temperature helpers.
mod temperature {
    pub(crate) use nsrm::{
        bradford_between, cct, dng_weight, neutral_to_xy, temperature_xy, D50_XY,
    };
}
use nodes::{eval_chain, LogCurve, Lut1d, Lut3d, Node};

/// Errors from building or writing an export.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// A request that cannot be honoured (the user's mistake).
    #[error("{0}")]
    Usage(String),
    /// The model cannot be expressed in the format (a reference white that is not positive, …).
    #[error("the model cannot be exported: {0}")]
    Model(String),
    #[error(
        "the export's approximation error, max ΔE00 {max:.4} ({where_}), exceeds the limit {limit}"
    )]
    /// The export is further from the model than the ΔE00 limit asked for.
    TooInaccurate {
        /// The largest ΔE00 measured.
        max: f64,
        /// The limit.
        limit: f64,
        /// Where it was measured (training patches or the dense set).
        where_: String,
    },
}

impl ExportError {
    /// True for export options out of range.
    pub fn is_usage(&self) -> bool {
        matches!(self, ExportError::Usage(_))
    }
}

/// File formats `nsrm export` writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Format {
    /// Academy/SMPTE Common LUT Format v3 (`.clf`).
    #[cfg_attr(feature = "clap", value(name = "clf"))]
    Clf,
    /// Resolve/OCIO `.cube` (1D shaper and 3D table).
    #[cfg_attr(feature = "clap", value(name = "cube"))]
    Cube,
    /// A minimal OpenColorIO v2 config with its CLF beside it.
    #[cfg_attr(feature = "clap", value(name = "ocio"))]
    Ocio,
    /// A DNG Camera Profile (`.dcp`) for raw developers (Lightroom/Camera Raw, RawTherapee).
    #[cfg_attr(feature = "clap", value(name = "dcp"))]
    Dcp,
    /// An ICC input profile (`.icc`), a LUT-based camera profile.
    #[cfg_attr(feature = "clap", value(name = "icc"))]
    Icc,
}

impl Format {
    /// Parses `clf`, `cube` or `ocio`.
    pub fn parse(s: &str) -> Option<Format> {
        match s.trim().to_ascii_lowercase().as_str() {
            "clf" => Some(Format::Clf),
            "cube" => Some(Format::Cube),
            "ocio" => Some(Format::Ocio),
            "dcp" => Some(Format::Dcp),
            "icc" => Some(Format::Icc),
            _ => None,
        }
    }

    /// The name `export --format` takes (`clf`, `cube`, `ocio`, `dcp`, `icc`).
    pub fn name(self) -> &'static str {
        match self {
            Format::Clf => "clf",
            Format::Cube => "cube",
            Format::Ocio => "ocio",
            Format::Dcp => "dcp",
            Format::Icc => "icc",
        }
    }
}

/// The smallest and largest 3D LUT size accepted (OpenColorIO reads .cube lattices of 2..=129).
pub(crate) const LUT_SIZES: std::ops::RangeInclusive<usize> = 2..=129;
/// The largest .cube shaper accepted.
pub(crate) const MAX_SHAPER_SIZE: usize = 65536;

/// How far (in stops) below the bottom of the documented range the shaper's logarithmic part
/// starts: the lattice is smooth across the whole range, and the straight segment that takes the
/// curve through 0 stays below it.
pub(crate) const TOE_STOPS: f64 = 1.0;

/// How the LUT of a nonlinear model is built.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LutOptions {
    /// Lattice points per axis of the 3D LUT (default 65).
    pub size: usize,
    /// log2 of the bottom and top of the shaper's logarithmic range, in camera units (the
    /// training white has G = 1): default −6 and 4.
    pub stops: [f64; 2],
    /// Entries of the .cube 1D shaper (default 65536).
    pub shaper_size: usize,
    /// The interpolation the 3D LUT is declared (CLF) or meant (.cube) for, and measured with
    /// (default tetrahedral: OpenColorIO's best, what `ocioconvert --lut` uses for .cube).
    pub interpolation: Interpolation,
}

impl Default for LutOptions {
    fn default() -> Self {
        LutOptions {
            size: 65,
            stops: [-6.0, 4.0],
            shaper_size: 65536,
            interpolation: Interpolation::Tetrahedral,
        }
    }
}

impl LutOptions {
    /// Checks the sizes and the range.
    pub fn check(&self) -> Result<(), ExportError> {
        if !LUT_SIZES.contains(&self.size) {
            return Err(ExportError::Usage(format!(
                "LUT size {} is out of range ({}..={})",
                self.size,
                LUT_SIZES.start(),
                LUT_SIZES.end()
            )));
        }
        if !(2..=MAX_SHAPER_SIZE).contains(&self.shaper_size) {
            return Err(ExportError::Usage(format!(
                "shaper size {} is out of range (2..={MAX_SHAPER_SIZE})",
                self.shaper_size
            )));
        }
        let [lo, hi] = self.stops;
        if !(lo.is_finite()
            && hi.is_finite()
            && (-24.0..=16.0).contains(&lo)
            && lo < hi
            && hi <= 16.0
            && hi - lo >= 1.0)
        {
            return Err(ExportError::Usage(format!(
                "exposure range 2^{lo}..2^{hi} is invalid (need −24 ≤ lo, lo + 1 ≤ hi ≤ 16)"
            )));
        }
        Ok(())
    }

    /// The shaper curve: `0 → 0`, log2 from `2^(lo − TOE_STOPS)` to `2^hi → 1`.
    pub(crate) fn curve(&self) -> LogCurve {
        LogCurve::zero_to_one((self.stops[0] - TOE_STOPS).exp2(), self.stops[1].exp2())
    }
}

/// The step of the dense chromaticity grid (camera `r, g`).
pub(crate) const DENSE_STEP: f64 = 0.005;
/// The step, in stops, between the exposures of the dense set.
pub(crate) const EXPOSURE_STEP: f64 = 0.125;

/// ΔE00 statistics over a sample set.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ErrorStats {
    /// Samples measured.
    pub count: usize,
    /// Mean ΔE00.
    pub mean: f64,
    /// Largest ΔE00.
    pub max: f64,
}

impl ErrorStats {
    fn from(values: &[f64]) -> ErrorStats {
        let count = values.len();
        if count == 0 {
            return ErrorStats::default();
        }
        // A NaN (an error that could not be measured) is the maximum: it must fail any limit.
        let max = if values.iter().any(|v| v.is_nan()) {
            f64::NAN
        } else {
            values.iter().cloned().fold(0.0, f64::max)
        };
        ErrorStats {
            count,
            mean: values.iter().sum::<f64>() / count as f64,
            max,
        }
    }

    /// The one of `self` and `other` with the larger maximum (NaN counts as largest).
    fn worst(self, other: ErrorStats) -> ErrorStats {
        if other.max.is_nan() || other.max > self.max {
            other
        } else {
            self
        }
    }
}

impl std::fmt::Display for ErrorStats {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "mean {:.4} / max {:.4} ΔE00 over {} samples",
            self.mean, self.max, self.count
        )
    }
}

/// The approximation error of an export against the exact model.
#[derive(Debug, Clone, PartialEq)]
pub struct ErrorReport {
    /// On the training patches (as exposed in the training data).
    pub training: ErrorStats,
    /// On the dense in-gamut set, all exposures together.
    pub dense: ErrorStats,
    /// log2 of the exposures of the dense set (relative to the brightest training patch).
    pub exposures: Vec<f64>,
    /// Dense samples left out because a channel fell outside the LUT's range.
    pub out_of_range: usize,
}

impl ErrorReport {
    /// The larger of the two maxima (NaN when either is: an error not measured).
    pub fn max(&self) -> f64 {
        if self.training.max.is_nan() || self.dense.max.is_nan() {
            return f64::NAN;
        }
        self.training.max.max(self.dense.max)
    }

    /// Per sample set, the worse of two measurements of one export (e.g. a DCP against the
    /// re-balanced model and against the model as applied without a white).
    pub(crate) fn worst(&self, other: &ErrorReport) -> ErrorReport {
        ErrorReport {
            training: self.training.worst(other.training),
            dense: self.dense.worst(other.dense),
            exposures: self.exposures.clone(),
            out_of_range: self.out_of_range.max(other.out_of_range),
        }
    }

    /// Refuses an export whose largest error passes the caller's `limit`, saying where it was.
    /// An error that could not be measured (NaN or infinite anywhere in the statistics: a
    /// sample the export or the model sends to NaN) passes no limit.
    pub(crate) fn check_limit(&self, limit: Option<f64>) -> Result<(), ExportError> {
        let Some(limit) = limit else {
            return Ok(());
        };
        let stats = [&self.training, &self.dense];
        if let Some(bad) = stats
            .iter()
            .position(|s| !(s.mean.is_finite() && s.max.is_finite()))
        {
            return Err(ExportError::TooInaccurate {
                max: f64::NAN,
                limit,
                where_: format!(
                    "not measurable {}: {}",
                    ["on the training patches", "on the dense in-gamut set"][bad],
                    stats[bad]
                ),
            });
        }
        if self.max() > limit {
            return Err(ExportError::TooInaccurate {
                max: self.max(),
                limit,
                where_: if self.training.max >= self.dense.max {
                    "on the training patches"
                } else {
                    "on the dense in-gamut set"
                }
                .into(),
            });
        }
        Ok(())
    }

    /// One line for the CLF `Description`, the .cube header and the terminal.
    pub fn summary(&self) -> String {
        format!(
            "training patches: {}; dense in-gamut set ({} exposures 2^{:.2}..2^{:.2} of the brightest patch): {}",
            self.training,
            self.exposures.len(),
            self.exposures.first().copied().unwrap_or(0.0),
            self.exposures.last().copied().unwrap_or(0.0),
            self.dense
        )
    }
}

/// A model turned into the nodes of a file, with what is needed to describe it.
#[derive(Debug, Clone)]
pub(crate) struct LutExport {
    /// The model with the output space folded in (what `nsrm apply` evaluates).
    pub folded: Model,
    /// The model as fitted (XYZ, white at `Y = white[1]`).
    pub model: Model,
    /// The output space folded in.
    pub space: OutputSpace,
    /// The options it was built with.
    pub options: LutOptions,
    /// The processing chain, in order.
    pub(crate) nodes: Vec<Node>,
    /// Whether the chain is the model itself (LRM) rather than an approximation.
    pub exact: bool,
}

fn check_model(model: &Model) -> Result<(), ExportError> {
    let w = model.white_xyz();
    if !(w.iter().all(|v| v.is_finite() && *v > 0.0)) {
        return Err(ExportError::Model(format!(
            "its reference white {w:?} is not positive"
        )));
    }
    Ok(())
}

/// The least-squares 3×3 `L` with `f(S) ≈ L·S` over the training patches: the CLF chain stores
/// `log(L⁻¹·f(S))` in its LUT, which is nearly linear in the log-encoded input (exactly so for
/// a linear model), and decodes and multiplies by `L` after it.
pub(crate) fn linear_part(folded: &Model, training_rgb: &[[f64; 3]]) -> Result<Mat3, ExportError> {
    if training_rgb.len() < 3 {
        return Err(ExportError::Usage(
            "the LUT export needs the training patches' camera RGB".into(),
        ));
    }
    let mut sst = [[0.0; 3]; 3];
    let mut fst = [[0.0; 3]; 3];
    for &s in training_rgb {
        let f = folded.apply_f64(s);
        for i in 0..3 {
            for j in 0..3 {
                sst[i][j] += s[i] * s[j];
                fst[i][j] += f[i] * s[j];
            }
        }
    }
    let l = spaces::mul(&fst, &spaces::invert(&sst));
    let inv = spaces::invert(&l);
    if !l.iter().chain(inv.iter()).flatten().all(|v| v.is_finite()) {
        return Err(ExportError::Model(
            "its linear part on the training patches is singular".into(),
        ));
    }
    Ok(l)
}

fn fold(model: &Model, space: OutputSpace) -> Result<Model, ExportError> {
    check_model(model)?;
    nsrm::output_model(model, space).map_err(|e| ExportError::Model(e.to_string()))
}

/// Refuses a sampled LUT with an entry that is not a finite 32-bit float: the model's output
/// overflows (or is undefined) somewhere in the exported range, and a file with `inf` or `nan`
/// entries is not one other tools can read.
fn check_finite(lut: &Lut3d, options: LutOptions) -> Result<(), ExportError> {
    let bad = lut
        .values
        .iter()
        .filter(|v| !v.iter().all(|x| x.is_finite()))
        .count();
    if bad == 0 {
        return Ok(());
    }
    let n = lut.size;
    let first = lut
        .values
        .iter()
        .position(|v| !v.iter().all(|x| x.is_finite()))
        .unwrap_or(0);
    Err(ExportError::Model(format!(
        "{bad} of the {} entries of the {n}³ LUT are not finite 32-bit floats (the first at \
         lattice point r {}, g {}, b {}): the model's output overflows over the exposure range \
         {}..{} stops; a file with them would not be a LUT",
        lut.values.len(),
        first / (n * n),
        (first / n) % n,
        first % n,
        options.stops[0],
        options.stops[1],
    )))
}

impl LutExport {
    /// The CLF chain: a Matrix for LRM, else clamp + log shaper + LUT3D (tetrahedral).
    pub(crate) fn clf(
        model: &Model,
        space: OutputSpace,
        options: LutOptions,
        training_rgb: &[[f64; 3]],
    ) -> Result<LutExport, ExportError> {
        options.check()?;
        let folded = fold(model, space)?;
        let (nodes, exact) = if model.kind() == Kind::Lrm {
            let m = folded.matrix();
            (
                vec![Node::Matrix([
                    [m[0], m[1], m[2]],
                    [m[3], m[4], m[5]],
                    [m[6], m[7], m[8]],
                ])],
                true,
            )
        } else {
            let curve = options.curve();
            let hi = options.stops[1].exp2();
            let l = linear_part(&folded, training_rgb)?;
            let l_inv = spaces::invert(&l);
            let lut = Lut3d::sample(options.size, options.interpolation, |y| {
                let out = folded.apply_f64(y.map(|v| curve.inverse(v)));
                spaces::apply(&l_inv, out).map(|v| curve.forward(v))
            });
            check_finite(&lut, options)?;
            (
                vec![
                    Node::Clamp { lo: 0.0, hi },
                    Node::Log {
                        curve,
                        inverse: false,
                    },
                    Node::Lut3d(lut),
                    Node::Log {
                        curve,
                        inverse: true,
                    },
                    Node::Matrix(l),
                ],
                false,
            )
        };
        Ok(LutExport {
            folded,
            model: model.clone(),
            space,
            options,
            nodes,
            exact,
        })
    }

    /// The .cube chain: a 1D shaper over `[0, 2^hi]` and a 3D LUT, for every kind
    /// (the format has no matrix).
    pub(crate) fn cube(
        model: &Model,
        space: OutputSpace,
        options: LutOptions,
    ) -> Result<LutExport, ExportError> {
        options.check()?;
        let folded = fold(model, space)?;
        let curve = options.curve();
        let hi = options.stops[1].exp2();
        let shaper = Lut1d::sample([0.0, hi], options.shaper_size, |x| curve.forward(x));
        let lut = Lut3d::sample(options.size, options.interpolation, |y| {
            folded.apply_f64([
                shaper.inverse(0, y[0]),
                shaper.inverse(1, y[1]),
                shaper.inverse(2, y[2]),
            ])
        });
        check_finite(&lut, options)?;
        Ok(LutExport {
            folded,
            model: model.clone(),
            space,
            options,
            nodes: vec![Node::Lut1d(shaper), Node::Lut3d(lut)],
            exact: false,
        })
    }

    /// Applies the chain to one camera RGB (output space, white `Y = 1`).
    pub(crate) fn eval(&self, rgb: [f64; 3]) -> [f64; 3] {
        eval_chain(&self.nodes, rgb)
    }

    /// The 3D LUT of the chain, if any.
    pub(crate) fn lut3d(&self) -> Option<&Lut3d> {
        self.nodes.iter().find_map(|n| match n {
            Node::Lut3d(l) => Some(l),
            _ => None,
        })
    }

    /// The ΔE00 of the chain against the exact model (see the [module docs](self)), on the
    /// training camera RGBs and the dense set built from them.
    pub(crate) fn measure(&self, training_rgb: &[[f64; 3]]) -> Result<ErrorReport, ExportError> {
        if training_rgb.is_empty() {
            return Err(ExportError::Usage(
                "measuring the export's error needs the training patches' camera RGB".into(),
            ));
        }
        let white = self.model.white_xyz();
        // Output space (white Y = 1) → the model's XYZ (white Y = white[1]).
        let back: Mat3 = spaces::invert(&nsrm::output_matrix(white, self.space));
        let de = |rgb: [f64; 3], k: f64| -> f64 {
            let exact = spaces::apply(&back, self.folded.apply_f64(rgb));
            let approx = spaces::apply(&back, self.eval(rgb));
            nsrm::delta_e00_xyz(exact, approx, white.map(|v| v * k))
        };
        Ok(measure_fn(training_rgb, self.options.stops, true, de))
    }
}

/// The measurement every export reports: `de(rgb, k)` (the ΔE00 of the export against the exact
/// model at camera RGB `rgb`, judged against the training white × `k`) on the training patches
/// (`k = 1`) and on the dense in-gamut set: chromaticities inside the training patches' hull
/// ([`dense_chromaticities`]) at exposures every [`EXPOSURE_STEP`] stops across `stops` (relative
/// to the brightest patch), leaving out samples with a channel outside `2^stops` when
/// `skip_out_of_range`.
pub(crate) fn measure_fn(
    training_rgb: &[[f64; 3]],
    stops: [f64; 2],
    skip_out_of_range: bool,
    de: impl Fn([f64; 3], f64) -> f64,
) -> ErrorReport {
    let training: Vec<f64> = training_rgb.iter().map(|&c| de(c, 1.0)).collect();
    let (lo, hi) = (stops[0].exp2(), stops[1].exp2());
    let s_ref = training_rgb
        .iter()
        .map(|c| c[0] + c[1] + c[2])
        .fold(0.0, f64::max);
    let chroma = dense_chromaticities(training_rgb, DENSE_STEP);
    // Exposures every EXPOSURE_STEP stops across the range, offset from the lattice's powers
    // of two.
    let [slo, shi] = stops;
    let n_exp = ((shi - slo) / EXPOSURE_STEP).floor() as usize;
    let exposures: Vec<f64> = (0..n_exp)
        .map(|i| slo + 0.137 + EXPOSURE_STEP * i as f64)
        .collect();
    let mut dense = Vec::new();
    let mut out_of_range = 0;
    for &e in &exposures {
        let k = e.exp2();
        for &(r, g) in &chroma {
            let s = k * s_ref;
            let rgb = [r * s, g * s, (1.0 - r - g) * s];
            if skip_out_of_range && rgb.iter().any(|&v| v < lo || v > hi) {
                out_of_range += 1;
                continue;
            }
            // The training white scaled to this exposure: the brightest patch stays near L* 100.
            dense.push(de(rgb, k));
        }
    }
    ErrorReport {
        training: ErrorStats::from(&training),
        dense: ErrorStats::from(&dense),
        exposures,
        out_of_range,
    }
}

/// The file an export writes beside `out`: for OCIO the config's CLF, `<stem>.clf`; none for the
/// other formats. A caller declares it as an output of its session with `out`.
pub fn companion_path(
    format: Format,
    out: &std::path::Path,
) -> Result<Option<std::path::PathBuf>, ExportError> {
    match format {
        Format::Ocio => {
            let stem = out
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| "config".into());
            let p = out.with_file_name(format!("{stem}.clf"));
            if p == out {
                return Err(ExportError::Usage(format!(
                    "{}: the OCIO config cannot be named .clf (the CLF is written beside it)",
                    out.display()
                )));
            }
            Ok(Some(p))
        }
        _ => Ok(None),
    }
}

/// An export built and measured in memory ([`render`]): the bytes of each file, nothing
/// written.
#[derive(Debug, Clone)]
pub struct Rendered {
    /// Each file's path (from [`render`]'s `out`) and bytes, in the order written (for
    /// OCIO: the CLF, then the config, which names the CLF by its file name).
    pub files: Vec<(std::path::PathBuf, Vec<u8>)>,
    /// The error of the export against the model.
    pub report: ErrorReport,
    /// Whether the file is the model itself (an LRM as a CLF Matrix) rather than a LUT.
    pub exact: bool,
    /// The 3D LUT size, if there is one.
    pub lut_size: Option<usize>,
}

/// Refuses a ΔE00 limit that is not a finite, non-negative number.
pub(crate) fn check_max_de00(max_de00: Option<f64>) -> Result<(), ExportError> {
    match max_de00 {
        Some(x) if !(x.is_finite() && x >= 0.0) => Err(ExportError::Usage(format!(
            "the ΔE00 limit {x} is not a finite, non-negative number"
        ))),
        _ => Ok(()),
    }
}

/// Builds and measures an export of `model` in `format` and returns its files' bytes, writing
/// nothing: `out` only names them (for OCIO, `out` is the config and the CLF is `<stem>.clf`
/// beside it, named in the config). An embedder (the studio, a renderer) writes the bytes where
/// it likes (the `nsrm` command stages them in its output session and commits them together).
/// The error against the training patches is checked against `max_de00` first.
pub fn render(
    model: &Model,
    format: Format,
    space: OutputSpace,
    options: LutOptions,
    training_rgb: &[[f64; 3]],
    max_de00: Option<f64>,
    out: &std::path::Path,
) -> Result<Rendered, ExportError> {
    check_max_de00(max_de00)?;
    let clf_path = companion_path(format, out)?;
    let e = match format {
        Format::Dcp => {
            return Err(ExportError::Usage(
                "a DCP is written from a model set (one or two illuminants): dcp::render".into(),
            ))
        }
        Format::Icc => {
            return Err(ExportError::Usage(
                "an ICC profile is written by icc::render".into(),
            ))
        }
        Format::Cube => LutExport::cube(model, space, options)?,
        Format::Clf | Format::Ocio => LutExport::clf(model, space, options, training_rgb)?,
    };
    let report = e.measure(training_rgb)?;
    report.check_limit(max_de00)?;
    let files = match (format, clf_path) {
        (Format::Ocio, Some(clf_path)) => {
            let clf_name = clf_path
                .file_name()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default();
            vec![
                (clf_path, clf::write(&e, Some(&report)).into_bytes()),
                (out.to_path_buf(), ocio::write(&e, &clf_name).into_bytes()),
            ]
        }
        (Format::Cube, _) => vec![(
            out.to_path_buf(),
            cube::write(&e, Some(&report))?.into_bytes(),
        )],
        _ => vec![(
            out.to_path_buf(),
            clf::write(&e, Some(&report)).into_bytes(),
        )],
    };
    Ok(Rendered {
        files,
        report,
        exact: e.exact,
        lut_size: e.lut3d().map(|l| l.size),
    })
}

/// A grid of camera chromaticities `(r, g)` (step `step`) inside the convex hull of the training
/// patches' chromaticities.
pub(crate) fn dense_chromaticities(rgb: &[[f64; 3]], step: f64) -> Vec<(f64, f64)> {
    let mut pts: Vec<(f64, f64)> = rgb
        .iter()
        .filter_map(|c| {
            let s = c[0] + c[1] + c[2];
            (s > 0.0 && c.iter().all(|v| *v > 0.0)).then(|| (c[0] / s, c[1] / s))
        })
        .collect();
    let hull = convex_hull(&mut pts);
    if hull.len() < 3 {
        return pts;
    }
    let (mut rmin, mut rmax, mut gmin, mut gmax) = (1.0f64, 0.0f64, 1.0f64, 0.0f64);
    for &(r, g) in &hull {
        rmin = rmin.min(r);
        rmax = rmax.max(r);
        gmin = gmin.min(g);
        gmax = gmax.max(g);
    }
    let mut out = Vec::new();
    let mut r = rmin;
    while r <= rmax {
        let mut g = gmin;
        while g <= gmax {
            if inside(&hull, (r, g)) {
                out.push((r, g));
            }
            g += step;
        }
        r += step;
    }
    out
}

fn cross(o: (f64, f64), a: (f64, f64), b: (f64, f64)) -> f64 {
    (a.0 - o.0) * (b.1 - o.1) - (a.1 - o.1) * (b.0 - o.0)
}

/// Andrew's monotone chain; counter-clockwise, no repeated end point.
fn convex_hull(pts: &mut [(f64, f64)]) -> Vec<(f64, f64)> {
    pts.sort_by(|a, b| a.partial_cmp(b).unwrap_or(std::cmp::Ordering::Equal));
    let mut h: Vec<(f64, f64)> = Vec::new();
    for pass in 0..2 {
        let start = h.len();
        let iter: Box<dyn Iterator<Item = &(f64, f64)>> = if pass == 0 {
            Box::new(pts.iter())
        } else {
            Box::new(pts.iter().rev())
        };
        for &p in iter {
            while h.len() >= start + 2 && cross(h[h.len() - 2], h[h.len() - 1], p) <= 0.0 {
                h.pop();
            }
            h.push(p);
        }
        h.pop();
    }
    h
}

fn inside(hull: &[(f64, f64)], p: (f64, f64)) -> bool {
    (0..hull.len()).all(|i| cross(hull[i], hull[(i + 1) % hull.len()], p) >= 0.0)
}

/// A one-line account of where the model came from, for file headers.
pub fn provenance_line(model: &Model) -> String {
    let p = model.provenance();
    let mut parts = vec![format!(
        "{} order {} ({} terms) fitted on {} patches",
        model.kind(),
        model.order(),
        model.len_terms(),
        model.patches().len()
    )];
    let mut src = vec![if p.source.is_empty() {
        "unknown source".to_string()
    } else {
        p.source.clone()
    }];
    for (name, v) in [
        ("camera", &p.camera),
        ("illuminant", &p.illuminant),
        ("reflectances", &p.reflectances),
        ("grid", &p.grid),
        ("patches", &p.patches),
    ] {
        if let Some(v) = v {
            src.push(format!("{name} {v}"));
        }
    }
    parts.push(format!("training data: {}", src.join(", ")));
    let w = model.white_xyz();
    parts.push(format!(
        "training white XYZ ({:.4}, {:.4}, {:.4})",
        w[0], w[1], w[2]
    ));
    parts.join("; ")
}

/// A name for the camera colour space, from the provenance: `nsrm NSRM3 nikon-d5100 D65`.
pub fn camera_space_name(model: &Model) -> String {
    let p = model.provenance();
    let mut name = format!("nsrm {}{}", model.kind(), model.order());
    for v in [&p.camera, &p.illuminant].into_iter().flatten() {
        name.push(' ');
        name.push_str(&nsrm::display_name(v));
    }
    name.push_str(" camera RGB");
    name.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || " -_.()".contains(c) {
                c
            } else {
                '_'
            }
        })
        .collect()
}

#[cfg(test)]
#[path = "export_tests.rs"]
mod tests;
