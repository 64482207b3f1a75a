//! The paper's Fig. 1: ΔE00 histograms per model, one panel per illuminant, as SVG or PNG.
//!
//! The figure is drawn once with [`plotters`] on either of its back ends: SVG text, or an RGB
//! bitmap encoded as PNG. Text is laid out (and, in the bitmap, rasterised) with the embedded
//! DejaVu Sans font, registered with plotters from its bytes, so no system font is needed.

use super::EvalResult;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::path::Path;

/// Errors from drawing a plot.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// The plot path (held here) has an extension other than `.png` or `.svg`.
    #[error("{0}: the plot file must end in .png or .svg")]
    Format(String),
    /// There was no data to draw.
    #[error("nothing to plot")]
    Empty,
    /// Encoding the PNG failed (the encoder's message).
    #[error("encoding the PNG: {0}")]
    Png(String),
    /// The embedded font did not parse, or plotters failed to draw.
    #[error("drawing the plot: {0}")]
    Draw(String),
}

impl PlotError {
    /// True for a plot file name that is neither `.png` nor `.svg`.
    pub fn is_usage(&self) -> bool {
        matches!(self, PlotError::Format(_))
    }
}

/// The file formats a plot can be written in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// Scalable vector graphics.
    Svg,
    /// A PNG bitmap.
    Png,
}

impl Format {
    /// From the file name's extension.
    pub fn from_path(path: &Path) -> Result<Format, PlotError> {
        match path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase())
            .as_deref()
        {
            Some("svg") => Ok(Format::Svg),
            Some("png") => Ok(Format::Png),
            _ => Err(PlotError::Format(path.display().to_string())),
        }
    }
}

/// One colour per series, all distinct: `--orders 1-4` draws 13 (LRM and three kinds × four
/// orders). Tableau's ten, then six more of tab20's and darker tones, so no two series share one.
const PALETTE: [RGBColor; 16] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
    RGBColor(11, 61, 145),
    RGBColor(174, 199, 232),
    RGBColor(255, 187, 120),
    RGBColor(152, 223, 138),
    RGBColor(255, 152, 150),
    RGBColor(0, 0, 0),
];
const GRID: RGBColor = RGBColor(220, 220, 220);

/// Panel (plotting area plus its labels) and legend sizes, in pixels.
const PANEL_W: u32 = 470;
const PANEL_H: u32 = 410;
const LEGEND_ROW: u32 = 20;
/// Legend entries per row at most, each [`LEGEND_ENTRY`] pixels wide after a [`LEGEND_LEFT`]
/// margin; fewer when the figure is narrower (one panel), so no label is clipped.
const LEGEND_COLS: usize = 4;
const LEGEND_ENTRY: u32 = 110;
const LEGEND_LEFT: u32 = 52;
/// The height of each line of the figure's title, when it has one (lines: `\n` in the title).
const TITLE_LINE_H: u32 = 22;

/// The family the embedded font is registered under. plotters writes it verbatim as the SVG
/// `font-family`, so viewers without DejaVu fall back to their sans-serif face.
const FAMILY: &str = "DejaVu Sans, sans-serif";
const FONT: &[u8] = include_bytes!("../../assets/DejaVuSans.ttf");

/// Registers [`FONT`] with plotters (whose font registry is its own process-wide table; text is
/// looked up there by family name). Done for every figure rather than remembered here: the
/// registration is idempotent (the same bytes under the same name) and parsing the embedded
/// font is cheap next to drawing, so this crate keeps no process-wide state of its own.
fn register_font() -> Result<(), PlotError> {
    plotters::style::register_font(FAMILY, FontStyle::Normal, FONT)
        .map_err(|_| PlotError::Draw("the embedded DejaVu Sans font does not parse".into()))
}

/// Text in the embedded font; `size` in pixels as plotters counts them (the SVG gets
/// `size / 1.24`).
fn font(size: f64) -> TextStyle<'static> {
    (FAMILY, size).into_font().color(&BLACK)
}

