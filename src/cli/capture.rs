//! Reading a photographed chart (shared by `chart extract`, `fit --capture`, `eval --capture`):
//! the frame, its chart (by `--corners` or detection), the patch readings, flat-field
//! compensation and the check against the reference.

use super::common::UsageError;
use super::values;
use anyhow::{anyhow, Context, Result};
use nsrm::chart::detect::{detect, Candidate, DetectOptions, Detection};
use nsrm::chart::extract::{extract, verify, ExtractOptions, Extraction, Quantisation};
use nsrm::chart::flat::{self, Flat};
use nsrm::chart::reference::Reference;
use nsrm::chart::{homography_from_corners, overlay, parse_corners, ChartKind};
use nsrm::io::display::{read_chart_frame, Encoding, Transfer};
use nsrm::output::{Session, Unit};
use nsrm::training::{CaptureProvenance, TrainingSet};
use nsrm::Frame;
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};

/// How the chart in a frame is read.
#[derive(Debug, Clone, clap::Args)]
pub struct CaptureOptions {
    /// The chart photographed: cc24 (ColorChecker Classic) or sg (Digital ColorChecker SG).
    #[arg(long, value_enum, ignore_case = true)]
    pub chart: Option<values::Chart>,
    /// Reference values: cc24-after2014 (default for cc24), cc24-before2014, sg-after2014
    /// (default for sg), sg-before2014, or a file: CSV `label` + `X,Y,Z` or `L,a,b`, or CGATS
    /// (.cie/.txt: SAMPLE_ID + XYZ_X/Y/Z or LAB_L/A/B).
    #[arg(long, value_name = "NAME|FILE")]
    pub reference: Option<String>,
    /// White of a reference file's values, in the forms `--white` takes: `X,Y,Z`, `x,y`, D50 or
    /// an illuminant name (needed for a Lab file; XYZ files default to D50, as chart makers'
    /// tables are). Not `--white`: that names the white of a `--training` file, and a Lab
    /// reference's white is given here even when both are used. Built-in references ignore it.
    #[arg(long, value_name = "X,Y,Z|x,y|D50|ILLUMINANT")]
    pub reference_white: Option<String>,
    /// The four outer corners of the patch grid in pixels, first patch's corner first, then
    /// clockwise: "X,Y X,Y X,Y X,Y". Without it the chart is found automatically.
    #[arg(long, value_name = "\"X,Y X,Y X,Y X,Y\"", allow_hyphen_values = true)]
    pub corners: Option<String>,
    /// EXR layer holding the camera RGB (as in `apply`).
    #[arg(long, value_name = "NAME")]
    pub layer: Option<String>,
    /// Sensor clipping level (default: inferred from the frame).
    #[arg(long, value_name = "V")]
    pub white_level: Option<f64>,
    /// Uneven-light compensation: a flat frame (grey card under the same light), or `neutrals`
    /// (a smooth surface fitted to the chart's neutral patches).
    #[arg(long, value_name = "FRAME|neutrals")]
    pub flat: Option<String>,
    /// How the frame's values are encoded: auto (sRGB for JPEG, PNG and 8-bit TIFF; linear for
    /// EXR, 16-bit and float TIFF, raw), linear, or srgb (decoded with the sRGB transfer
    /// function). Display-referred frames still carry the camera's tone curve: a model fitted
    /// from one is marked so and warned about.
    #[arg(long, value_enum, ignore_case = true, default_value = "auto")]
    pub encoding: EncodingArg,
    /// Most pixels the frame (and the flat frame) may have, as in `apply`.
    #[arg(long, value_name = "N", default_value_t = nsrm::io::DEFAULT_MAX_PIXELS,
          value_parser = clap::value_parser!(u64).range(1..))]
    pub max_pixels: u64,
    /// How a camera raw frame (and flat frame) is demosaiced: half (one pixel per 2×2 CFA block,
    /// no interpolation: the chart reading of profiling tools), bilinear (LibRaw's), or mhc
    /// (Malvar-He-Cutler).
    #[arg(long, value_enum, ignore_case = true, default_value_t = values::Demosaic::Half)]
    pub demosaic: values::Demosaic,
}

