//! The calibration report of `nsrm calibrate`: a per-patch table (worst first) with the summary,
//! the model choice and the diagnosis as text, and the same as one self-contained HTML page
//! (no network, no external file: the overlay as an inline PNG, the plots as inline SVG).

use super::calibrate::Candidate;
use nsrm::{apply_mat3 as apply, OutputSpace};
use nsrm::{delta_e00_xyz, xyz_to_lab};
use nsrm::{output_matrix, srgb8};
use nsrm::{EvalResult, Stats};
use nsrm_chart::capture::Capture;
use nsrm_chart::diagnose::{Finding, Ramp, Severity};
use std::fmt::Write as _;
use std::path::Path;

/// What the report says besides the patches.
pub(crate) struct Context<'a> {
    /// The chart shot.
    pub(crate) shot: &'a Path,
    /// The diagnosis (measured before any glare compensation).
    pub(crate) findings: Vec<Finding>,
    /// The neutral ramp as read (before any glare compensation).
    pub(crate) ramp: Option<Ramp>,
    /// The glare term subtracted, with `--glare-compensation`.
    pub(crate) glare: Option<[f64; 3]>,
    /// The candidates' leave-one-out results (empty when `--kind` named the model).
    pub(crate) tried: Vec<Candidate>,
    /// Whether the model was chosen by leave-one-out.
    pub(crate) chosen_by_loo: bool,
    /// Whether the shot is display-referred (a JPEG, PNG, 8-bit TIFF).
    pub(crate) display_referred: bool,
}

/// One patch of the report.
pub(crate) struct Row {
    pub(crate) label: String,
    pub(crate) reference: [f64; 3],
    pub(crate) fitted: [f64; 3],
    /// In-sample ΔE00.
    pub(crate) de: f64,
    /// Leave-one-out ΔE00 (usable patches).
    pub(crate) loo: Option<f64>,
    pub(crate) flags: Vec<String>,
}

/// The report of one calibration.
pub(crate) struct Report<'a> {
    pub(crate) rows: Vec<Row>,
    pub(crate) in_sample: Stats,
    pub(crate) loo: Stats,
    pub(crate) model: String,
    pub(crate) white: [f64; 3],
    pub(crate) reading: String,
    pub(crate) light: Option<([f64; 2], f64)>,
    pub(crate) ctx: Context<'a>,
}

