//! Calibration from a photographed chart: the chart geometries ([`ChartKind`]), their reference
//! values ([`Reference`]), and the whole reading in one call ([`read`]: a decoded frame
//! ([`CaptureFrame`]) → its [`Capture`]: the chart placed at given corners or found
//! automatically, its patches read, uneven light compensated ([`FlatField`]), the result checked
//! against the reference, then [`Capture::training_set`] for [`fit`](nsrm::fit)). Beside it,
//! synthetic chart frames ([`render_chart`]) and rendered photographs
//! ([`render_scene`]) for tests and users. Detection, patch extraction, the flat-field estimate
//! and the overlay picture are the crate's own steps behind [`read`].
//!
//! ## Geometry assumed
//!
//! Chart coordinates `(u, v)` are in units of the patch pitch (centre-to-centre distance), `u` to
//! the right and `v` down with the chart upright; cell `(c, r)` spans `[c, c+1] × [r, r+1]` and its
//! patch is the centred square of side `ChartKind::patch_fraction` (the rest of the cell is the
//! black gap between patches). The chart body extends `ChartKind::margin` beyond the cells.
//!
//! * **CC24** (ColorChecker Classic): 6 columns × 4 rows, patch side 0.84 of the pitch (≈ 40 mm
//!   patches on a ≈ 47.6 mm pitch), body margin 0.4 pitch. Labels in reading order: row 1 `01 dark
//!   skin` … `06 bluish green`, row 4 `19 white 9.5` … `24 black 2`.
//! * **SG** (Digital ColorChecker SG): 14 columns × 10 rows, patch side 0.80 of the pitch, body
//!   margin 0.6 pitch. Labels `A1` … `N10`: column letter A..N, row number 1..10, `A1` at the top
//!   left when the chart is upright.
//!
//! `--corners` are the four outer corners of the patch grid: the outer corner of the first patch
//! (`01 dark skin` / `A1`) first, then clockwise as seen upright — in chart coordinates
//! `(g, g)`, `(C−g, g)`, `(C−g, R−g)`, `(g, R−g)` with `g = (1 − patch_fraction) / 2`.
#![forbid(unsafe_code)]
#![deny(unreachable_pub)]
#![warn(missing_docs)]
// `!(x > 0.0)` is meant: it is true for NaN too.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

/// The unit tests' kit, shared with the integration tests (the corrector's public API only).
#[cfg(test)]
#[path = "../../../tests/all/common/kit.rs"]
#[allow(unreachable_pub, dead_code)]
mod kit;

pub mod capture;
pub mod detect;
pub mod diagnose;
pub mod extract;
pub mod flat;
pub mod overlay;
mod raster;
pub mod reference;
pub mod scene;
pub mod synthetic;

pub use self::{
    capture::{read, Capture, CaptureError, CaptureFrame, FlatField, ReadingOptions},
    detect::Candidate,
    reference::Reference,
    scene::{
        render as render_scene, CameraLook, ChartColours, SceneOptions, SceneTruth, TruePatch,
    },
    synthetic::{render as render_chart, ChartLayout, ChartOptions, PatchRect},
};

#[cfg(test)]
mod chart_tests;

use nsrm::Param;
use serde::{Deserialize, Serialize};

