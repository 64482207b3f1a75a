//! Synthetic chart frames: each patch of a [`TrainingSet`] drawn as a square of its simulated
//! linear camera RGB, in a grid on a black background, with an optional exposure multiplier and
//! seeded Gaussian noise. A layout ([`ChartLayout`], written as JSON beside the frame) says
//! where each patch is and what its true RGB and XYZ are, so a corrected chart can be checked.

use nsrm::{Concern, Param};
use nsrm::{Frame, Layout};
use nsrm::{Provenance, TrainingSet};
use nsrm_io::{IoError, WriteSeek};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The `format` field of a chart layout file.
pub(crate) const FORMAT: &str = "nsrm-chart";

/// How a chart is drawn.
#[derive(Debug, Clone, PartialEq)]
pub struct ChartOptions {
    /// Side of a patch in pixels.
    pub patch_size: usize,
    /// Black pixels between patches and around the chart.
    pub gap: usize,
    /// Patches per row; `None`: about 3:2 landscape.
    pub columns: Option<usize>,
    /// Multiplies the camera RGB (and the reference XYZ in the layout).
    pub exposure: f64,
    /// Standard deviation of additive Gaussian noise on every pixel value (camera RGB units,
    /// the perfect white having G = 1); 0 for none.
    pub noise: f64,
    /// Seed of the noise: the same seed gives the same frame, bit for bit.
    pub seed: u64,
}

impl Default for ChartOptions {
    fn default() -> Self {
        ChartOptions {
            patch_size: 32,
            gap: 4,
            columns: None,
            exposure: 1.0,
            noise: 0.0,
            seed: 1,
        }
    }
}

/// One patch of a rendered chart.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PatchRect {
    /// The patch label.
    pub label: String,
    /// Top-left pixel (x to the right, y down, from the frame's top-left).
    pub x: usize,
    /// Top pixel row.
    pub y: usize,
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Noise-free camera RGB of the patch (after exposure).
    pub rgb: [f64; 3],
    /// Reference XYZ (after exposure; the unexposed perfect white has Y = 100).
    pub xyz: [f64; 3],
}

/// Where the patches of a rendered chart are, and how it was rendered.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ChartLayout {
    /// `nsrm-chart`.
    pub format: String,
    /// The file format's version.
    pub version: u32,
    /// Frame width in pixels.
    pub width: usize,
    /// Frame height in pixels.
    pub height: usize,
    /// Patches per row.
    pub columns: usize,
    /// Patch side in pixels.
    pub patch_size: usize,
    /// Gap between patches in pixels.
    pub gap: usize,
    /// As [`ChartOptions::exposure`].
    pub exposure: f64,
    /// As [`ChartOptions::noise`].
    pub noise: f64,
    /// As [`ChartOptions::seed`].
    pub seed: u64,
    /// The reference white of the training data (XYZ, Y = 100).
    pub white_xyz: [f64; 3],
    /// Where the training data came from.
    pub provenance: Provenance,
    /// Every patch, in the training data's order.
    pub patches: Vec<PatchRect>,
}

impl ChartLayout {
    /// Reads a layout file written by [`write()`].
    #[cfg(test)]
    pub(crate) fn read(path: &Path) -> Result<ChartLayout, IoError> {
        let text = nsrm::limits::read_text(path).map_err(|err| IoError::Read {
            path: path.to_path_buf(),
            err,
        })?;
        let l: ChartLayout = serde_json::from_str(&text).map_err(|e| {
            IoError::Invalid(format!("{}: not a chart layout: {e}", path.display()))
        })?;
        if l.format != FORMAT {
            return Err(IoError::Invalid(format!(
                "{}: format `{}`, expected `{FORMAT}`",
                path.display(),
                l.format
            )));
        }
        Ok(l)
    }

    /// The mean of each channel of `frame` over the inner part of patch `i` (a margin of a
    /// quarter of the patch is left out on each side, so blur or misregistration at edges does
    /// not count).
    #[cfg(test)]
    pub(crate) fn patch_mean(&self, frame: &Frame, i: usize) -> [f64; 3] {
        let p = &self.patches[i];
        let (mx, my) = (p.width / 4, p.height / 4);
        let ch = frame.layout.channels();
        let mut sum = [0.0f64; 3];
        let mut n = 0usize;
        for y in p.y + my..p.y + p.height - my {
            for x in p.x + mx..p.x + p.width - mx {
                let px = &frame.data[(y * frame.width + x) * ch..][..3];
                for k in 0..3 {
                    sum[k] += px[k] as f64;
                }
                n += 1;
            }
        }
        sum.map(|s| s / n.max(1) as f64)
    }
}

