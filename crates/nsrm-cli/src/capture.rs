//! Reading a photographed chart (shared by `chart extract`, `fit --capture`, `eval --capture`):
//! the frame, its chart (by `--corners` or detection), the patch readings, flat-field
//! compensation and the check against the reference.

use super::common::UsageError;
use anyhow::{Context, Result};
use nsrm::Frame;
use nsrm_chart::capture::{CaptureError, CaptureFrame, FlatField, ReadingOptions};
use nsrm_chart::detect::Candidate;
use nsrm_chart::extract::{ExtractOptions, Extraction};
use nsrm_chart::reference::Reference;
use nsrm_chart::{overlay, parse_corners, ChartKind};
use nsrm_io::display::Encoding;
use nsrm_output::{Session, Unit};
use std::path::Path;
use std::sync::Arc;

/// How the chart in a frame is read.
#[derive(Debug, Clone, clap::Args)]
pub(crate) struct CaptureOptions {
    /// The chart photographed: cc24 (ColorChecker Classic, Passport), sg (Digital ColorChecker
    /// SG), spyder24 (Datacolor SpyderCHECKR 24), or auto (every one is tried; the one found is
    /// named).
    #[arg(
        help_heading = "Chart in a photograph",
        long,
        value_name = "cc24|sg|spyder24|auto",
        value_parser = parse_chart_pick
    )]
    pub(crate) chart: Option<ChartPick>,
    /// Reference values: cc24-after2014 (default for cc24), cc24-before2014, sg-after2014
    /// (default for sg), sg-before2014, spyder24-after2018 (default for spyder24),
    /// spyder24-before2018, or a file: CSV `label` + `X,Y,Z` or `L,a,b`, or CGATS (.cie/.txt:
    /// SAMPLE_ID + XYZ_X/Y/Z or LAB_L/A/B).
    #[arg(help_heading = "Chart in a photograph", long, value_name = "NAME|FILE")]
    pub(crate) reference: Option<String>,
    /// White of a reference file's values, in the forms `--white` takes: `X,Y,Z`, `x,y`, D50 or
    /// an illuminant name (needed for a Lab file; XYZ files default to D50, as chart makers'
    /// tables are). Not `--white`: that names the white of a `--training` file, and a Lab
    /// reference's white is given here even when both are used. Built-in references ignore it.
    #[arg(help_heading = "Chart in a photograph", long, value_name = "WHITE")]
    pub(crate) reference_white: Option<String>,
    /// The four outer corners of the patch grid in pixels, first patch's corner first, then
    /// clockwise: "X,Y X,Y X,Y X,Y". Without it the chart is found automatically.
    #[arg(
        help_heading = "Chart in a photograph",
        long,
        value_name = "CORNERS",
        allow_hyphen_values = true
    )]
    pub(crate) corners: Option<String>,
    /// EXR layer holding the camera RGB (as in `apply`).
    #[arg(help_heading = "Chart in a photograph", long, value_name = "NAME")]
    pub(crate) layer: Option<String>,
    /// Sensor clipping level (default: inferred from the frame).
    #[arg(help_heading = "Chart in a photograph", long, value_name = "V")]
    pub(crate) white_level: Option<f64>,
    /// Uneven-light compensation: a flat frame (grey card under the same light), or `neutrals`
    /// (a smooth surface fitted to the chart's neutral patches).
    #[arg(
        help_heading = "Chart in a photograph",
        long,
        value_name = "FRAME|neutrals"
    )]
    pub(crate) flat: Option<String>,
    /// How the frame's values are encoded: auto (sRGB for JPEG, PNG and 8-bit TIFF; linear for
    /// EXR, 16-bit and float TIFF, raw), linear, or srgb (decoded with the sRGB transfer
    /// function). Display-referred frames still carry the camera's tone curve: a model fitted
    /// from one is marked so and warned about.
    #[arg(
        help_heading = "Chart in a photograph",
        long,
        value_enum,
        ignore_case = true,
        default_value = "auto"
    )]
    pub(crate) encoding: EncodingArg,
    #[command(flatten)]
    pub(crate) max_pixels: super::values::MaxPixelsArg,
    /// How a camera raw frame (and flat frame) is demosaiced: half (one pixel per 2×2 CFA block,
    /// no interpolation: the chart reading of profiling tools), bilinear (LibRaw's), or mhc
    /// (Malvar-He-Cutler).
    #[arg(help_heading = "Chart in a photograph", long, value_enum, ignore_case = true, default_value_t = nsrm_io::Demosaic::Half)]
    pub(crate) demosaic: nsrm_io::Demosaic,
}