impl<'a> Report<'a> {
    /// The report of `model` fitted on `cap` (its usable patches), `loo` its leave-one-out.
    pub(crate) fn new(
        cap: &Capture,
        model: &nsrm::Model,
        loo: &EvalResult,
        ctx: Context<'a>,
    ) -> Report<'a> {
        let white = cap.reference.white;
        let level = cap.extraction.white_level;
        let mut rows: Vec<Row> = cap
            .extraction
            .patches
            .iter()
            .map(|p| {
                let fitted = model.apply_f64(p.rgb);
                let mut flags: Vec<String> = p
                    .flags
                    .iter()
                    .map(|f| format!("excluded: {}", f.name()))
                    .collect();
                if let Some(l) = level {
                    let near = nsrm_chart::diagnose::NEAR_CLIP * l;
                    if p.usable() && p.rgb.iter().any(|&v| v >= near) {
                        flags.push("near clipping".into());
                    }
                }
                Row {
                    label: p.label.clone(),
                    reference: p.xyz,
                    fitted,
                    de: delta_e00_xyz(fitted, p.xyz, white),
                    loo: loo
                        .per_patch
                        .iter()
                        .find(|e| e.label == p.label)
                        .map(|e| e.de00),
                    flags,
                }
            })
            .collect();
        rows.sort_by(|a, b| {
            let key = |r: &Row| r.loo.unwrap_or(r.de);
            key(b).total_cmp(&key(a))
        });
        let used: Vec<f64> = rows
            .iter()
            .filter(|r| r.loo.is_some())
            .map(|r| r.de)
            .collect();
        let loo_v: Vec<f64> = rows.iter().filter_map(|r| r.loo).collect();
        let model_name = format!(
            "{} order {} ({} terms)",
            model.kind(),
            model.order(),
            model.len_terms()
        );
        Report {
            in_sample: Stats::of(if used.is_empty() { &[f64::NAN] } else { &used }),
            loo: Stats::of(if loo_v.is_empty() {
                &[f64::NAN]
            } else {
                &loo_v
            }),
            rows,
            model: model_name,
            white,
            reading: super::capture::CaptureText::summary(cap),
            light: cap.light(),
            ctx,
        }
    }

    /// The choice of the model, in words.
    fn choice(&self) -> String {
        if !self.ctx.chosen_by_loo {
            return format!("{}, as named by --kind", self.model);
        }
        let list: Vec<String> = self
            .ctx
            .tried
            .iter()
            .map(|c| {
                format!(
                    "{}{} {:.2} (max {:.2})",
                    c.kind, c.order, c.loo_mean, c.loo_max
                )
            })
            .collect();
        format!(
            "{}: the smallest leave-one-out mean ΔE00 among {} (name one with --kind/--order)",
            self.model,
            list.join(", ")
        )
    }

    fn summary_lines(&self) -> Vec<String> {
        let s = |x: &Stats| {
            format!(
                "mean {:.2}, median {:.2}, p95 {:.2}, max {:.2}",
                x.mean, x.median, x.p95, x.max
            )
        };
        let mut v = vec![
            format!("model: {}", self.choice()),
            format!("in-sample ΔE00:     {}", s(&self.in_sample)),
            format!(
                "leave-one-out ΔE00: {}  (each patch predicted by a fit without it: what to expect on other colours)",
                s(&self.loo)
            ),
        ];
        if let Some((xy, t)) = self.light {
            v.push(format!(
                "light: {t:.0} K (x {:.4}, y {:.4}), from the chart's neutral patches through the raw file's colour matrices",
                xy[0], xy[1]
            ));
        }
        if let Some(g) = self.ctx.glare {
            v.push(format!(
                "glare compensation: subtracted camera RGB ({:.3e}, {:.3e}, {:.3e}) from every patch before the fit",
                g[0], g[1], g[2]
            ));
        }
        if self.ctx.display_referred {
            v.push("warning: the shot is display-referred (JPEG/PNG/8-bit TIFF): the model maps display values, not light; shoot raw for a calibration".into());
        }
        v
    }

    /// The printed report: the table (worst first), the summary and the diagnosis.
    pub(crate) fn text(&self, exports: &[String]) -> String {
        let mut t = String::new();
        let _ = writeln!(t, "calibration of {}", self.ctx.shot.display());
        let _ = writeln!(t, "{}", self.reading);
        let _ = writeln!(
            t,
            "\n{:<18} {:>22} {:>22} {:>6} {:>6}  flags",
            "patch (worst first)", "reference L*a*b*", "fitted L*a*b*", "ΔE00", "LOO"
        );
        for r in &self.rows {
            let lab = |x: [f64; 3]| {
                let l = xyz_to_lab(x, self.white);
                format!("{:6.1} {:6.1} {:6.1}", l[0], l[1], l[2])
            };
            let _ = writeln!(
                t,
                "{:<18} {:>22} {:>22} {:>6.2} {:>6}  {}",
                r.label,
                lab(r.reference),
                lab(r.fitted),
                r.de,
                r.loo.map_or("-".into(), |v| format!("{v:.2}")),
                r.flags.join(", ")
            );
        }
        t.push('\n');
        for l in self.summary_lines() {
            let _ = writeln!(t, "{l}");
        }
        let _ = writeln!(t, "\ndiagnosis:");
        for f in &self.ctx.findings {
            let _ = writeln!(t, "  [{}] {}", severity_name(f.severity), f.text);
            if !f.advice.is_empty() {
                let _ = writeln!(t, "      → {}", f.advice);
            }
        }
        if !exports.is_empty() {
            let _ = writeln!(t, "\nexports:");
            for e in exports {
                let _ = writeln!(t, "  {e}");
            }
        }
        t
    }

    /// The HTML page: self-contained (`overlay_png` inline; SVG plots; a content security policy
    /// that lets the page fetch nothing).
    pub(crate) fn html(&self, overlay_png: &[u8]) -> String {
        let mut h = String::new();
        h.push_str("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\n");
        h.push_str("<meta http-equiv=\"Content-Security-Policy\" content=\"default-src 'none'; img-src data:; style-src 'unsafe-inline'\">\n");
        let _ = writeln!(
            h,
            "<title>nsrm calibration: {}</title>",
            esc(&self.ctx.shot.display().to_string())
        );
        h.push_str(STYLE);
        h.push_str("</head><body>\n");
        let _ = writeln!(
            h,
            "<h1>Calibration of {}</h1>\n<p class=\"reading\">{}</p>",
            esc(&self.ctx.shot.display().to_string()),
            esc(&self.reading)
        );
        h.push_str("<h2 id=\"summary\">Summary</h2>\n<ul>");
        for l in self.summary_lines() {
            let _ = write!(h, "<li>{}</li>", esc(&l));
        }
        h.push_str("</ul>\n");
        self.html_stats(&mut h);
        h.push_str("<h2 id=\"diagnosis\">Diagnosis</h2>\n<ul class=\"diagnosis\">");
        for f in &self.ctx.findings {
            let _ = write!(
                h,
                "<li class=\"{s}\"><b>{s}</b> {}{}</li>",
                esc(&f.text),
                if f.advice.is_empty() {
                    String::new()
                } else {
                    format!("<br><i>→ {}</i>", esc(&f.advice))
                },
                s = severity_name(f.severity)
            );
        }
        h.push_str("</ul>\n<h2 id=\"overlay\">The chart as read</h2>\n");
        let _ = writeln!(
            h,
            "<img alt=\"overlay\" class=\"overlay\" src=\"data:image/png;base64,{}\">",
            base64(overlay_png)
        );
        h.push_str("<h2 id=\"swatches\">Reference (top) and corrected (bottom)</h2>\n");
        h.push_str(&self.swatches_svg());
        h.push_str("<h2 id=\"histogram\">ΔE00 per patch</h2>\n");
        h.push_str(&self.histogram_svg());
        h.push_str("<h2 id=\"ramp\">Neutral ramp: camera response against reference Y</h2>\n");
        h.push_str(&self.ramp_svg());
        h.push_str("<h2 id=\"patches\">Patches, worst first</h2>\n");
        self.html_table(&mut h);
        h.push_str("</body></html>\n");
        h
    }

    fn html_stats(&self, h: &mut String) {
        h.push_str("<table class=\"stats\"><tr><th>ΔE00</th><th>mean</th><th>median</th><th>p95</th><th>max</th></tr>");
        for (name, s) in [("in-sample", &self.in_sample), ("leave-one-out", &self.loo)] {
            let _ = write!(
                h,
                "<tr><td>{name}</td><td>{:.2}</td><td>{:.2}</td><td>{:.2}</td><td>{:.2}</td></tr>",
                s.mean, s.median, s.p95, s.max
            );
        }
        h.push_str("</table>\n");
    }

    fn html_table(&self, h: &mut String) {
        h.push_str("<table class=\"patches\"><tr><th>patch</th><th>reference L*a*b*</th><th>fitted L*a*b*</th><th>ΔE00</th><th>leave-one-out ΔE00</th><th>flags</th></tr>\n");
        for r in &self.rows {
            let lab = |x: [f64; 3]| {
                let l = xyz_to_lab(x, self.white);
                format!("{:.1}, {:.1}, {:.1}", l[0], l[1], l[2])
            };
            let _ = writeln!(
                h,
                "<tr><td>{}</td><td>{}</td><td>{}</td><td>{:.2}</td><td>{}</td><td>{}</td></tr>",
                esc(&r.label),
                lab(r.reference),
                lab(r.fitted),
                r.de,
                r.loo.map_or("–".into(), |v| format!("{v:.2}")),
                esc(&r.flags.join(", "))
            );
        }
        h.push_str("</table>\n");
    }

    /// Reference and corrected colours per patch (sRGB for viewing), ΔE00 under each.
    fn swatches_svg(&self) -> String {
        let m = output_matrix(self.white, OutputSpace::LinearSrgb);
        let hex = |xyz: [f64; 3]| {
            let c = apply(&m, xyz).map(srgb8);
            format!("#{:02x}{:02x}{:02x}", c[0], c[1], c[2])
        };
        let mut rows: Vec<&Row> = self.rows.iter().collect();
        rows.sort_by(|a, b| a.label.cmp(&b.label));
        let (cell, cols) = (80.0, 12usize);
        let lines = rows.len().div_ceil(cols).max(1);
        let mut s = format!(
            "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{}\" height=\"{}\" role=\"img\">",
            cell * cols as f64,
            lines as f64 * (cell + 16.0)
        );
        for (i, r) in rows.iter().enumerate() {
            let x = (i % cols) as f64 * cell;
            let y = (i / cols) as f64 * (cell + 16.0);
            let _ = write!(
                s,
                "<rect x=\"{x}\" y=\"{y}\" width=\"{w}\" height=\"{hh}\" fill=\"{}\"/><rect x=\"{x}\" y=\"{y2}\" width=\"{w}\" height=\"{hh}\" fill=\"{}\"/><text x=\"{tx}\" y=\"{ty}\" font-size=\"11\">{} {:.1}</text>",
                hex(r.reference),
                hex(r.fitted),
                esc(r.label.split(' ').next().unwrap_or("")),
                r.de,
                w = cell - 4.0,
                hh = cell / 2.0 - 2.0,
                y2 = y + cell / 2.0,
                tx = x + 2.0,
                ty = y + cell + 12.0,
            );
        }
        s.push_str("</svg>\n");
        s
    }

    /// Histogram of ΔE00 (in-sample and leave-one-out), bins of 0.5.
    fn histogram_svg(&self) -> String {
        let ins: Vec<f64> = self
            .rows
            .iter()
            .filter(|r| r.loo.is_some())
            .map(|r| r.de)
            .collect();
        let loo: Vec<f64> = self.rows.iter().filter_map(|r| r.loo).collect();
        let top = ins.iter().chain(&loo).cloned().fold(1.0, f64::max);
        let bins = ((top / 0.5).ceil() as usize).clamp(1, 60);
        let count = |v: &[f64]| {
            let mut c = vec![0usize; bins];
            for x in v {
                c[((x / 0.5) as usize).min(bins - 1)] += 1;
            }
            c
        };
        let (a, b) = (count(&ins), count(&loo));
        let most = a.iter().chain(&b).copied().max().unwrap_or(1).max(1) as f64;
        let (w, h, left, bottom) = (640.0, 220.0, 40.0, 30.0);
        let bw = (w - left) / bins as f64;
        let mut s = format!(
            "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" role=\"img\">"
        );
        for i in 0..bins {
            for (j, (c, colour)) in [(a[i], "#4477aa"), (b[i], "#ee6677")].iter().enumerate() {
                let bh = (*c as f64) / most * (h - bottom - 10.0);
                let _ = write!(
                    s,
                    "<rect x=\"{:.1}\" y=\"{:.1}\" width=\"{:.1}\" height=\"{bh:.1}\" fill=\"{colour}\"/>",
                    left + i as f64 * bw + j as f64 * bw / 2.0,
                    h - bottom - bh,
                    bw / 2.0 - 1.0
                );
            }
            if i % 2 == 0 {
                let _ = write!(
                    s,
                    "<text x=\"{:.1}\" y=\"{}\" font-size=\"10\">{:.0}</text>",
                    left + i as f64 * bw,
                    h - bottom + 12.0,
                    i as f64 * 0.5
                );
            }
        }
        let _ = write!(
            s,
            "<text x=\"{left}\" y=\"{}\" font-size=\"11\">ΔE00 (bins of 0.5; most {most:.0} patches) — blue: in-sample, red: leave-one-out</text></svg>",
            h - 4.0
        );
        s.push('\n');
        s
    }

    /// The neutral ramp: camera R, G, B of the neutral patches against reference Y, each with its
    /// line; the intercept is the glare.
    fn ramp_svg(&self) -> String {
        let Some(r) = &self.ctx.ramp else {
            return "<p>fewer than 3 usable neutral patches: no ramp.</p>\n".into();
        };
        let (w, h, m) = (480.0, 320.0, 40.0);
        let top = r
            .points
            .iter()
            .flat_map(|p| p.2)
            .fold(f64::MIN_POSITIVE, f64::max)
            * 1.1;
        let px = |y: f64| m + y / 100.0 * (w - 2.0 * m);
        let py = |v: f64| h - m - v / top * (h - 2.0 * m);
        let mut s = format!(
            "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" role=\"img\">"
        );
        let _ = write!(
            s,
            "<line x1=\"{m}\" y1=\"{b}\" x2=\"{r}\" y2=\"{b}\" stroke=\"#888\"/><line x1=\"{m}\" y1=\"{m}\" x2=\"{m}\" y2=\"{b}\" stroke=\"#888\"/>",
            b = h - m,
            r = w - m
        );
        for (k, colour) in ["#cc3311", "#228833", "#0077bb"].iter().enumerate() {
            let _ = write!(
                s,
                "<line x1=\"{:.1}\" y1=\"{:.1}\" x2=\"{:.1}\" y2=\"{:.1}\" stroke=\"{colour}\" stroke-dasharray=\"4 3\"/>",
                px(0.0),
                py(r.intercept[k]),
                px(100.0),
                py(r.intercept[k] + 100.0 * r.slope[k])
            );
            for p in &r.points {
                let _ = write!(
                    s,
                    "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"3.5\" fill=\"{colour}\"><title>{} {}: {:.5}</title></circle>",
                    px(p.1),
                    py(p.2[k]),
                    esc(&p.0),
                    ["R", "G", "B"][k],
                    p.2[k]
                );
            }
        }
        let _ = write!(
            s,
            "<text x=\"{m}\" y=\"{}\" font-size=\"11\">reference Y (0–100) → ; intercept of G {:.2} % of white (glare), linear to {:.2} %</text></svg>",
            h - 8.0,
            100.0 * r.glare(),
            100.0 * r.nonlinearity
        );
        s.push('\n');
        s
    }
}