/// `--encoding`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum EncodingArg {
    Auto,
    Linear,
    Srgb,
}

impl From<EncodingArg> for Encoding {
    fn from(e: EncodingArg) -> Encoding {
        match e {
            EncodingArg::Auto => Encoding::Auto,
            EncodingArg::Linear => Encoding::Linear,
            EncodingArg::Srgb => Encoding::Srgb,
        }
    }
}

/// A read chart.
pub struct Capture {
    pub frame: Frame,
    /// How the frame's values were decoded.
    pub transfer: Transfer,
    /// `make model` of a camera raw frame.
    pub camera: Option<String>,
    pub frame_path: PathBuf,
    pub sha256: String,
    pub reference: Reference,
    pub extraction: Extraction,
    pub detection: Option<Detection>,
    pub flat: Option<Flat>,
    pub score: f64,
}

impl CaptureOptions {
    /// The chart kind (usage error when missing or unknown).
    pub fn kind(&self) -> Result<ChartKind> {
        let c = self
            .chart
            .ok_or_else(|| UsageError("--chart cc24|sg is required".into()))?;
        Ok(ChartKind::from(c))
    }

    /// True when any capture option is given.
    pub fn any(&self) -> bool {
        self.chart.is_some()
            || self.reference.is_some()
            || self.reference_white.is_some()
            || self.corners.is_some()
            || self.layer.is_some()
            || self.white_level.is_some()
            || self.flat.is_some()
    }

    /// Loads the reference (cheap; done before reading frames).
    pub fn reference(&self) -> Result<Reference> {
        let kind = self.kind()?;
        let white = self
            .reference_white
            .as_deref()
            .map(nsrm::training::parse_white)
            .transpose()
            .context("--reference-white")?;
        let spec = self
            .reference
            .clone()
            .unwrap_or_else(|| kind.default_reference().to_string());
        Reference::load(&spec, kind, white).context("--reference")
    }

    /// The files these options read (a reference file, a flat frame), for the run's session.
    pub fn input_files(&self) -> Vec<&Path> {
        let mut v = Vec::new();
        if let Some(r) = self.reference.as_deref().and_then(super::outputs::file_arg) {
            v.push(r);
        }
        if let Some(f) = self.flat.as_deref() {
            if !f.eq_ignore_ascii_case("neutrals") {
                v.push(Path::new(f));
            }
        }
        v
    }

