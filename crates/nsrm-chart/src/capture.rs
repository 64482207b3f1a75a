//! The capture workflow: a photographed chart → its reading. A frame is decoded once
//! ([`CaptureFrame::open`]: read as chart reading wants it, and hashed for the provenance);
//! [`read`] then finds the chart (at given corners, or by detection), reads the patches,
//! compensates uneven light and checks the result against the reference. Reading again with
//! other corners, another flat field or another reference reuses the decoded frame: nothing is
//! read from disk twice.
//!
//! What `chart extract`, `fit`/`eval` with a capture and the studio all call, so that they give
//! the same numbers.

// The errors carry a `ChartError` (itself near the lint's size) and the frame's path: larger
// than a pointer or two, on a path taken once per frame and never in a loop.
#![allow(clippy::result_large_err)]

use super::detect::{detect, Candidate, DetectOptions, Detection};
use super::extract::{extract, verify, ExtractOptions, Extraction, Quantisation};
use super::flat::{self, Flat};
use super::reference::Reference;
use super::{homography_from_corners, overlay, ChartError, ChartKind};
use nsrm::Frame;
use nsrm::{CaptureProvenance, TrainingSet};
use nsrm_io::display::{read_chart_frame, ChartFrame, Encoding, Transfer};
use nsrm_io::{IoError, ReadOptions};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Errors of the capture workflow.
#[derive(Debug, thiserror::Error)]
pub enum CaptureError {
    /// The frame could not be read.
    #[error(transparent)]
    Io(#[from] IoError),
    /// The frame's bytes could not be hashed.
    #[error("reading {}: {err}", path.display())]
    Hash {
        /// The frame's file.
        path: PathBuf,
        /// The system's error.
        #[source]
        err: std::io::Error,
    },
    /// No chart was found; `candidates` are the regions detection looked at (for an overlay).
    #[error("{}: looking for a {chart} chart", path.display())]
    NotFound {
        /// The frame's file.
        path: PathBuf,
        /// The chart looked for.
        chart: &'static str,
        /// The cause.
        #[source]
        source: ChartError,
        /// The regions detection looked at.
        candidates: Vec<Candidate>,
    },
    /// The chart was placed but its patches could not be read.
    #[error("{}: reading the patches", path.display())]
    Patches {
        /// The frame's file.
        path: PathBuf,
        /// The cause.
        #[source]
        source: ChartError,
    },
    /// The reading does not match the reference.
    #[error("{}", path.display())]
    Verify {
        /// The frame's file.
        path: PathBuf,
        /// The cause.
        #[source]
        source: ChartError,
    },
    /// Options, corners or the light estimate.
    #[error(transparent)]
    Chart(#[from] ChartError),
}

impl CaptureError {
    /// True for options or corners that are malformed or do not fit the frame.
    pub fn is_usage(&self) -> bool {
        match self {
            CaptureError::Io(e) => e.is_usage(),
            CaptureError::Chart(e) => e.is_usage(),
            _ => false,
        }
    }

    /// The parameter this error is about (see [`ChartError::concern`]).
    pub fn concern(&self) -> Option<nsrm::Concern> {
        match self {
            CaptureError::Io(e) => e.concern(),
            CaptureError::Chart(e) => e.concern(),
            CaptureError::NotFound { source, .. }
            | CaptureError::Patches { source, .. }
            | CaptureError::Verify { source, .. } => source.concern(),
            CaptureError::Hash { .. } => None,
        }
    }
}

/// A decoded frame of a chart and where it came from.
#[derive(Debug, Clone)]
pub struct CaptureFrame {
    /// The pixels and how they were decoded.
    pub(crate) decoded: ChartFrame,
    /// The file read (for messages and the provenance).
    pub path: PathBuf,
    /// SHA-256 of the file's bytes (lowercase hex).
    pub sha256: String,
}

impl CaptureFrame {
    /// Reads `path` for chart reading and hashes its bytes: JPEG, PNG and 8-bit TIFF as display
    /// encodings (decoded per `encoding`), anything else through [`nsrm_io::Decoded::read`].
    ///
    /// For a camera raw file, chart readers want `opts.demosaic` = [`Demosaic::Half`] (one pixel
    /// per CFA block, no interpolation; what `nsrm chart extract` uses); [`ReadOptions`]'s
    /// default is the full-resolution demosaic that correcting frames uses.
    ///
    /// [`Demosaic::Half`]: nsrm_io::Demosaic::Half
    /// [`ReadOptions`]: nsrm_io::ReadOptions
    pub fn open(
        path: &Path,
        opts: &ReadOptions,
        encoding: Encoding,
    ) -> Result<CaptureFrame, CaptureError> {
        let decoded = read_chart_frame(path, opts, encoding)?;
        let sha256 = sha256_file(path)?;
        Ok(CaptureFrame {
            decoded,
            path: path.to_path_buf(),
            sha256,
        })
    }

    /// A frame the caller decoded (linear camera RGB, e.g. an array from Python), read as a
    /// linear file is; `name` stands for the file in messages and in the provenance, and the
    /// hash is that of its f32 pixels (little-endian).
    pub fn from_frame(frame: Frame, name: &str) -> CaptureFrame {
        use sha2::{Digest, Sha256};
        let mut h = Sha256::new();
        for v in &frame.data {
            h.update(v.to_le_bytes());
        }
        let sha256 = h.finalize().iter().map(|x| format!("{x:02x}")).collect();
        CaptureFrame {
            decoded: ChartFrame {
                frame,
                transfer: Transfer::Linear,
                max_code: None,
                camera: None,
            },
            path: PathBuf::from(name),
            sha256,
        }
    }

    /// An already decoded frame (`path` names it in messages and in the provenance).
    #[cfg(test)]
    pub(crate) fn from_decoded(decoded: ChartFrame, path: PathBuf, sha256: String) -> CaptureFrame {
        CaptureFrame {
            decoded,
            path,
            sha256,
        }
    }

    /// The decoded pixels.
    pub fn frame(&self) -> &Frame {
        &self.decoded.frame
    }

    /// Make, model, exposure and clip level of a camera raw frame; `None` for other files.
    pub fn camera(&self) -> Option<&nsrm_io::raw::CameraInfo> {
        self.decoded.camera.as_ref()
    }
}

/// SHA-256 of a file's bytes, read in 1 MiB blocks (lowercase hex).
pub(crate) fn sha256_file(path: &Path) -> Result<String, CaptureError> {
    use sha2::{Digest, Sha256};
    use std::io::Read;
    let err = |err| CaptureError::Hash {
        path: path.to_path_buf(),
        err,
    };
    let mut f = std::fs::File::open(path).map_err(err)?;
    let mut h = Sha256::new();
    let mut buf = vec![0u8; 1 << 20];
    loop {
        let n = f.read(&mut buf).map_err(err)?;
        if n == 0 {
            break;
        }
        h.update(&buf[..n]);
    }
    Ok(h.finalize().iter().map(|x| format!("{x:02x}")).collect())
}

/// How uneven light on the chart is compensated.
#[derive(Debug, Clone, Copy)]
pub enum FlatField<'a> {
    /// A smooth surface fitted to the chart's neutral patches.
    Neutrals,
    /// A flat frame (a grey card under the same light and framing), decoded.
    Frame(&'a Frame),
}

/// How the chart in a frame is read.
#[derive(Debug, Clone, Copy, Default)]
pub struct ReadingOptions<'a> {
    /// The four outer corners of the patch grid in pixels (first patch's corner first, then
    /// clockwise); `None`: the chart is detected.
    pub corners: Option<[[f64; 2]; 4]>,
    /// The sensor's clipping level; `None`: inferred from the frame.
    pub white_level: Option<f64>,
    /// Uneven-light compensation; `None`: none.
    pub flat: Option<FlatField<'a>>,
}

/// A read chart.
#[derive(Debug, Clone)]
pub struct Capture {
    /// The frame it was read from (shared with whoever decoded it).
    pub frame: Arc<CaptureFrame>,
    /// The reference the patches were read against.
    pub reference: Reference,
    /// The patches as read (after flat-field compensation when asked for): in
    /// [`report`](Self::report), the usable ones in [`to_csv`](Self::to_csv).
    pub extraction: Extraction,
    /// How the chart was found; `None` when read at given corners.
    pub detection: Option<Detection>,
    /// The light compensation applied; `None` when none was asked for.
    pub flat: Option<Flat>,
    /// Median ΔE00 of the reading against the reference (after a linear fit).
    pub score: f64,
}

/// Reads the chart of `reference` in `frame`.
pub fn read(
    frame: &Arc<CaptureFrame>,
    reference: &Reference,
    opts: &ReadingOptions,
) -> Result<Capture, CaptureError> {
    let kind = reference.chart;
    let decoded = &frame.decoded;
    let img = &decoded.frame;
    let path = &frame.path;
    let mut ex_opts = ExtractOptions {
        white_level: opts.white_level,
        ..Default::default()
    };
    ex_opts.validate()?;
    ex_opts.quantisation = Quantisation::of(decoded);
    let (h, detection) = match opts.corners {
        Some(c) => (
            homography_from_corners(kind, &c, img.width, img.height)?,
            None,
        ),
        None => match detect(img, reference, &DetectOptions::default()) {
            Ok(d) => (d.homography, Some(d)),
            Err(f) => {
                return Err(CaptureError::NotFound {
                    path: path.clone(),
                    chart: kind.name(),
                    source: f.error,
                    candidates: f.candidates,
                })
            }
        },
    };
    let mut ex = extract(img, reference, &h, &ex_opts).map_err(|source| CaptureError::Patches {
        path: path.clone(),
        source,
    })?;
    let flat = match opts.flat {
        None => None,
        Some(FlatField::Neutrals) => Some(flat::from_neutrals(&ex, reference)?),
        Some(FlatField::Frame(ff)) => Some(flat::from_flat_frame(
            ff,
            (img.width, img.height),
            &ex,
            &ex_opts,
        )?),
    };
    if let Some(f) = &flat {
        flat::apply(&mut ex, f);
    }
    let score = verify(&ex, reference).map_err(|source| CaptureError::Verify {
        path: path.clone(),
        source,
    })?;
    Ok(Capture {
        frame: Arc::clone(frame),
        reference: reference.clone(),
        extraction: ex,
        detection,
        flat,
        score,
    })
}

impl Capture {
    /// How the frame's values were decoded.
    pub fn transfer(&self) -> Transfer {
        self.frame.decoded.transfer
    }