/// Errors of chart reading.
#[derive(Debug, thiserror::Error)]
pub enum ChartError {
    /// A chart name that is none of `cc24`, `sg` and `spyder24`.
    #[error("unknown chart `{0}` (known: cc24, sg, spyder24)")]
    UnknownChart(String),
    /// A reference file or table that cannot be used (its header, labels or values).
    #[error("{0}")]
    Reference(String),
    /// A reference CSV that cannot be read (a ragged row, a cell that is not a number).
    #[error(transparent)]
    Csv(#[from] nsrm::csv_table::CsvError),
    /// Corners or a homography that do not describe a chart in the frame.
    #[error("{0}")]
    Geometry(String),
    /// No chart was found in the frame.
    #[error("no chart found: {0}")]
    NotFound(String),
    /// A reading that cannot be right (too few usable patches, a flat field that varies
    /// too much, patches that do not match the reference).
    #[error("{0}")]
    Implausible(String),
    /// A value or frame the reader cannot work with.
    #[error("{0}")]
    Invalid(String),
    /// Options out of range (named in words in the message): a usage error.
    #[error("{0}")]
    Options(String),
    /// About one parameter of the request (`concern` says which and how).
    #[error("{why}")]
    Param {
        /// The parameter.
        concern: nsrm::Concern,
        /// What is wrong with its value.
        why: String,
    },
    /// A frame or file could not be read or written.
    #[error(transparent)]
    Io(#[from] nsrm_io::IoError),
}

impl ChartError {
    /// True for an unknown chart name, scene options out of range, and a parameter value that is
    /// malformed or does not fit the frame (corners, white level, flat frame).
    pub fn is_usage(&self) -> bool {
        use ChartError;
        matches!(
            self,
            ChartError::UnknownChart(_)
                | ChartError::Options(_)
                | ChartError::Param {
                    concern: nsrm::Concern::Value(_),
                    ..
                }
        )
    }

    /// The parameter this error is about; a chart that was not found can always be read from
    /// its corners ([`nsrm::Param::Corners`]).
    pub fn concern(&self) -> Option<nsrm::Concern> {
        use ChartError;
        match self {
            ChartError::Param { concern, .. } => Some(*concern),
            ChartError::NotFound(_) => Some(nsrm::Concern::Remedy(nsrm::Param::Corners)),
            ChartError::Io(e) => e.concern(),
            _ => None,
        }
    }
}

impl ChartError {
    /// A usage error about the value given for `p`.
    pub(crate) fn value(p: nsrm::Param, why: impl Into<String>) -> ChartError {
        ChartError::Param {
            concern: nsrm::Concern::Value(p),
            why: why.into(),
        }
    }
}

/// The kind of chart.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum ChartKind {
    /// The ColorChecker Classic (24 patches, 6 × 4).
    #[cfg_attr(feature = "clap", value(name = "cc24"))]
    Cc24,
    /// The Digital ColorChecker SG (140 patches, 14 × 10).
    #[cfg_attr(feature = "clap", value(name = "sg"))]
    Sg,
    /// The Datacolor SpyderCHECKR 24 (24 patches, 6 × 4: the classic's colours in another
    /// order, the grey ramp at the bottom).
    #[cfg_attr(feature = "clap", value(name = "spyder24"))]
    Spyder24,
}

/// SpyderCHECKR 24 patch names in reading order (top row first, the grey ramp at the bottom),
/// with the rows lettered D … A from the top and the columns numbered from the left, as in
/// darktable's table of the chart.
const SPYDER24_NAMES: [&str; 24] = [
    "bluish green",
    "blue flower",
    "foliage",
    "blue sky",
    "light skin",
    "dark skin",
    "orange",
    "purplish blue",
    "moderate red",
    "purple",
    "yellow green",
    "orange yellow",
    "cyan",
    "magenta",
    "yellow",
    "red",
    "green",
    "blue",
    "white",
    "grey 80",
    "grey 65",
    "grey 50",
    "grey 35",
    "black",
];

/// CC24 patch names in reading order.
const CC24_NAMES: [&str; 24] = [
    "dark skin",
    "light skin",
    "blue sky",
    "foliage",
    "blue flower",
    "bluish green",
    "orange",
    "purplish blue",
    "moderate red",
    "purple",
    "yellow green",
    "orange yellow",
    "blue",
    "green",
    "red",
    "yellow",
    "magenta",
    "cyan",
    "white 9.5",
    "neutral 8",
    "neutral 6.5",
    "neutral 5",
    "neutral 3.5",
    "black 2",
];

impl ChartKind {
    /// Every chart nsrm knows, in the order `--chart auto` tries them.
    pub const ALL: [ChartKind; 3] = [ChartKind::Cc24, ChartKind::Sg, ChartKind::Spyder24];

    /// `cc24`, `sg` or `spyder24` (case-insensitive).
    pub fn parse(s: &str) -> Result<ChartKind, ChartError> {
        match s.trim().to_ascii_lowercase().as_str() {
            "cc24" => Ok(ChartKind::Cc24),
            "sg" => Ok(ChartKind::Sg),
            "spyder24" => Ok(ChartKind::Spyder24),
            _ => Err(ChartError::UnknownChart(s.to_string())),
        }
    }