fn model_label(r: &EvalResult) -> String {
    if r.model == "lrm" {
        "LRM".into()
    } else {
        format!("{}{}", r.model.to_uppercase(), r.order)
    }
}

/// One panel: the illuminant, and (model index, counts per bin) for each of its results.
type Panel = (String, Vec<(usize, Vec<usize>)>);

/// What is drawn: the histogram counts of every result, grouped by illuminant, on shared axes.
#[derive(Debug, Clone, PartialEq)]
struct Figure {
    panels: Vec<Panel>,
    /// Model labels, in order of first appearance (the legend, and the colour index).
    models: Vec<String>,
    /// Bin width in ΔE00 units.
    bin: f64,
    nbins: usize,
    /// The y axis' top (a multiple of `ystep`).
    ytop: f64,
    ystep: f64,
    /// Above the panels: what was evaluated (data set, camera, protocol).
    title: Option<String>,
}

impl Figure {
    fn new(results: &[EvalResult], title: Option<&str>) -> Result<Figure, PlotError> {
        if results.is_empty() {
            return Err(PlotError::Empty);
        }
        let max_de = results
            .iter()
            .flat_map(|r| r.per_patch.iter().map(|p| p.de00))
            .filter(|v| v.is_finite())
            .fold(0.0f64, f64::max);
        let bin = if max_de > 8.0 { 1.0 } else { 0.5 };
        let nbins = ((max_de / bin).floor() as usize + 1).max(1);
        let counts = |r: &EvalResult| {
            let mut c = vec![0usize; nbins];
            for p in &r.per_patch {
                if p.de00.is_finite() {
                    c[((p.de00 / bin) as usize).min(nbins - 1)] += 1;
                }
            }
            c
        };
        let mut models: Vec<String> = Vec::new();
        let mut panels: Vec<Panel> = Vec::new();
        for r in results {
            let m = model_label(r);
            let mi = match models.iter().position(|x| *x == m) {
                Some(i) => i,
                None => {
                    models.push(m);
                    models.len() - 1
                }
            };
            let pi = match panels.iter().position(|(ill, _)| *ill == r.illuminant) {
                Some(i) => i,
                None => {
                    panels.push((r.illuminant.clone(), Vec::new()));
                    panels.len() - 1
                }
            };
            panels[pi].1.push((mi, counts(r)));
        }
        let ymax = panels
            .iter()
            .flat_map(|(_, bars)| bars.iter().flat_map(|(_, c)| c.iter().copied()))
            .max()
            .unwrap_or(1)
            .max(1) as f64;
        let ystep = nice_step(ymax);
        let ytop = (ymax / ystep).ceil() * ystep;
        Ok(Figure {
            panels,
            models,
            bin,
            nbins,
            ytop,
            ystep,
            title: title.map(|t| t.replace(|c: char| c.is_control() && c != '\n', " ")),
        })
    }

    /// Legend entries per row: as many as fit the figure's width (at least one).
    fn legend_cols(&self) -> usize {
        let w = self.panels.len() as u32 * PANEL_W;
        (((w.saturating_sub(LEGEND_LEFT)) / LEGEND_ENTRY) as usize).clamp(1, LEGEND_COLS)
    }

    fn title_h(&self) -> u32 {
        match &self.title {
            Some(t) => 8 + TITLE_LINE_H * t.lines().count().max(1) as u32,
            None => 0,
        }
    }