/// `--encoding`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum EncodingArg {
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

/// What `--chart` names: one chart, or `auto` (every chart nsrm knows).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum ChartPick {
    /// Try every chart ([`ChartKind::ALL`]); read the one found.
    Auto,
    /// This chart.
    Kind(ChartKind),
}

impl From<ChartKind> for ChartPick {
    fn from(k: ChartKind) -> ChartPick {
        ChartPick::Kind(k)
    }
}

/// `--chart`'s value: a chart's name or `auto` (case-insensitive).
fn parse_chart_pick(s: &str) -> Result<ChartPick, String> {
    if s.trim().eq_ignore_ascii_case("auto") {
        return Ok(ChartPick::Auto);
    }
    ChartKind::parse(s)
        .map(ChartPick::Kind)
        .map_err(|_| format!("`{s}` is not a chart: {} or auto", chart_names()))
}

/// The charts `--chart` names, for messages: `cc24, sg, spyder24`.
pub(crate) fn chart_names() -> String {
    ChartKind::ALL.map(|k| k.name()).join(", ")
}

/// A read chart (the library's reading, with the frame it was read from).
pub(crate) use nsrm_chart::capture::Capture;

impl CaptureOptions {
    /// The charts to try: the one `--chart` names, or every one for `auto` (usage error when
    /// `--chart` is missing, or when `auto` meets a `--reference` file, which is one chart's).
    pub(crate) fn kinds(&self) -> Result<Vec<ChartKind>> {
        match self.chart {
            None => Err(UsageError("--chart cc24|sg|spyder24|auto is required".into()).into()),
            Some(ChartPick::Kind(k)) => Ok(vec![k]),
            Some(ChartPick::Auto) if self.reference.is_some() => Err(UsageError(
                "--reference holds one chart's values: name that chart with --chart instead of auto"
                    .into(),
            )
            .into()),
            Some(ChartPick::Auto) => Ok(ChartKind::ALL.to_vec()),
        }
    }

    /// True when any capture option is given.
    pub(crate) fn any(&self) -> bool {
        self.chart.is_some()
            || self.reference.is_some()
            || self.reference_white.is_some()
            || self.corners.is_some()
            || self.layer.is_some()
            || self.white_level.is_some()
            || self.flat.is_some()
    }

    /// Loads the reference of the one chart `--chart` names (not `auto`): the studio's reading.
    #[cfg(feature = "studio")]
    pub(crate) fn the_reference(&self) -> Result<Reference> {
        match self.kinds()?.as_slice() {
            [k] => self.reference(*k),
            _ => Err(UsageError(format!("name the chart ({}), not auto", chart_names())).into()),
        }
    }

    /// Loads the reference of chart `kind` (cheap; done before reading frames).
    pub(crate) fn reference(&self, kind: ChartKind) -> Result<Reference> {
        let white = self
            .reference_white
            .as_deref()
            .map(nsrm::parse_white)
            .transpose()
            .context("--reference-white")?;
        let spec = self
            .reference
            .clone()
            .unwrap_or_else(|| kind.default_reference().to_string());
        Reference::load(&spec, kind, white).context("--reference")
    }