    /// Reads the chart in `path`. On failure with `failure_overlay`, the frame and the rejected
    /// detection candidates are drawn there (committed on its own in `session`).
    pub fn read(&self, path: &Path, failure_overlay: Option<(&Path, &Session)>) -> Result<Capture> {
        let reference = self.reference()?;
        let kind = reference.chart;
        let corners = self.corners.as_deref().map(parse_corners).transpose()?;
        let mut opts = ExtractOptions {
            white_level: self.white_level,
            ..Default::default()
        };
        opts.validate()?;
        let limits = nsrm::io::Limits {
            max_pixels: self.max_pixels,
        };
        let read = read_chart_frame(
            path,
            &nsrm::io::ReadOptions {
                layer: self.layer.clone(),
                limits,
                demosaic: self.demosaic.into(),
            },
            self.encoding.into(),
        )?;
        let (frame, transfer, camera) = (read.frame, read.transfer, read.camera);
        opts.quantisation = read.max_code.map(|max_code| Quantisation {
            max_code,
            srgb: transfer == Transfer::SrgbDecoded,
        });
        let sha256 = sha256_file(path)?;
        let (h, detection) = match corners {
            Some(c) => (
                homography_from_corners(kind, &c, frame.width, frame.height)?,
                None,
            ),
            None => match detect(&frame, &reference, &DetectOptions::default()) {
                Ok(d) => (d.homography, Some(d)),
                Err(f) => {
                    if let Some((p, session)) = failure_overlay {
                        let mut unit = session.unit();
                        write_overlay(&frame, None, &f.candidates, None, p, &mut unit)?;
                        unit.commit()?;
                        eprintln!(
                            "overlay with the {} rejected candidate regions written to {}",
                            f.candidates.len(),
                            p.display()
                        );
                    }
                    return Err(anyhow!(f.error)).with_context(|| {
                        format!("{}: looking for a {} chart", path.display(), kind.name())
                    });
                }
            },
        };
        let mut ex = extract(&frame, &reference, &h, &opts)
            .with_context(|| format!("{}: reading the patches", path.display()))?;
        let flat = match self.flat.as_deref() {
            None => None,
            Some(s) if s.eq_ignore_ascii_case("neutrals") => {
                Some(flat::from_neutrals(&ex, &reference)?)
            }
            Some(f) => {
                let ff = nsrm::io::read_frame(
                    Path::new(f),
                    &nsrm::io::ReadOptions {
                        limits,
                        demosaic: self.demosaic.into(),
                        ..Default::default()
                    },
                )
                .with_context(|| format!("--flat {f}"))?;
                Some(flat::from_flat_frame(
                    &ff,
                    (frame.width, frame.height),
                    &ex,
                    &opts,
                )?)
            }
        };
        if let Some(f) = &flat {
            flat::apply(&mut ex, f);
        }
        let score = verify(&ex, &reference).with_context(|| format!("{}", path.display()))?;
        let flagged = ex.flagged();
        if !flagged.is_empty() {
            eprintln!(
                "warning: {} patch(es) excluded: {}",
                flagged.len(),
                flagged.join("; ")
            );
        }
        Ok(Capture {
            camera: camera.map(|c| c.camera()),
            frame,
            transfer,
            frame_path: path.to_path_buf(),
            sha256,
            reference,
            extraction: ex,
            detection,
            flat,
            score,
        })
    }
}

/// SHA-256 of a file's bytes, read in 1 MiB blocks (hex).
fn sha256_file(path: &Path) -> Result<String> {
    use std::io::Read;
    let mut f = std::fs::File::open(path).with_context(|| format!("reading {}", path.display()))?;
    let mut h = Sha256::new();
    let mut buf = vec![0u8; 1 << 20];
    loop {
        let n = f
            .read(&mut buf)
            .with_context(|| format!("reading {}", path.display()))?;
        if n == 0 {
            break;
        }
        h.update(&buf[..n]);
    }
    Ok(h.finalize().iter().map(|x| format!("{x:02x}")).collect())
}

impl Capture {
    /// Camera G of the perfect white implied by the usable neutral patches.
    pub fn white_g(&self) -> f64 {
        let mut r: Vec<f64> = self
            .extraction
            .patches
            .iter()
            .filter(|p| p.usable() && p.xyz[1] > 1.0)
            .filter(|p| {
                let lab = nsrm::colorimetry::xyz_to_lab(p.xyz, self.reference.white);
                lab[1].hypot(lab[2]) < 4.0
            })
            .map(|p| 100.0 * p.rgb[1] / p.xyz[1])
            .collect();
        r.sort_by(f64::total_cmp);
        r.get(r.len() / 2).copied().unwrap_or(f64::NAN)
    }

    pub fn provenance(&self) -> CaptureProvenance {
        CaptureProvenance {
            frame: self
                .frame_path
                .file_name()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default(),
            sha256: self.sha256.clone(),
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
            encoding: self.transfer.describe().into(),
            camera: self.camera.clone(),
        }
    }

    /// The unflagged patches as training data, with the capture's provenance.
    pub fn training_set(&self) -> TrainingSet {
        let mut t = self.extraction.training_set(&self.reference);
        t.provenance.capture = Some(self.provenance());
        t
    }