    /// The whole figure's size in pixels.
    fn size(&self) -> (u32, u32) {
        let rows = self.models.len().div_ceil(self.legend_cols()) as u32;
        (
            self.panels.len() as u32 * PANEL_W,
            self.title_h() + PANEL_H + 16 + rows * LEGEND_ROW,
        )
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), PlotError> {
        register_font()?;
        root.fill(&WHITE).map_err(draw_err)?;
        let (head, body) = root.split_vertically(self.title_h());
        if let Some(t) = &self.title {
            let (w, _) = head.dim_in_pixel();
            for (i, line) in t.lines().enumerate() {
                // DejaVu Sans averages about 0.56 of its size per character: the line is made
                // small enough to fit the figure's width (a one-panel figure is 470 px wide).
                let chars = line.chars().count().max(1) as f64;
                let size = (w.saturating_sub(16) as f64 / (0.56 * chars)).clamp(9.0, 17.0);
                let style = font(size).pos(Pos::new(HPos::Center, VPos::Center));
                let y = 4 + TITLE_LINE_H as i32 * i as i32 + TITLE_LINE_H as i32 / 2;
                head.draw(&Text::new(line, (w as i32 / 2, y), style))
                    .map_err(draw_err)?;
            }
        }
        let (top, legend) = body.split_vertically(PANEL_H);
        let areas = top.split_evenly((1, self.panels.len()));
        let xmax = self.nbins as f64 * self.bin;
        let every = self.nbins.div_ceil(10).max(1);
        let x_ticks = self.nbins / every + 1;
        let y_ticks = (self.ytop / self.ystep).round() as usize + 1;
        let tick = |v: &f64| format!("{}", (v * 1e6).round() / 1e6);
        for ((ill, bars), area) in self.panels.iter().zip(&areas) {
            let mut chart = ChartBuilder::on(area)
                .caption(ill, font(19.0))
                .margin_top(6)
                .margin_right(12)
                .x_label_area_size(48)
                .y_label_area_size(52)
                .build_cartesian_2d(0.0..xmax, 0.0..self.ytop)
                .map_err(draw_err)?;
            chart
                .configure_mesh()
                .disable_x_mesh()
                .bold_line_style(GRID)
                .max_light_lines(0)
                .x_labels(x_ticks)
                .y_labels(y_ticks)
                .x_label_formatter(&tick)
                .y_label_formatter(&tick)
                .label_style(font(14.0))
                .axis_desc_style(font(15.0))
                .x_desc("ΔE00")
                .y_desc("patches")
                .draw()
                .map_err(draw_err)?;
            // Each bin's bars side by side, one per model, with a small gap between bins.
            let pad = self.bin * 0.03;
            let w = (self.bin - 2.0 * pad) / bars.len().max(1) as f64;
            let rects = bars.iter().enumerate().flat_map(|(k, (mi, counts))| {
                let color = PALETTE[mi % PALETTE.len()];
                counts
                    .iter()
                    .enumerate()
                    .filter(|(_, &c)| c > 0)
                    .map(move |(b, &c)| {
                        let x = b as f64 * self.bin + pad + k as f64 * w;
                        Rectangle::new([(x, 0.0), (x + w, c as f64)], color.filled())
                    })
            });
            chart.draw_series(rects).map_err(draw_err)?;
        }
        let label = font(15.0).pos(Pos::new(HPos::Left, VPos::Center));
        let cols = self.legend_cols();
        for (i, m) in self.models.iter().enumerate() {
            let x = LEGEND_LEFT as i32 + (i % cols) as i32 * LEGEND_ENTRY as i32;
            let y = 10 + (i / cols) as i32 * LEGEND_ROW as i32;
            let color = PALETTE[i % PALETTE.len()];
            legend
                .draw(&Rectangle::new([(x, y), (x + 14, y + 12)], color.filled()))
                .map_err(draw_err)?;
            legend
                .draw(&Text::new(m.as_str(), (x + 20, y + 6), label.clone()))
                .map_err(draw_err)?;
        }
        root.present().map_err(draw_err)?;
        Ok(())
    }
}

fn draw_err<E: std::error::Error + Send + Sync>(e: DrawingAreaErrorKind<E>) -> PlotError {
    PlotError::Draw(e.to_string())
}

fn nice_step(max: f64) -> f64 {
    let raw = max / 5.0;
    let p = 10f64.powf(raw.log10().floor());
    for m in [1.0, 2.0, 5.0, 10.0] {
        if m * p >= raw {
            return (m * p).max(1.0);
        }
    }
    10.0 * p
}