    /// The name `--chart` takes: `cc24`, `sg` or `spyder24`.
    pub fn name(self) -> &'static str {
        match self {
            ChartKind::Cc24 => "cc24",
            ChartKind::Sg => "sg",
            ChartKind::Spyder24 => "spyder24",
        }
    }

    /// The chart's name as its maker calls it.
    pub fn title(self) -> &'static str {
        match self {
            ChartKind::Cc24 => "ColorChecker Classic",
            ChartKind::Sg => "Digital ColorChecker SG",
            ChartKind::Spyder24 => "Datacolor SpyderCHECKR 24",
        }
    }

    /// Columns of the patch grid (chart upright).
    pub fn columns(self) -> usize {
        match self {
            ChartKind::Cc24 | ChartKind::Spyder24 => 6,
            ChartKind::Sg => 14,
        }
    }

    /// Rows of the patch grid.
    pub fn rows(self) -> usize {
        match self {
            ChartKind::Cc24 | ChartKind::Spyder24 => 4,
            ChartKind::Sg => 10,
        }
    }

    pub(crate) fn cells(self) -> usize {
        self.columns() * self.rows()
    }

    /// Side of a patch as a fraction of the pitch.
    pub(crate) fn patch_fraction(self) -> f64 {
        match self {
            ChartKind::Cc24 => 0.84,
            ChartKind::Sg => 0.80,
            // 26 mm patches at a 31 mm pitch.
            ChartKind::Spyder24 => 0.84,
        }
    }

    /// Chart body beyond the outer cells, in pitches.
    pub(crate) fn margin(self) -> f64 {
        match self {
            ChartKind::Cc24 => 0.4,
            ChartKind::Sg => 0.6,
            // 8 mm of card beyond the outer patches' edges (to the guide dots), 31 mm pitch.
            ChartKind::Spyder24 => 0.35,
        }
    }

    /// The built-in reference used when `--reference` is not given.
    pub fn default_reference(self) -> &'static str {
        match self {
            ChartKind::Cc24 => "cc24-after2014",
            ChartKind::Sg => "sg-after2014",
            ChartKind::Spyder24 => "spyder24-after2018",
        }
    }

    /// The label of cell `(c, r)`.
    pub(crate) fn label(self, c: usize, r: usize) -> String {
        match self {
            ChartKind::Cc24 => {
                let i = r * 6 + c;
                format!("{:02} {}", i + 1, CC24_NAMES[i])
            }
            ChartKind::Sg => format!("{}{}", (b'A' + c as u8) as char, r + 1),
            ChartKind::Spyder24 => {
                let i = r * 6 + c;
                format!(
                    "{}{} {}",
                    (b'D' - r as u8) as char,
                    c + 1,
                    SPYDER24_NAMES[i]
                )
            }
        }
    }

    /// All labels, cell index `r * columns + c`.
    pub(crate) fn labels(self) -> Vec<String> {
        (0..self.cells())
            .map(|i| self.label(i % self.columns(), i / self.columns()))
            .collect()
    }

    /// The cell `(c, r)` of index `i`.
    pub(crate) fn cell(self, i: usize) -> (usize, usize) {
        (i % self.columns(), i / self.columns())
    }

    /// Centre of cell `i` in chart coordinates.
    pub(crate) fn cell_centre(self, i: usize) -> [f64; 2] {
        let (c, r) = self.cell(i);
        [c as f64 + 0.5, r as f64 + 0.5]
    }

    /// The patch-grid corners (what `--corners` names) in chart coordinates.
    pub(crate) fn grid_corners(self) -> [[f64; 2]; 4] {
        let g = (1.0 - self.patch_fraction()) / 2.0;
        let (c, r) = (self.columns() as f64, self.rows() as f64);
        [[g, g], [c - g, g], [c - g, r - g], [g, r - g]]
    }

    /// The chart body corners in chart coordinates (clockwise from top left).
    pub(crate) fn body_corners(self) -> [[f64; 2]; 4] {
        let m = self.margin();
        let (c, r) = (self.columns() as f64, self.rows() as f64);
        [[-m, -m], [c + m, -m], [c + m, r + m], [-m, r + m]]
    }

    /// The index of the patch a label names, accepting the full label (`01 dark skin`, `A1`,
    /// `A1 white`), for CC24 also its number (`1`, `01`) or its name (`dark skin`), for the
    /// SpyderCHECKR its cell (`A1`) or its name (`white`); case and spaces around are ignored, as
    /// is a parenthesised suffix (`white 9.5 (.05 D)`).
    pub(crate) fn index_of(self, label: &str) -> Option<usize> {
        let l = label.trim().trim_matches('"').trim().to_ascii_lowercase();
        let l = match l.find('(') {
            Some(p) => l[..p].trim().to_string(),
            None => l,
        };
        match self {
            ChartKind::Cc24 => {
                if let Ok(n) = l.parse::<usize>() {
                    return (1..=24).contains(&n).then(|| n - 1);
                }
                (0..24).find(|&i| {
                    l == self.label(i % 6, i / 6).to_ascii_lowercase() || l == CC24_NAMES[i]
                })
            }
            ChartKind::Sg => {
                let mut ch = l.chars();
                let col = ch.next()?;
                if !col.is_ascii_lowercase() {
                    return None;
                }
                let c = (col as u8 - b'a') as usize;
                let r: usize = ch.as_str().trim().parse().ok()?;
                (c < 14 && (1..=10).contains(&r)).then(|| (r - 1) * 14 + c)
            }
            ChartKind::Spyder24 => (0..24).find(|&i| {
                let full = self.label(i % 6, i / 6).to_ascii_lowercase();
                l == full || l == SPYDER24_NAMES[i] || full.split(' ').next() == Some(l.as_str())
            }),
        }
    }
}