    /// The line every command that reads a chart prints: where the chart was found, how well it
    /// matches its reference, the white its X,Y,Z are relative to and the light's non-uniformity.
    pub fn summary(&self) -> String {
        let used = self
            .extraction
            .patches
            .iter()
            .filter(|p| p.usable())
            .count();
        format!(
            "{} chart {} in {} ({}; {}); {used} of {} patches usable; reference {} matches (median ΔE00 {:.2}), X,Y,Z relative to its white {}; light non-uniformity {}",
            self.reference.chart.name(),
            match &self.detection {
                Some(d) => format!(
                    "found (lattice of {} patches, score {:.2} vs {:.2} for the next placement)",
                    d.lattice, d.score, d.runner_up
                ),
                None => "read at --corners".into(),
            },
            self.frame_path.display(),
            self.sha256.get(..12).unwrap_or(""),
            self.transfer.describe(),
            self.extraction.patches.len(),
            self.reference.name,
            self.score,
            nsrm::training::fmt_white(self.reference.white.map(|v| (v * 1e4).round() / 1e4)),
            match &self.flat {
                Some(f) => format!("{:.3} (max/min, compensated: {})", f.nonuniformity, f.method),
                None => "not measured (no --flat)".into(),
            }
        )
    }

    /// A warning when the detected lattice holds more patches than the chart asked for: the
    /// frame probably shows the other chart (a CC24 read inside an SG's patches).
    pub fn other_chart_warning(&self) -> Option<String> {
        let d = self.detection.as_ref()?;
        let n = self.reference.chart.columns() * self.reference.chart.rows();
        (d.lattice > n + n / 4).then(|| {
            let other = match self.reference.chart {
                ChartKind::Cc24 => "sg",
                ChartKind::Sg => "cc24",
            };
            format!(
                "warning: the detected patch lattice has {} patches, more than a {}'s {n}: the frame may hold another chart (an SG?); if so, pass --chart {other}",
                d.lattice,
                self.reference.chart.name()
            )
        })
    }

    /// The full report (`--json`).
    pub fn report(&self) -> serde_json::Value {
        serde_json::json!({
            "format": "nsrm-chart-reading",
            "version": 1,
            "frame": self.frame_path.display().to_string(),
            "width": self.frame.width,
            "height": self.frame.height,
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
}

/// Stages an overlay PNG in `unit`.
pub fn write_overlay(
    frame: &Frame,
    reading: Option<&Extraction>,
    candidates: &[Candidate],
    swatches: Option<(&[overlay::Swatch], [f64; 3])>,
    dest: &Path,
    unit: &mut Unit,
) -> Result<()> {
    let img = overlay::render(frame, reading, candidates, swatches);
    let png = overlay::encode(&img)?;
    unit.write_bytes(dest, &png)
        .with_context(|| format!("writing the overlay {}", dest.display()))?;
    Ok(())
}

/// `--capture FRAME` with its chart options, for `fit` and `eval`: the read capture, or `None`
/// without `--capture` (then no chart option may be given).
pub fn for_model(capture: Option<&Path>, o: &CaptureOptions) -> Result<Option<Capture>> {
    match capture {
        None if o.any() => Err(UsageError(
            "--chart, --reference, --corners, --flat, … need --capture FRAME".into(),
        )
        .into()),
        None => Ok(None),
        Some(p) => {
            let cap = o.read(p, None)?;
            eprintln!("{}", cap.summary());
            if cap.transfer.display_referred() {
                eprintln!(
                    "warning: {} is display-referred ({}): its values carry the camera's tone curve and saturation, so a model fitted from them maps display values, not light; use a raw, linear EXR or 16-bit linear TIFF capture for a calibration",
                    p.display(),
                    cap.transfer.describe()
                );
            }
            Ok(Some(cap))
        }
    }
}

/// Swatches (reference vs the model's prediction) of the usable patches of a capture.
pub fn swatches(cap: &Capture, model: &nsrm::Model) -> Vec<overlay::Swatch> {
    cap.extraction
        .patches
        .iter()
        .filter(|p| p.usable())
        .map(|p| {
            let c = model.apply_f64(p.rgb);
            overlay::Swatch {
                label: p.label.clone(),
                reference_xyz: p.xyz,
                corrected_xyz: c,
                delta_e: nsrm::colorimetry::delta_e00_xyz(c, p.xyz, cap.reference.white),
            }
        })
        .collect()
}
