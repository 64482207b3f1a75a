//! The paper's Fig. 1: ΔE00 histograms per model, one panel per illuminant, as SVG or PNG.
//!
//! The drawing is described once as a list of primitives ([`Shape`]) and rendered by two small
//! back ends: SVG text, and a PNG rasteriser (text drawn with the embedded DejaVu Sans font).

use super::EvalResult;
use std::path::Path;

/// Errors from drawing a plot.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    #[error("{0}: the plot file must end in .png or .svg")]
    Format(String),
    #[error("nothing to plot")]
    Empty,
    #[error(transparent)]
    Write(#[from] crate::atomic::WriteError),
    #[error("encoding the PNG: {0}")]
    Png(String),
}

/// The file formats a plot can be written in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    Svg,
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

type Rgb = [u8; 3];

/// A drawing primitive in pixel coordinates (y down).
#[derive(Debug, Clone, PartialEq)]
pub enum Shape {
    Rect {
        x: f64,
        y: f64,
        w: f64,
        h: f64,
        fill: Rgb,
    },
    /// An axis-aligned line.
    Line {
        x1: f64,
        y1: f64,
        x2: f64,
        y2: f64,
        color: Rgb,
    },
    /// Text; `anchor` is 0 (start), 1 (middle) or 2 (end).
    Text {
        x: f64,
        y: f64,
        size: f64,
        anchor: u8,
        text: String,
    },
}

const PALETTE: [Rgb; 8] = [
    [31, 119, 180],
    [255, 127, 14],
    [44, 160, 44],
    [214, 39, 40],
    [148, 103, 189],
    [140, 86, 75],
    [227, 119, 194],
    [127, 127, 127],
];

const PANEL_W: f64 = 420.0;
const PANEL_H: f64 = 300.0;
const MARGIN_L: f64 = 50.0;
const MARGIN_T: f64 = 40.0;
const MARGIN_B: f64 = 70.0;

fn model_label(r: &EvalResult) -> String {
    if r.model == "lrm" {
        "LRM".into()
    } else {
        format!("{}{}", r.model.to_uppercase(), r.order)
    }
}