/// The layout file written beside `chart`: `NAME.patches.json` for `NAME.exr`.
pub fn layout_path(chart: &Path) -> PathBuf {
    chart.with_extension("patches.json")
}

/// The range of [`ChartOptions::exposure`]: a camera RGB of 1 times it stays a normal f32 (≈ 1.2e-38 to
/// 3.4e38) with room for the patch values and the noise.
pub(crate) const EXPOSURE_RANGE: (f64, f64) = (1e-30, 1e30);
/// The largest [`ChartOptions::noise`] (a standard deviation): noise draws up to ~40σ stay finite in f32.
pub(crate) const MAX_NOISE: f64 = 1e30;
/// The largest [`ChartOptions::patch_size`] and [`ChartOptions::gap`] in pixels.
pub(crate) const MAX_PATCH_PIXELS: usize = 1 << 14;

/// Checks an exposure and a noise level against [`EXPOSURE_RANGE`] and [`MAX_NOISE`]; the
/// message names the limit, the error the parameter ([`Param::Exposure`], [`Param::Noise`]).
pub fn check_exposure_noise(exposure: f64, noise: f64) -> Result<(), IoError> {
    let (lo, hi) = EXPOSURE_RANGE;
    if !(exposure.is_finite() && (lo..=hi).contains(&exposure)) {
        return Err(param(
            Param::Exposure,
            format!(
                "exposure {exposure} is out of range: it must be within {lo:e}..{hi:e} (so that \
                 the pixels stay finite, non-zero 32-bit floats)"
            ),
        ));
    }
    if !(noise.is_finite() && (0.0..=MAX_NOISE).contains(&noise)) {
        return Err(param(
            Param::Noise,
            format!(
                "noise {noise} is out of range: it must be within 0..{MAX_NOISE:e} (so that the \
                 pixels stay finite 32-bit floats)"
            ),
        ));
    }
    Ok(())
}

/// A usage error about the value of `p`.
fn param(p: Param, why: String) -> IoError {
    IoError::Param {
        concern: Concern::Value(p),
        why,
    }
}

impl ChartOptions {
    /// Checks each option on its own (whether they fit together depends on the patch count,
    /// which [`render`] checks): a patch size of 1 to [`MAX_PATCH_PIXELS`], a gap up to it, at
    /// least one column, and [`check_exposure_noise`].
    pub fn validate(&self) -> Result<(), IoError> {
        for (p, what, v, least) in [
            (Param::PatchSize, "patch size", self.patch_size, 1),
            (Param::Gap, "gap", self.gap, 0),
        ] {
            if v < least {
                return Err(param(
                    p,
                    format!("the {what} must be at least {least} pixel"),
                ));
            }
            if v > MAX_PATCH_PIXELS {
                return Err(param(
                    p,
                    format!("{what} {v} is too big: the limit is {MAX_PATCH_PIXELS} pixels"),
                ));
            }
        }
        if self.columns == Some(0) {
            return Err(param(
                Param::Columns,
                "the number of columns must be at least 1".into(),
            ));
        }
        check_exposure_noise(self.exposure, self.noise)
    }
}