    /// The files these options read (a reference file, a flat frame), for the run's session.
    pub(crate) fn input_files(&self) -> Vec<&Path> {
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

    /// Decodes `path` as these options say (the frame and its hash, read once).
    pub(crate) fn open_frame(&self, path: &Path) -> Result<Arc<CaptureFrame>> {
        Ok(Arc::new(CaptureFrame::open(
            path,
            &nsrm_io::ReadOptions {
                layer: self.layer.clone(),
                limits: self.limits(),
                demosaic: self.demosaic,
            },
            self.encoding.into(),
        )?))
    }

    fn limits(&self) -> nsrm_io::Limits {
        nsrm_io::Limits {
            max_pixels: self.max_pixels.max_pixels,
        }
    }

    /// Reads the `--flat` frame, if one is named, decoded as the chart frame is (`--encoding`:
    /// a JPEG/PNG/8-bit grey card is sRGB-decoded to linear under `auto`).
    pub(crate) fn flat_frame(&self) -> Result<Option<Frame>> {
        match self.flat.as_deref() {
            None => Ok(None),
            Some(s) if s.eq_ignore_ascii_case("neutrals") => Ok(None),
            Some(f) => Ok(Some(
                nsrm_io::display::read_chart_frame(
                    Path::new(f),
                    &nsrm_io::ReadOptions {
                        limits: self.limits(),
                        demosaic: self.demosaic,
                        ..Default::default()
                    },
                    self.encoding.into(),
                )
                .with_context(|| format!("--flat {f}"))?
                .frame,
            )),
        }
    }

    /// Reads the chart in `path` (under `--chart auto`, each chart in turn; the one found is
    /// named). On failure with `failure_overlay`, the frame and the rejected detection
    /// candidates are drawn there (committed on its own in `session`).
    pub(crate) fn read(
        &self,
        path: &Path,
        failure_overlay: Option<(&Path, &Session)>,
    ) -> Result<Capture> {
        let kinds = self.kinds()?;
        let references = kinds
            .iter()
            .map(|&k| self.reference(k))
            .collect::<Result<Vec<_>>>()?;
        let corners = self.corners.as_deref().map(parse_corners).transpose()?;
        if let Some(w) = self.white_level {
            ExtractOptions {
                white_level: Some(w),
                ..Default::default()
            }
            .validate()?;
        }
        let frame = self.open_frame(path)?;
        let flat_frame = self.flat_frame()?;
        let flat = match (&self.flat, &flat_frame) {
            (_, Some(f)) => Some(FlatField::Frame(f)),
            (Some(_), None) => Some(FlatField::Neutrals),
            (None, None) => None,
        };
        let opts = ReadingOptions {
            corners,
            white_level: self.white_level,
            flat,
        };
        let cap = if references.len() > 1 {
            pick_chart(&frame, &references, &opts).map_err(|e| *e)
        } else {
            nsrm_chart::capture::read(&frame, &references[0], &opts)
        };
        let cap = cap.map_err(|e| {
            if let (CaptureError::NotFound { candidates, .. }, Some((p, session))) =
                (&e, failure_overlay)
            {
                let mut unit = session.unit();
                let written = write_overlay(frame.frame(), None, candidates, None, p, &mut unit)
                    .and_then(|_| Ok(unit.commit()?));
                match written {
                    Ok(()) => eprintln!(
                        "overlay with the {} rejected candidate regions written to {}",
                        candidates.len(),
                        p.display()
                    ),
                    Err(w) => return w,
                }
            }
            anyhow::Error::from(e)
        })?;
        let flagged = cap.extraction.flagged();
        if !flagged.is_empty() {
            eprintln!(
                "warning: {} patch(es) excluded: {}",
                flagged.len(),
                flagged.join("; ")
            );
        }
        Ok(cap)
    }
}

/// The innermost cause of an error: the reason a chart was not found, without the frame's name
/// and the step that every chart tried shares.
fn innermost(e: &dyn std::error::Error) -> String {
    let mut cur = e;
    while let Some(next) = cur.source() {
        cur = next;
    }
    cur.to_string()
}

/// `--chart auto`: reads `frame` as each chart of `references` and keeps the reading that
/// matches best among those whose lattice is not clearly a larger chart's
/// ([`Capture::other_chart`]); prints which chart it found and why the others were not taken.
/// When none is found, the first chart's error (its rejected candidates), naming every chart
/// tried.
fn pick_chart(
    frame: &Arc<CaptureFrame>,
    references: &[Reference],
    opts: &ReadingOptions<'_>,
) -> Result<Capture, Box<CaptureError>> {
    let mut found = Vec::new();
    let mut first_err = None;
    let mut notes = Vec::new();
    for r in references {
        match nsrm_chart::capture::read(frame, r, opts) {
            Ok(c) => found.push(c),
            Err(e) => {
                notes.push(format!("not a {}: {}", r.chart.name(), innermost(&e)));
                first_err.get_or_insert(e);
            }
        }
    }
    let whole = found.iter().any(|c| c.other_chart().is_none());
    found.retain(|c| !whole || c.other_chart().is_none());
    found.sort_by(|a, b| a.score.total_cmp(&b.score));
    let mut found = found.into_iter();
    let Some(best) = found.next() else {
        let names: Vec<&str> = references.iter().map(|r| r.chart.name()).collect();
        eprintln!("--chart auto: none of {} found", names.join(", "));
        return Err(Box::new(first_err.expect("a reference was tried")));
    };
    for other in found {
        notes.push(format!(
            "also read as a {} (median ΔE00 {:.2}), a worse match",
            other.reference.chart.name(),
            other.score
        ));
    }
    eprintln!(
        "--chart auto: a {} ({}) found, median ΔE00 {:.2}{}",
        best.reference.chart.name(),
        best.reference.chart.title(),
        best.score,
        notes.iter().map(|n| format!("; {n}")).collect::<String>()
    );
    Ok(best)
}

/// The CLI's words about a reading (they name its flags).
pub(crate) trait CaptureText {
    /// The line every command that reads a chart prints: where the chart was found, how well it
    /// matches its reference, the white its X,Y,Z are relative to and the light's non-uniformity.
    fn summary(&self) -> String;
    /// A warning when the detected lattice holds more patches than the chart asked for: the
    /// frame probably shows the other chart (a CC24 read inside an SG's patches).
    fn other_chart_warning(&self) -> Option<String>;
}

impl CaptureText for Capture {
    fn summary(&self) -> String {
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
            self.frame.path.display(),
            self.frame.sha256.get(..12).unwrap_or(""),
            self.transfer().describe(),
            self.extraction.patches.len(),
            self.reference.name,
            self.score,
            nsrm::fmt_white(self.reference.white.map(|v| (v * 1e4).round() / 1e4)),
            match &self.flat {
                Some(f) => format!("{:.3} (max/min, compensated: {})", f.nonuniformity, f.method),
                None => "not measured (no --flat)".into(),
            }
        )
    }