fn severity_name(s: Severity) -> &'static str {
    match s {
        Severity::Ok => "ok",
        Severity::Note => "note",
        Severity::Warning => "warning",
    }
}

/// HTML text escaping.
fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// Standard base64 (RFC 4648, with padding).
fn base64(bytes: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for c in bytes.chunks(3) {
        let n = (u32::from(c[0]) << 16)
            | (u32::from(*c.get(1).unwrap_or(&0)) << 8)
            | u32::from(*c.get(2).unwrap_or(&0));
        for i in 0..4 {
            if i <= c.len() {
                s.push(A[((n >> (18 - 6 * i)) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

const STYLE: &str = "<style>body{font-family:sans-serif;max-width:1000px;margin:1em auto;padding:0 1em;color:#222}\
table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #ccc;padding:2px 6px;text-align:right}\
td:first-child,th:first-child{text-align:left}.overlay{max-width:100%}svg{max-width:100%;height:auto;display:block}\
.diagnosis li{margin:.3em 0}.warning b{color:#b00}.note b{color:#a60}.ok b{color:#070}.reading{font-size:90%;color:#555}</style>\n";

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_matches_the_rfc_vectors() {
        for (i, o) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ] {
            assert_eq!(base64(i.as_bytes()), o);
        }
        assert_eq!(
            esc("<a href=\"x\">&</a>"),
            "&lt;a href=&quot;x&quot;&gt;&amp;&lt;/a&gt;"
        );
    }
}