/// A plane projective transform (3×3, row-major, `h[8]` normalised to 1 where possible).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Homography(pub(crate) [f64; 9]);

impl Homography {
    /// The transform taking each `src[i]` to `dst[i]` (least squares for more than four
    /// points; direct linear transform with Hartley normalisation, solved by SVD).
    pub(crate) fn from_points(
        src: &[[f64; 2]],
        dst: &[[f64; 2]],
    ) -> Result<Homography, ChartError> {
        use nalgebra::{DMatrix, Matrix3};
        if src.len() != dst.len() || src.len() < 4 {
            return Err(ChartError::Geometry(
                "a homography needs at least four point pairs".into(),
            ));
        }
        let norm = |p: &[[f64; 2]]| -> Matrix3<f64> {
            let n = p.len() as f64;
            let cx = p.iter().map(|q| q[0]).sum::<f64>() / n;
            let cy = p.iter().map(|q| q[1]).sum::<f64>() / n;
            let d = p.iter().map(|q| (q[0] - cx).hypot(q[1] - cy)).sum::<f64>() / n;
            let s = if d > 0.0 {
                std::f64::consts::SQRT_2 / d
            } else {
                1.0
            };
            Matrix3::new(s, 0.0, -s * cx, 0.0, s, -s * cy, 0.0, 0.0, 1.0)
        };
        let (ts, td) = (norm(src), norm(dst));
        let tp = |t: &Matrix3<f64>, p: [f64; 2]| {
            let v = t * nalgebra::Vector3::new(p[0], p[1], 1.0);
            [v[0] / v[2], v[1] / v[2]]
        };
        let mut a = DMatrix::<f64>::zeros(2 * src.len().max(5), 9);
        for (i, (s, d)) in src.iter().zip(dst).enumerate() {
            if !(s.iter().chain(d).all(|v| v.is_finite())) {
                return Err(ChartError::Geometry(
                    "a corner is not a finite number".into(),
                ));
            }
            let [x, y] = tp(&ts, *s);
            let [u, v] = tp(&td, *d);
            let r = 2 * i;
            a.row_mut(r)
                .copy_from_slice(&[-x, -y, -1.0, 0.0, 0.0, 0.0, u * x, u * y, u]);
            a.row_mut(r + 1)
                .copy_from_slice(&[0.0, 0.0, 0.0, -x, -y, -1.0, v * x, v * y, v]);
        }
        let svd = a.svd(false, true);
        let vt = svd
            .v_t
            .ok_or_else(|| ChartError::Geometry("homography: SVD failed".into()))?;
        // The right singular vector of the smallest singular value.
        let (k, _) = svd
            .singular_values
            .iter()
            .enumerate()
            .min_by(|a, b| a.1.total_cmp(b.1))
            .expect("nine singular values");
        let sv = &svd.singular_values;
        let mut sorted: Vec<f64> = sv.iter().copied().collect();
        sorted.sort_by(f64::total_cmp);
        if !(sorted[1] > 1e-9 * sorted[8]) {
            return Err(ChartError::Geometry(
                "the points are degenerate (collinear or repeated)".into(),
            ));
        }
        let h = vt.row(k);
        let hn = Matrix3::new(h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7], h[8]);
        let td_inv = td
            .try_inverse()
            .ok_or_else(|| ChartError::Geometry("homography: singular normalisation".into()))?;
        let m = td_inv * hn * ts;
        let s = if m[(2, 2)].abs() > 1e-300 {
            m[(2, 2)]
        } else {
            1.0
        };
        let out = Homography([
            m[(0, 0)] / s,
            m[(0, 1)] / s,
            m[(0, 2)] / s,
            m[(1, 0)] / s,
            m[(1, 1)] / s,
            m[(1, 2)] / s,
            m[(2, 0)] / s,
            m[(2, 1)] / s,
            m[(2, 2)] / s,
        ]);
        if out.0.iter().all(|v| v.is_finite()) {
            Ok(out)
        } else {
            Err(ChartError::Geometry("homography is not finite".into()))
        }
    }

    /// Maps a point.
    pub fn apply(&self, p: [f64; 2]) -> [f64; 2] {
        let h = &self.0;
        let w = h[6] * p[0] + h[7] * p[1] + h[8];
        [
            (h[0] * p[0] + h[1] * p[1] + h[2]) / w,
            (h[3] * p[0] + h[4] * p[1] + h[5]) / w,
        ]
    }

    /// The denominator of [`apply`](Self::apply): positive where the plane is in front.
    pub(crate) fn w(&self, p: [f64; 2]) -> f64 {
        self.0[6] * p[0] + self.0[7] * p[1] + self.0[8]
    }

    /// The inverse transform.
    pub(crate) fn inverse(&self) -> Option<Homography> {
        let m = nalgebra::Matrix3::from_row_slice(&self.0).try_inverse()?;
        let s = if m[(2, 2)].abs() > 1e-300 {
            m[(2, 2)]
        } else {
            1.0
        };
        let v: Vec<f64> = m.transpose().iter().map(|x| x / s).collect();
        Some(Homography(v.try_into().ok()?))
    }

    /// `self ∘ other` (apply `other` first).
    pub(crate) fn then_after(&self, other: &Homography) -> Homography {
        let a = nalgebra::Matrix3::from_row_slice(&self.0);
        let b = nalgebra::Matrix3::from_row_slice(&other.0);
        let m = a * b;
        let s = if m[(2, 2)].abs() > 1e-300 {
            m[(2, 2)]
        } else {
            1.0
        };
        let v: Vec<f64> = m.transpose().iter().map(|x| x / s).collect();
        Homography(v.try_into().expect("nine entries"))
    }

    /// Scales image coordinates by `k` (a transform into a `k`-times larger image).
    pub(crate) fn scaled(&self, k: f64) -> Homography {
        let h = &self.0;
        Homography([
            h[0] * k,
            h[1] * k,
            h[2] * k,
            h[3] * k,
            h[4] * k,
            h[5] * k,
            h[6],
            h[7],
            h[8],
        ])
    }
}