/// The figure of `results` as an SVG document, with `title` above the panels.
pub(crate) fn to_svg(results: &[EvalResult], title: Option<&str>) -> Result<String, PlotError> {
    let fig = Figure::new(results, title)?;
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, fig.size()).into_drawing_area();
        fig.draw(&root)?;
    }
    Ok(out)
}

/// The figure of `results` as an RGB image, with `title` above the panels.
pub(crate) fn to_image(
    results: &[EvalResult],
    title: Option<&str>,
) -> Result<image::RgbImage, PlotError> {
    let fig = Figure::new(results, title)?;
    let (w, h) = fig.size();
    let mut buf = vec![255u8; w as usize * h as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        fig.draw(&root)?;
    }
    image::RgbImage::from_raw(w, h, buf)
        .ok_or_else(|| PlotError::Draw("the bitmap has the wrong size".into()))
}

/// Draws the histograms of `results` as the file `path` names (.svg or .png) and returns its
/// bytes, with `title` (what was evaluated: data set, camera, protocol) above the panels.
pub fn histograms(
    results: &[EvalResult],
    title: Option<&str>,
    path: &Path,
) -> Result<Vec<u8>, PlotError> {
    let format = Format::from_path(path)?;
    let bytes = match format {
        Format::Svg => to_svg(results, title)?.into_bytes(),
        Format::Png => {
            let img = to_image(results, title)?;
            let mut buf = std::io::Cursor::new(Vec::new());
            img.write_to(&mut buf, image::ImageFormat::Png)
                .map_err(|e| PlotError::Png(e.to_string()))?;
            buf.into_inner()
        }
    };
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eval::{PatchError, Stats};

    fn result(ill: &str, model: &str, v: &[f64]) -> EvalResult {
        EvalResult {
            illuminant: ill.into(),
            model: model.into(),
            order: 3,
            terms: 10,
            stats: Stats::of(v),
            per_patch: v
                .iter()
                .enumerate()
                .map(|(i, &d)| PatchError {
                    label: format!("p{i}"),
                    de00: d,
                })
                .collect(),
            f32_guard: false,
            f32_unsafe_fits: 0,
            fits: v.len(),
            f32_error_max: 0.0,
        }
    }

    fn sample() -> Vec<EvalResult> {
        vec![
            result("D65", "nsrm", &[0.2, 0.7, 0.8, 2.1]),
            result("D65", "lrm", &[1.2, 1.7, 3.8, 0.1]),
            result("TL865", "nsrm", &[0.3, 0.4]),
        ]
    }

    #[test]
    fn figure_has_a_panel_per_illuminant_and_shared_bins() {
        let fig = Figure::new(&sample(), None).unwrap();
        assert_eq!(fig.models, ["NSRM3", "LRM"]);
        assert_eq!((fig.bin, fig.nbins), (0.5, 8));
        let ills: Vec<&str> = fig.panels.iter().map(|(i, _)| i.as_str()).collect();
        assert_eq!(ills, ["D65", "TL865"]);
        // Non-empty bins: D65 NSRM 3 (0-0.5, 0.5-1, 2-2.5), LRM 4, TL865 NSRM 1.
        let nonempty: Vec<usize> = fig
            .panels
            .iter()
            .flat_map(|(_, bars)| {
                bars.iter()
                    .map(|(_, c)| c.iter().filter(|&&n| n > 0).count())
            })
            .collect();
        assert_eq!(nonempty, [3, 4, 1]);
        assert_eq!((fig.ystep, fig.ytop), (1.0, 2.0));
        assert_eq!(fig.size(), (2 * PANEL_W, PANEL_H + 16 + LEGEND_ROW));
        assert!(matches!(Figure::new(&[], None), Err(PlotError::Empty)));
        assert!(matches!(to_svg(&[], None), Err(PlotError::Empty)));
        assert!(Format::from_path(Path::new("a.jpg")).is_err());
        assert_eq!(Format::from_path(Path::new("a.SVG")).unwrap(), Format::Svg);
    }

    #[test]
    fn png_decodes_at_the_figure_size_and_is_not_blank() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("fig.png");
        std::fs::write(&p, histograms(&sample(), None, &p).unwrap()).unwrap();
        let img = image::open(&p).unwrap().to_rgb8();
        assert_eq!(img.dimensions(), (2 * PANEL_W, PANEL_H + 16 + LEGEND_ROW));
        // Bars in both models' colours, dark text and axes, and mostly white background.
        for c in [PALETTE[0], PALETTE[1]] {
            assert!(img.pixels().any(|p| p.0 == [c.0, c.1, c.2]), "{c:?}");
        }
        let dark = img.pixels().filter(|p| p.0.iter().all(|&v| v < 80)).count();
        let white = img.pixels().filter(|p| p.0 == [255, 255, 255]).count();
        let n = img.pixels().len();
        assert!(dark > 500, "{dark} dark pixels");
        assert!(white > n / 2 && white < n, "{white} of {n} white");
        // Another figure, other bytes; an SVG by its name.
        let before = std::fs::read(&p).unwrap();
        assert_ne!(histograms(&sample()[..1], None, &p).unwrap(), before);
        let svg = histograms(&sample(), None, Path::new("f.svg")).unwrap();
        assert!(svg.starts_with(b"<svg"));
    }

    /// 13 series (`--orders 1-4`), 13 colours; one panel's legend fits its width.
    #[test]
    fn thirteen_series_get_thirteen_colours_and_a_narrow_legend_fits() {
        let mut rs = vec![result("D65", "lrm", &[0.5, 1.5])];
        for kind in ["prm", "rprm", "nsrm"] {
            for order in 1..=4 {
                let mut r = result("D65", kind, &[0.5, 1.5]);
                r.order = order;
                rs.push(r);
            }
        }
        let fig = Figure::new(&rs, None).unwrap();
        assert_eq!(fig.models.len(), 13);
        let colours: std::collections::HashSet<_> =
            (0..13).map(|i| PALETTE[i % PALETTE.len()]).collect();
        assert_eq!(colours.len(), 13);
        // One panel: every legend entry ends inside the figure (the longest label, NSRM4, is
        // about 60 px at this size).
        let cols = fig.legend_cols();
        assert!(cols >= 1);
        let (w, h) = fig.size();
        assert!(
            LEGEND_LEFT + cols as u32 * LEGEND_ENTRY <= w,
            "{cols} columns in {w} px"
        );
        assert_eq!(h, PANEL_H + 16 + 13u32.div_ceil(cols as u32) * LEGEND_ROW);
        let svg = to_svg(&rs, None).unwrap();
        for label in ["NSRM4", "RPRM1", "PRM2", "LRM"] {
            assert!(
                svg.contains(&format!(">{label}<")) || svg.contains(label),
                "{label}"
            );
        }
    }

    #[test]
    fn svg_names_the_panels_and_models_in_the_embedded_font() {
        let svg = to_svg(&sample(), Some("rawtoaces-190, nikon-d5100, leave-one-out")).unwrap();
        assert!(svg.starts_with("<svg"), "{}", &svg[..svg.len().min(80)]);
        // The text of every `<text>` element.
        let texts: Vec<&str> = svg
            .split("</text>")
            .filter_map(|s| s.rsplit_once('>').map(|(_, t)| t.trim()))
            .collect();
        for t in [
            "D65",
            "TL865",
            "NSRM3",
            "LRM",
            "patches",
            "ΔE00",
            "0.5",
            "2",
            "rawtoaces-190, nikon-d5100, leave-one-out",
        ] {
            assert!(texts.contains(&t), "{t} not in {texts:?}");
        }
        assert!(svg.contains("font-family=\"DejaVu Sans, sans-serif\""));
        assert!(svg.contains("<rect"));
    }
}