/// Renders the chart of `data`.
pub fn render(data: &TrainingSet, opts: &ChartOptions) -> Result<(Frame, ChartLayout), IoError> {
    if data.is_empty() {
        return Err(IoError::Invalid("the chart has no patches".into()));
    }
    opts.validate()?;
    let n = data.len();
    let columns = match opts.columns {
        Some(c) => c.min(n),
        None => ((1.5 * n as f64).sqrt().ceil() as usize).clamp(1, n),
    };
    let rows = n.div_ceil(columns);
    // Checked: the patch size and the gap come from the caller.
    let side = |k: usize| {
        opts.patch_size
            .checked_add(opts.gap)
            .and_then(|pitch| pitch.checked_mul(k))
            .and_then(|v| v.checked_add(opts.gap))
    };
    let (Some(width), Some(height)) = (side(columns), side(rows)) else {
        return Err(param(
            Param::PatchSize,
            format!(
                "a chart of {columns}×{rows} patches of {} px with {} px gaps is too big to count",
                opts.patch_size, opts.gap
            ),
        ));
    };
    let pitch = opts.patch_size + opts.gap;
    if width.checked_mul(height).is_none_or(|p| p > 1 << 28) {
        return Err(param(
            Param::PatchSize,
            format!("a {width}×{height} chart is too big (the limit is 2^28 = 268435456 pixels)"),
        ));
    }
    let mut frame = Frame::new(width, height, Layout::Rgb);
    let mut patches = Vec::with_capacity(n);
    for i in 0..n {
        let (x, y) = (
            opts.gap + (i % columns) * pitch,
            opts.gap + (i / columns) * pitch,
        );
        let rgb = data.rgb[i].map(|v| v * opts.exposure);
        let value = rgb.map(|v| v as f32);
        for yy in y..y + opts.patch_size {
            let row = &mut frame.data[(yy * width + x) * 3..(yy * width + x + opts.patch_size) * 3];
            for px in row.chunks_exact_mut(3) {
                px.copy_from_slice(&value);
            }
        }
        patches.push(PatchRect {
            label: data.labels[i].clone(),
            x,
            y,
            width: opts.patch_size,
            height: opts.patch_size,
            rgb,
            xyz: data.xyz[i].map(|v| v * opts.exposure),
        });
    }
    if opts.noise > 0.0 {
        let mut rng = Gaussian::new(opts.seed);
        for v in frame.data.iter_mut() {
            *v = (*v as f64 + opts.noise * rng.next()) as f32;
        }
    }
    Ok((
        frame,
        ChartLayout {
            format: FORMAT.into(),
            version: 1,
            width,
            height,
            columns,
            patch_size: opts.patch_size,
            gap: opts.gap,
            exposure: opts.exposure,
            noise: opts.noise,
            seed: opts.seed,
            white_xyz: data.white_xyz,
            provenance: data.provenance.clone(),
            patches,
        },
    ))
}

/// A rendered chart's layout as the JSON written at [`layout_path`] beside its frame.
pub fn layout_json(layout: &ChartLayout) -> Result<String, IoError> {
    serde_json::to_string_pretty(layout)
        .map_err(|e| IoError::Invalid(format!("serialising the chart layout: {e}")))
}

/// Encodes a rendered chart's frame into `w`: camera RGB (so no `colorInteropID`) as a float
/// EXR whose header names its layout file ([`layout_path`] of `dest`), or a 32-bit float TIFF
/// when `dest` ends in `.tif`/`.tiff`. The layout itself is [`layout_json`]; the caller writes
/// both (the `nsrm` command commits them together).
pub fn write(
    frame: &Frame,
    layout: &ChartLayout,
    dest: &Path,
    w: &mut dyn WriteSeek,
) -> Result<(), IoError> {
    let layout_file = layout_path(dest);
    let describe = format!(
        "nsrm chart: {} patches; camera {}; illuminant {}; reflectances {}; linear camera RGB (perfect white G = {})",
        layout.patches.len(),
        layout.provenance.camera.as_deref().unwrap_or("?"),
        layout.provenance.illuminant.as_deref().unwrap_or("?"),
        layout.provenance.reflectances.as_deref().unwrap_or("?"),
        layout.exposure,
    );
    let layout_name = layout_file
        .file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    nsrm_io::write_camera_float(
        frame,
        dest,
        &[("comments", &describe), ("nsrmChartLayout", &layout_name)],
        w,
    )
}

/// Writes a camera-RGB frame (no colour space attribute) as a float EXR, or a 32-bit float TIFF
/// when `dest` ends in `.tif`/`.tiff`, with `comments` in the EXR header; encoded into `w`.
pub fn write_camera_frame(
    frame: &Frame,
    dest: &Path,
    comments: &str,
    w: &mut dyn WriteSeek,
) -> Result<(), IoError> {
    nsrm_io::write_camera_float(frame, dest, &[("comments", comments)], w)
}