    /// `make model` of a camera raw frame.
    pub fn camera(&self) -> Option<String> {
        self.frame.decoded.camera.as_ref().map(|c| c.camera())
    }

    /// Camera G of the perfect white implied by the usable neutral patches.
    pub fn white_g(&self) -> f64 {
        let mut r: Vec<f64> = self
            .extraction
            .patches
            .iter()
            .filter(|p| p.usable() && p.xyz[1] > 1.0)
            .filter(|p| {
                let lab = nsrm::xyz_to_lab(p.xyz, self.reference.white);
                lab[1].hypot(lab[2]) < 4.0
            })
            .map(|p| 100.0 * p.rgb[1] / p.xyz[1])
            .collect();
        r.sort_by(f64::total_cmp);
        r.get(r.len() / 2).copied().unwrap_or(f64::NAN)
    }

    /// The light the chart was shot under: the chromaticity and CCT of the camera response to
    /// the perfect white on the neutral ramp (glare left out), through the raw file's colour
    /// matrices by the DNG `NeutralToXY` iteration. `None` without matrices (not a raw file)
    /// or without a neutral ramp.
    pub fn light(&self) -> Option<([f64; 2], f64)> {
        let cam = self.frame.decoded.camera.as_ref()?;
        let ramp = super::diagnose::Ramp::of(&self.extraction, self.reference.white)?;
        let w = ramp.white_rgb();
        light_of_neutral(&cam.color_matrices, w.map(|v| v / w[1]))
    }