    /// A warning when the detected lattice holds more patches than the chart asked for: the
    /// frame probably shows the other chart (a CC24 read inside an SG's patches).
    fn other_chart_warning(&self) -> Option<String> {
        let other = self.other_chart()?;
        let lattice = self.detection.as_ref().map_or(0, |d| d.lattice);
        let n = self.reference.chart.columns() * self.reference.chart.rows();
        Some(format!(
            "warning: the detected patch lattice has {lattice} patches, more than a {}'s {n}: the frame may hold another chart (an SG?); if so, pass --chart {}",
            self.reference.chart.name(),
            other.name()
        ))
    }
}

/// Stages an overlay PNG in `unit`.
pub(crate) fn write_overlay(
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
/// without `--capture` (then no chart option may be given). The caller prints the reading's
/// [`CaptureText::summary`] (once).
pub(crate) fn for_model(capture: Option<&Path>, o: &CaptureOptions) -> Result<Option<Capture>> {
    match capture {
        None if o.any() => Err(UsageError(
            "--chart, --reference, --corners, --flat, … need --capture FRAME".into(),
        )
        .into()),
        None => Ok(None),
        Some(p) => {
            let cap = o.read(p, None)?;
            if cap.transfer().display_referred() {
                eprintln!(
                    "warning: {} is read as {}: its values carry the camera's tone curve and saturation, so a model fitted from them maps display values, not light; use a raw, linear EXR or 16-bit linear TIFF capture for a calibration",
                    p.display(),
                    cap.transfer().describe()
                );
            }
            Ok(Some(cap))
        }
    }
}

/// Swatches (reference vs the model's prediction) of the usable patches of a capture.
pub(crate) fn swatches(cap: &Capture, model: &nsrm::Model) -> Vec<overlay::Swatch> {
    cap.swatches(model)
}