/// Standard normal deviates from SplitMix64 and the Box–Muller transform: small, seeded and the
/// same on every platform.
pub(crate) struct Gaussian {
    state: u64,
    spare: Option<f64>,
}

impl Gaussian {
    pub(crate) fn new(seed: u64) -> Gaussian {
        Gaussian {
            state: seed,
            spare: None,
        }
    }

    fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.state;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in (0, 1].
    pub(crate) fn uniform(&mut self) -> f64 {
        ((self.next_u64() >> 11) + 1) as f64 / (1u64 << 53) as f64
    }

    pub(crate) fn next(&mut self) -> f64 {
        if let Some(s) = self.spare.take() {
            return s;
        }
        let (u1, u2) = (self.uniform(), self.uniform());
        let r = (-2.0 * u1.ln()).sqrt();
        let t = std::f64::consts::TAU * u2;
        self.spare = Some(r * t.sin());
        r * t.cos()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn data() -> TrainingSet {
        TrainingSet {
            labels: (0..5).map(|i| format!("p{i}")).collect(),
            rgb: (0..5).map(|i| [0.1 * i as f64, 0.2, 0.3]).collect(),
            xyz: (0..5).map(|i| [10.0 * i as f64, 20.0, 30.0]).collect(),
            white_xyz: [95.0, 100.0, 108.0],
            white_rgb: None,
            provenance: Provenance::default(),
        }
    }

    #[test]
    fn patches_hold_their_rgb() {
        let opts = ChartOptions {
            patch_size: 6,
            gap: 2,
            columns: Some(2),
            exposure: 2.0,
            ..Default::default()
        };
        let (f, l) = render(&data(), &opts).unwrap();
        assert_eq!((f.width, f.height), (2 * 8 + 2, 3 * 8 + 2));
        assert_eq!(l.patches.len(), 5);
        for (i, p) in l.patches.iter().enumerate() {
            let m = l.patch_mean(&f, i);
            for k in 0..3 {
                assert!((m[k] - p.rgb[k]).abs() < 1e-6);
            }
            assert!((p.rgb[0] - 0.2 * i as f64).abs() < 1e-12);
            assert_eq!(p.xyz[1], 40.0);
        }
        // The gap is black.
        assert_eq!(&f.data[..3], &[0.0, 0.0, 0.0]);
    }

    #[test]
    fn noise_is_seeded_and_about_the_right_size() {
        let opts = ChartOptions {
            patch_size: 40,
            noise: 0.01,
            seed: 7,
            ..Default::default()
        };
        let (a, _) = render(&data(), &opts).unwrap();
        let (b, _) = render(&data(), &opts).unwrap();
        assert_eq!(a, b);
        let (c, _) = render(&data(), &ChartOptions { seed: 8, ..opts }).unwrap();
        assert_ne!(a, c);
        let (clean, _) = render(&data(), &ChartOptions { noise: 0.0, ..opts }).unwrap();
        let d: Vec<f64> = a
            .data
            .iter()
            .zip(&clean.data)
            .map(|(x, y)| (*x - *y) as f64)
            .collect();
        let mean = d.iter().sum::<f64>() / d.len() as f64;
        let sd = (d.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / d.len() as f64).sqrt();
        assert!(mean.abs() < 1e-3, "{mean}");
        assert!((sd - 0.01).abs() < 5e-4, "{sd}");
    }

    // Moved from `tests/all/harden_fuzz.rs` when the check became crate-private.
    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig {
            cases: std::env::var("NSRM_FUZZ_CASES")
                .ok()
                .and_then(|v| v.parse().ok())
                .unwrap_or(2000),
            ..proptest::prelude::ProptestConfig::default()
        })]

        #[test]
        fn exposure_and_noise_limits_keep_pixels_finite(
            e in proptest::prelude::any::<f64>(),
            n in proptest::prelude::any::<f64>(),
        ) {
            if check_exposure_noise(e, n).is_ok() {
                // The brightest patch value (≤ 1) times the exposure plus 40σ of noise stays finite.
                proptest::prop_assert!(((e + 40.0 * n) as f32).is_finite());
                proptest::prop_assert!((e as f32) > 0.0);
            }
        }
    }
}