    /// Subtracts the veiling glare measured on the neutral ramp (a uniform camera-RGB term,
    /// its positive intercepts) from every patch and checks the reading again; returns the
    /// term subtracted, or `None` (nothing changed) without a ramp of 3 neutral patches.
    pub fn compensate_glare(&mut self) -> Option<[f64; 3]> {
        let ramp = super::diagnose::Ramp::of(&self.extraction, self.reference.white)?;
        let g = ramp.glare_rgb();
        super::diagnose::remove_glare(&mut self.extraction, g);
        if let Ok(score) = verify(&self.extraction, &self.reference) {
            self.score = score;
        }
        Some(g)
    }

    /// Where the training data came from, for the model's provenance.
    pub fn provenance(&self) -> CaptureProvenance {
        CaptureProvenance {
            frame: self
                .frame
                .path
                .file_name()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default(),
            sha256: self.frame.sha256.clone(),
            chart: self.reference.chart.name().into(),
            reference: self.reference.name.clone(),
            located: if self.detection.is_some() { "detected" } else { "corners" }.into(),
            excluded: self.extraction.flagged(),
            exposure_normalisation:
                "none: camera RGB as recorded (after flat-field division, factors of mean 1), so the model applies to this frame's raw values"
                    .into(),
            white_g: self.white_g(),
            flat: self
                .flat
                .as_ref()
                .map_or("none".to_string(), |f| f.method.clone()),
            light_nonuniformity: self.flat.as_ref().map_or(1.0, |f| f.nonuniformity),
            reference_match_de00: self.score,
            encoding: self.transfer().describe().into(),
            camera: self.camera(),
            light_xy: self.light().map(|l| l.0.map(|v| (v * 1e6).round() / 1e6)),
            light_cct: self.light().map(|l| l.1.round()),
            training: None,
        }
    }