/// Parses a chart's corners: four `X,Y` pairs separated by spaces (or `;`).
pub fn parse_corners(spec: &str) -> Result<[[f64; 2]; 4], ChartError> {
    let bad = |why: &str| ChartError::value(Param::Corners, format!("corners `{spec}`: {why}"));
    let parts: Vec<&str> = spec
        .split(|c: char| c.is_whitespace() || c == ';')
        .filter(|s| !s.is_empty())
        .collect();
    if parts.len() != 4 {
        return Err(bad(
            "expected four X,Y pairs (first patch's corner first, then clockwise)",
        ));
    }
    let mut out = [[0.0; 2]; 4];
    for (k, p) in parts.iter().enumerate() {
        let (x, y) = p.split_once(',').ok_or_else(|| bad("each corner is X,Y"))?;
        let parse = |s: &str| {
            s.trim()
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| bad(&format!("`{s}` is not a finite number")))
        };
        out[k] = [parse(x)?, parse(y)?];
    }
    Ok(out)
}

/// The chart → image transform from the chart's four corners in the frame (pixel coordinates: pixel `(x, y)` covers
/// `[x, x+1) × [y, y+1)`, so its centre is `(x + 0.5, y + 0.5)`).
pub(crate) fn homography_from_corners(
    kind: ChartKind,
    corners: &[[f64; 2]; 4],
    width: usize,
    height: usize,
) -> Result<Homography, ChartError> {
    for (k, c) in corners.iter().enumerate() {
        if !(c[0] >= 0.0 && c[1] >= 0.0 && c[0] <= width as f64 && c[1] <= height as f64) {
            return Err(ChartError::value(
                Param::Corners,
                format!(
                    "corner {} ({}, {}) is outside the {width}×{height} frame",
                    k + 1,
                    c[0],
                    c[1]
                ),
            ));
        }
    }
    // The quadrilateral must be convex and not degenerate.
    let mut sign = 0.0;
    for k in 0..4 {
        let (a, b, c) = (corners[k], corners[(k + 1) % 4], corners[(k + 2) % 4]);
        let cross = (b[0] - a[0]) * (c[1] - b[1]) - (b[1] - a[1]) * (c[0] - b[0]);
        if cross.abs() < 1e-6 || (sign != 0.0 && cross.signum() != sign) {
            return Err(ChartError::value(
                Param::Corners,
                "the corners do not form a convex quadrilateral",
            ));
        }
        sign = cross.signum();
    }
    Homography::from_points(&kind.grid_corners(), corners)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn labels_and_lookup() {
        let k = ChartKind::Cc24;
        assert_eq!(k.label(0, 0), "01 dark skin");
        assert_eq!(k.label(5, 0), "06 bluish green");
        assert_eq!(k.label(0, 3), "19 white 9.5");
        assert_eq!(k.label(5, 3), "24 black 2");
        assert_eq!(k.index_of("24"), Some(23));
        assert_eq!(k.index_of("Dark Skin"), Some(0));
        assert_eq!(k.index_of("white 9.5 (.05 D)"), Some(18));
        assert_eq!(k.index_of("25"), None);
        let s = ChartKind::Sg;
        assert_eq!(s.label(0, 0), "A1");
        assert_eq!(s.label(13, 9), "N10");
        assert_eq!(s.index_of("n10"), Some(139));
        assert_eq!(s.index_of("B1"), Some(1));
        assert_eq!(s.index_of("O1"), None);
        for k in [ChartKind::Cc24, ChartKind::Sg] {
            for (i, l) in k.labels().iter().enumerate() {
                assert_eq!(k.index_of(l), Some(i));
            }
        }
    }

    #[test]
    fn homography_round_trip() {
        let src = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.5, 0.3]];
        let h0 = Homography([2.0, 0.3, 10.0, -0.2, 1.5, 20.0, 0.001, 0.002, 1.0]);
        let dst: Vec<[f64; 2]> = src.iter().map(|p| h0.apply(*p)).collect();
        let h = Homography::from_points(&src, &dst).unwrap();
        for k in 0..9 {
            assert!((h.0[k] - h0.0[k]).abs() < 1e-9, "{h:?}");
        }
        let inv = h.inverse().unwrap();
        let p = inv.apply(h.apply([0.7, 0.2]));
        assert!((p[0] - 0.7).abs() < 1e-12 && (p[1] - 0.2).abs() < 1e-12);
        let both = h.then_after(&inv);
        let q = both.apply([3.0, 4.0]);
        assert!((q[0] - 3.0).abs() < 1e-9 && (q[1] - 4.0).abs() < 1e-9);
        assert!(Homography::from_points(&[[0.0, 0.0]; 4], &[[1.0, 1.0]; 4]).is_err());
    }

    #[test]
    fn corners_are_checked() {
        assert!(parse_corners("1,2 3,4 5,6").is_err());
        assert!(parse_corners("1,2 3,4 5,6 x,8").is_err());
        let c = parse_corners("10,10 110,10 110,80 10,80").unwrap();
        assert!(homography_from_corners(ChartKind::Cc24, &c, 200, 100).is_ok());
        let e = homography_from_corners(ChartKind::Cc24, &c, 100, 100).unwrap_err();
        assert!(e.to_string().contains("outside"), "{e}");
        let twisted = parse_corners("10,10 110,80 110,10 10,80").unwrap();
        assert!(homography_from_corners(ChartKind::Cc24, &twisted, 200, 100).is_err());
    }
}