/// The figure as primitives, and its size.
pub fn layout(results: &[EvalResult]) -> Result<(Vec<Shape>, f64, f64), PlotError> {
    if results.is_empty() {
        return Err(PlotError::Empty);
    }
    let mut ills: Vec<&str> = Vec::new();
    let mut models: Vec<String> = Vec::new();
    for r in results {
        if !ills.contains(&r.illuminant.as_str()) {
            ills.push(&r.illuminant);
        }
        let m = model_label(r);
        if !models.contains(&m) {
            models.push(m);
        }
    }
    let max_de = results
        .iter()
        .flat_map(|r| r.per_patch.iter().map(|p| p.de00))
        .filter(|v| v.is_finite())
        .fold(0.0f64, f64::max);
    let bin = if max_de > 8.0 { 1.0 } else { 0.5 };
    let nbins = ((max_de / bin).floor() as usize + 1).max(1);
    // Histogram counts, and the tallest bar, for a shared y axis.
    let counts = |r: &EvalResult| {
        let mut c = vec![0usize; nbins];
        for p in &r.per_patch {
            if p.de00.is_finite() {
                c[((p.de00 / bin) as usize).min(nbins - 1)] += 1;
            }
        }
        c
    };
    let ymax = results.iter().flat_map(counts).max().unwrap_or(1).max(1) as f64;
    let ystep = nice_step(ymax);
    let ytop = (ymax / ystep).ceil() * ystep;

    let width = MARGIN_L + ills.len() as f64 * (PANEL_W + MARGIN_L) - 10.0;
    let height = MARGIN_T + PANEL_H + MARGIN_B + 20.0 * models.len().div_ceil(4) as f64;
    let mut s = vec![Shape::Rect {
        x: 0.0,
        y: 0.0,
        w: width,
        h: height,
        fill: [255, 255, 255],
    }];
    let black = [0, 0, 0];
    let grey = [220, 220, 220];
    for (pi, ill) in ills.iter().enumerate() {
        let x0 = MARGIN_L + pi as f64 * (PANEL_W + MARGIN_L);
        let y0 = MARGIN_T;
        s.push(Shape::Text {
            x: x0 + PANEL_W / 2.0,
            y: y0 - 14.0,
            size: 15.0,
            anchor: 1,
            text: ill.to_string(),
        });
        // Grid lines and y ticks.
        let mut t = 0.0;
        while t <= ytop + 1e-9 {
            let y = y0 + PANEL_H - t / ytop * PANEL_H;
            s.push(Shape::Line {
                x1: x0,
                y1: y,
                x2: x0 + PANEL_W,
                y2: y,
                color: grey,
            });
            s.push(Shape::Text {
                x: x0 - 6.0,
                y: y + 4.0,
                size: 11.0,
                anchor: 2,
                text: format!("{t}"),
            });
            t += ystep;
        }
        let bw = PANEL_W / nbins as f64;
        let of_ill: Vec<&EvalResult> = results.iter().filter(|r| r.illuminant == *ill).collect();
        let nb = of_ill.len().max(1) as f64;
        for r in &of_ill {
            let mi = models.iter().position(|m| *m == model_label(r)).unwrap();
            let k = of_ill
                .iter()
                .position(|o| std::ptr::eq(*o, *r))
                .unwrap_or(0) as f64;
            for (b, &c) in counts(r).iter().enumerate() {
                if c == 0 {
                    continue;
                }
                let h = c as f64 / ytop * PANEL_H;
                s.push(Shape::Rect {
                    x: x0 + b as f64 * bw + 1.0 + k * (bw - 2.0) / nb,
                    y: y0 + PANEL_H - h,
                    w: (bw - 2.0) / nb,
                    h,
                    fill: PALETTE[mi % PALETTE.len()],
                });
            }
        }
        // Axes and x ticks.
        s.push(Shape::Line {
            x1: x0,
            y1: y0 + PANEL_H,
            x2: x0 + PANEL_W,
            y2: y0 + PANEL_H,
            color: black,
        });
        s.push(Shape::Line {
            x1: x0,
            y1: y0,
            x2: x0,
            y2: y0 + PANEL_H,
            color: black,
        });
        let every = (nbins as f64 / 10.0).ceil().max(1.0) as usize;
        for b in (0..=nbins).step_by(every) {
            let x = x0 + b as f64 * bw;
            s.push(Shape::Line {
                x1: x,
                y1: y0 + PANEL_H,
                x2: x,
                y2: y0 + PANEL_H + 4.0,
                color: black,
            });
            s.push(Shape::Text {
                x,
                y: y0 + PANEL_H + 17.0,
                size: 11.0,
                anchor: 1,
                text: format!("{}", b as f64 * bin),
            });
        }
        s.push(Shape::Text {
            x: x0 + PANEL_W / 2.0,
            y: y0 + PANEL_H + 35.0,
            size: 12.0,
            anchor: 1,
            text: "ΔE00".into(),
        });
    }
    s.push(Shape::Text {
        x: 4.0,
        y: MARGIN_T - 14.0,
        size: 12.0,
        anchor: 0,
        text: "patches".into(),
    });
    // Legend.
    for (i, m) in models.iter().enumerate() {
        let x = MARGIN_L + (i % 4) as f64 * 130.0;
        let y = MARGIN_T + PANEL_H + 50.0 + (i / 4) as f64 * 20.0;
        s.push(Shape::Rect {
            x,
            y,
            w: 14.0,
            h: 12.0,
            fill: PALETTE[i % PALETTE.len()],
        });
        s.push(Shape::Text {
            x: x + 20.0,
            y: y + 11.0,
            size: 12.0,
            anchor: 0,
            text: m.clone(),
        });
    }
    Ok((s, width, height))
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

fn escape(t: &str) -> String {
    t.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// Renders primitives as an SVG document.
pub fn to_svg(shapes: &[Shape], width: f64, height: f64) -> String {
    let hex = |c: &Rgb| format!("#{:02x}{:02x}{:02x}", c[0], c[1], c[2]);
    let mut out = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{width}\" height=\"{height}\" viewBox=\"0 0 {width} {height}\" font-family=\"DejaVu Sans, sans-serif\">\n"
    );
    for sh in shapes {
        match sh {
            Shape::Rect { x, y, w, h, fill } => out.push_str(&format!(
                "<rect x=\"{x:.1}\" y=\"{y:.1}\" width=\"{w:.1}\" height=\"{h:.1}\" fill=\"{}\"/>\n",
                hex(fill)
            )),
            Shape::Line {
                x1,
                y1,
                x2,
                y2,
                color,
            } => out.push_str(&format!(
                "<line x1=\"{x1:.1}\" y1=\"{y1:.1}\" x2=\"{x2:.1}\" y2=\"{y2:.1}\" stroke=\"{}\" stroke-width=\"1\"/>\n",
                hex(color)
            )),
            Shape::Text {
                x,
                y,
                size,
                anchor,
                text,
            } => {
                let a = ["start", "middle", "end"][*anchor as usize];
                out.push_str(&format!(
                    "<text x=\"{x:.1}\" y=\"{y:.1}\" font-size=\"{size}\" text-anchor=\"{a}\">{}</text>\n",
                    escape(text)
                ));
            }
        }
    }
    out.push_str("</svg>\n");
    out
}

const FONT: &[u8] = include_bytes!("../../assets/DejaVuSans.ttf");

/// Rasterises primitives into an RGB image.
pub fn to_image(shapes: &[Shape], width: f64, height: f64) -> image::RgbImage {
    use ab_glyph::{Font, FontRef, PxScale, ScaleFont};
    let (w, h) = (width.ceil() as u32, height.ceil() as u32);
    let mut img = image::RgbImage::from_pixel(w, h, image::Rgb([255, 255, 255]));
    let font = FontRef::try_from_slice(FONT).expect("the embedded font parses (tested)");
    let clampx = |v: f64| v.round().clamp(0.0, w as f64) as u32;
    let clampy = |v: f64| v.round().clamp(0.0, h as f64) as u32;
    for sh in shapes {
        match sh {
            Shape::Rect {
                x,
                y,
                w: rw,
                h: rh,
                fill,
            } => {
                for py in clampy(*y)..clampy(y + rh) {
                    for px in clampx(*x)..clampx(x + rw) {
                        img.put_pixel(px, py, image::Rgb(*fill));
                    }
                }
            }
            Shape::Line {
                x1,
                y1,
                x2,
                y2,
                color,
            } => {
                let (xa, xb) = (clampx(x1.min(*x2)), clampx(x1.max(*x2)));
                let (ya, yb) = (clampy(y1.min(*y2)), clampy(y1.max(*y2)));
                for py in ya..=yb.min(h - 1) {
                    for px in xa..=xb.min(w - 1) {
                        img.put_pixel(px, py, image::Rgb(*color));
                    }
                }
            }
            Shape::Text {
                x,
                y,
                size,
                anchor,
                text,
            } => {
                let sf = font.as_scaled(PxScale::from(*size as f32 * 1.25));
                let glyphs: Vec<_> = text.chars().map(|c| sf.scaled_glyph(c)).collect();
                let advance: f32 = glyphs.iter().map(|g| sf.h_advance(g.id)).sum();
                let mut pen = *x as f32 - advance * (*anchor as f32) / 2.0;
                for mut g in glyphs {
                    let adv = sf.h_advance(g.id);
                    g.position = ab_glyph::point(pen, *y as f32);
                    if let Some(outline) = sf.outline_glyph(g) {
                        let bb = outline.px_bounds();
                        outline.draw(|gx, gy, cov| {
                            let px = bb.min.x as i64 + gx as i64;
                            let py = bb.min.y as i64 + gy as i64;
                            if px >= 0 && py >= 0 && (px as u32) < w && (py as u32) < h {
                                let p = img.get_pixel_mut(px as u32, py as u32);
                                for c in p.0.iter_mut() {
                                    *c = (*c as f32 * (1.0 - cov)).round() as u8;
                                }
                            }
                        });
                    }
                    pen += adv;
                }
            }
        }
    }
    img
}

/// Draws the histograms of `results` into `path` (.svg or .png, written atomically).
pub fn histograms(results: &[EvalResult], path: &Path, overwrite: bool) -> Result<(), PlotError> {
    let format = Format::from_path(path)?;
    let (shapes, w, h) = layout(results)?;
    let bytes = match format {
        Format::Svg => to_svg(&shapes, w, h).into_bytes(),
        Format::Png => {
            let img = to_image(&shapes, w, h);
            let mut buf = std::io::Cursor::new(Vec::new());
            img.write_to(&mut buf, image::ImageFormat::Png)
                .map_err(|e| PlotError::Png(e.to_string()))?;
            buf.into_inner()
        }
    };
    crate::atomic::write_atomic(path, &bytes, overwrite)?;
    Ok(())
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
        }
    }

    #[test]
    fn svg_and_png_have_a_panel_per_illuminant_and_bars() {
        let rs = vec![
            result("D65", "nsrm", &[0.2, 0.7, 0.8, 2.1]),
            result("D65", "lrm", &[1.2, 1.7, 3.8, 0.1]),
            result("TL865", "nsrm", &[0.3, 0.4]),
        ];
        let (shapes, w, h) = layout(&rs).unwrap();
        let svg = to_svg(&shapes, w, h);
        assert!(svg.contains(">D65<") && svg.contains(">TL865<") && svg.contains(">NSRM3<"));
        // One bar per non-empty bin: D65 NSRM has 3 bins (0-0.5, 0.5-1, 2-2.5), LRM 4, TL865 1.
        let bars = shapes
            .iter()
            .filter(|s| matches!(s, Shape::Rect { h, .. } if *h > 0.0 && *h < 300.5))
            .count();
        assert_eq!(bars, 3 + 4 + 1 + 2, "bars plus two legend swatches");
        let img = to_image(&shapes, w, h);
        assert_eq!(img.width(), w.ceil() as u32);
        // The first NSRM bar's colour appears in the raster, and so does black text/axes.
        assert!(img.pixels().any(|p| p.0 == PALETTE[0]));
        assert!(img.pixels().any(|p| p.0 == [0, 0, 0]));
        assert!(layout(&[]).is_err());
        assert!(Format::from_path(Path::new("a.jpg")).is_err());
    }
}