    /// The unflagged patches as training data, with the capture's provenance (which records
    /// the patches themselves: a model fitted on them carries them).
    pub fn training_set(&self) -> TrainingSet {
        let mut t = self.extraction.training_set(&self.reference);
        t.provenance.capture = Some(self.provenance());
        t.record_patches();
        t
    }

    /// True when the detected lattice holds clearly more patches than the chart has: the frame
    /// probably shows the other chart (a CC24 read inside an SG's patches). The other chart.
    pub fn other_chart(&self) -> Option<ChartKind> {
        let d = self.detection.as_ref()?;
        let n = self.reference.chart.columns() * self.reference.chart.rows();
        (d.lattice > n + n / 4).then_some(match self.reference.chart {
            ChartKind::Cc24 | ChartKind::Spyder24 => ChartKind::Sg,
            ChartKind::Sg => ChartKind::Cc24,
        })
    }

    /// The training CSV of the reading (what `nsrm chart extract -o` writes and `--training`
    /// reads): the unflagged patches' camera RGB and reference XYZ, after two comment lines (what
    /// the file is, and `# white: X,Y,Z`, the reference's white).
    pub fn to_csv(&self) -> String {
        self.extraction.to_csv(&self.reference)
    }

    /// The full report (`nsrm-chart-reading` version 1).
    pub fn report(&self) -> serde_json::Value {
        let img = self.frame.frame();
        serde_json::json!({
            "format": "nsrm-chart-reading",
            "version": 1,
            "frame": self.frame.path.display().to_string(),
            "width": img.width,
            "height": img.height,
            "provenance": self.provenance(),
            "reference_white": self.reference.white,
            "homography": self.extraction.homography,
            "corners": self.reference.chart.grid_corners().map(|c| self.extraction.homography.apply(c)),
            "detection": self.detection.as_ref().map(|d| serde_json::json!({
                "score_de00": d.score,
                "runner_up_de00": d.runner_up,
                "lattice_patches": d.lattice,
                "mirrored": d.mirrored,
                "downsample": d.downsample,
                "candidates": d.candidates.len(),
            })),
            "white_level": self.extraction.white_level,
            "white_level_inferred": self.extraction.white_level_inferred,
            "patches": self.extraction.patches,
        })
    }

    /// Swatches (reference vs the model's prediction) of the usable patches.
    pub fn swatches(&self, model: &nsrm::Model) -> Vec<overlay::Swatch> {
        self.extraction
            .patches
            .iter()
            .filter(|p| p.usable())
            .map(|p| {
                let c = model.apply_f64(p.rgb);
                overlay::Swatch {
                    label: p.label.clone(),
                    reference_xyz: p.xyz,
                    corrected_xyz: c,
                    delta_e: nsrm::delta_e00_xyz(c, p.xyz, self.reference.white),
                }
            })
            .collect()
    }
}

/// The temperatures the DNG SDK gives EXIF light sources (those a colour matrix is given for).
fn light_source_cct(code: u16) -> Option<f64> {
    Some(match code {
        17 => 2856.0,
        24 => 3200.0,
        23 => 5003.0,
        20 => 5503.0,
        21 => 6504.0,
        22 => 7504.0,
        _ => return None,
    })
}

/// The chromaticity and CCT of the light whose camera response is `neutral`, through colour
/// matrices (XYZ → camera, with their EXIF light sources): one matrix inverted, two interpolated
/// in inverse temperature by the DNG iteration. `None` when none is usable.
pub(crate) fn light_of_neutral(
    matrices: &[(u16, [f64; 9])],
    neutral: [f64; 3],
) -> Option<([f64; 2], f64)> {
    use nsrm::{apply_mat3, neutral_to_xy, try_invert_mat3, Mat3};
    let mut known: Vec<(f64, Mat3)> = matrices
        .iter()
        .filter_map(|(c, m)| {
            let t = light_source_cct(*c)?;
            Some((
                t,
                [[m[0], m[1], m[2]], [m[3], m[4], m[5]], [m[6], m[7], m[8]]],
            ))
        })
        .collect();
    known.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (lo, hi) = (*known.first()?, *known.last()?);
    let xy = neutral_to_xy(neutral, [lo.0, hi.0.max(lo.0 + 1.0)], |n, w| {
        let m: Mat3 = std::array::from_fn(|r| {
            std::array::from_fn(|c| w * lo.1[r][c] + (1.0 - w) * hi.1[r][c])
        });
        let inv = try_invert_mat3(&m)?;
        Some(apply_mat3(&inv, n))
    })
    .ok()?;
    let t = nsrm::cct(xy).ok()?;
    t.is_finite().then_some((xy, t))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{render, ChartColours, SceneOptions};

    fn decoded(frame: Frame) -> Arc<CaptureFrame> {
        Arc::new(CaptureFrame::from_decoded(
            ChartFrame {
                frame,
                transfer: Transfer::Linear,
                max_code: None,
                camera: None,
            },
            PathBuf::from("scene.exr"),
            "0".repeat(64),
        ))
    }

    fn scene(gradient: f64) -> (Frame, Frame, [[f64; 2]; 4], Reference) {
        let colours = ChartColours::simulate(ChartKind::Cc24, "nikon-d5100", "D65", None).unwrap();
        let corners = [[100.0, 80.0], [500.0, 90.0], [490.0, 350.0], [110.0, 340.0]];
        let opts = SceneOptions {
            width: 600,
            height: 420,
            corners: Some(corners),
            exposure: 0.8,
            gradient,
            clutter: 4,
            ..Default::default()
        };
        let (frame, flat, _) = render(&colours, &opts).unwrap();
        let reference = Reference::load("cc24-after2014", ChartKind::Cc24, None).unwrap();
        (frame, flat, corners, reference)
    }

    #[test]
    fn reads_at_corners_and_again_from_the_same_frame() {
        let (frame, flat, corners, reference) = scene(0.3);
        let f = decoded(frame);
        let opts = ReadingOptions {
            corners: Some(corners),
            ..Default::default()
        };
        let a = read(&f, &reference, &opts).unwrap();
        assert_eq!(a.extraction.patches.len(), 24);
        assert!(a.detection.is_none());
        assert!(a.score < 3.0, "reference match {}", a.score);
        // The reading shares the decoded frame: nothing was copied.
        assert!(Arc::ptr_eq(&a.frame, &f));
        // Read again (the studio after a drag): the same numbers.
        let b = read(&f, &reference, &opts).unwrap();
        assert_eq!(a.extraction, b.extraction);
        // Moved corners: other readings.
        let mut moved = corners;
        moved[2][0] -= 30.0;
        let c = read(
            &f,
            &reference,
            &ReadingOptions {
                corners: Some(moved),
                ..Default::default()
            },
        )
        .unwrap();
        assert_ne!(a.extraction.patches[0].rgb, c.extraction.patches[0].rgb);
        // The flat frame takes out the gradient the plain reading sees.
        let with_flat = read(
            &f,
            &reference,
            &ReadingOptions {
                corners: Some(corners),
                flat: Some(FlatField::Frame(&flat)),
                ..Default::default()
            },
        )
        .unwrap();
        let fl = with_flat.flat.as_ref().unwrap();
        assert!(fl.nonuniformity > 1.1, "{}", fl.nonuniformity);
        assert!(
            with_flat.score < a.score,
            "{} vs {}",
            with_flat.score,
            a.score
        );
        assert_eq!(with_flat.provenance().flat, "flat frame");
        assert_eq!(a.provenance().located, "corners");
    }

    /// A bright patch with a channel at 0 (a JPEG's cyan with red 0) is flagged as clipped at
    /// black, not as dark (issue 36: `18 cyan (dark)`).
    #[test]
    fn a_bright_patch_with_a_zero_channel_is_clipped_not_dark() {
        let mut colours =
            ChartColours::simulate(ChartKind::Cc24, "nikon-d5100", "D65", None).unwrap();
        colours.rgb[17][0] = 0.0;
        let corners = [[100.0, 80.0], [500.0, 90.0], [490.0, 350.0], [110.0, 340.0]];
        let opts = SceneOptions {
            width: 600,
            height: 420,
            corners: Some(corners),
            exposure: 0.8,
            noise: 0.0,
            clutter: 0,
            ..Default::default()
        };
        let (frame, _, _) = render(&colours, &opts).unwrap();
        let reference = Reference::load("cc24-after2014", ChartKind::Cc24, None).unwrap();
        let cap = read(
            &decoded(frame),
            &reference,
            &ReadingOptions {
                corners: Some(corners),
                ..Default::default()
            },
        )
        .unwrap();
        let cyan = &cap.extraction.patches[17];
        assert_eq!(cyan.label, "18 cyan");
        assert_eq!(cyan.flags, vec![crate::extract::Flag::ClippedBlack]);
        assert!(cap
            .extraction
            .flagged()
            .iter()
            .any(|f| f == "18 cyan (a channel clipped at 0)"));
    }

    #[test]
    fn a_flat_frame_of_another_size_and_a_frame_without_a_chart_are_refused() {
        let (frame, _, corners, reference) = scene(0.0);
        let f = decoded(frame);
        let small = Frame::new(10, 10, nsrm::Layout::Rgb);
        let e = read(
            &f,
            &reference,
            &ReadingOptions {
                corners: Some(corners),
                flat: Some(FlatField::Frame(&small)),
                ..Default::default()
            },
        )
        .unwrap_err();
        assert!(e.to_string().contains("flat frame is 10×10"), "{e}");
        let blank = decoded(Frame::new(300, 200, nsrm::Layout::Rgb));
        match read(&blank, &reference, &ReadingOptions::default()) {
            Err(CaptureError::NotFound { chart, path, .. }) => {
                assert_eq!(chart, "cc24");
                assert_eq!(path, PathBuf::from("scene.exr"));
            }
            other => panic!("{:?}", other.map(|c| c.score)),
        }
    }
}
