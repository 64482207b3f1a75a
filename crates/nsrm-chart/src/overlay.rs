//! The overlay picture of a chart reading: the frame as an sRGB preview (camera RGB shown as
//! linear sRGB, white-balanced on the chart's neutrals when there is a reading — else on the
//! frame's grey world — and exposed so the
//! brightest usable patch sits at 90 %), each sampled area outlined and labelled — green when
//! used, red with its flags when not — the candidate regions of a failed detection (yellow:
//! rejected, cyan: linked into a grid), and after a fit a swatch panel: reference (upper half of
//! each swatch) vs corrected (lower half) per patch, with its ΔE00. Labels are 15–28 px, on an
//! opaque dark box so they read on any patch.

use super::detect::Candidate;
use super::extract::Extraction;
use ab_glyph::{FontRef, PxScale};
use image::{Rgb, RgbImage};
use imageproc::drawing::{
    draw_filled_rect_mut, draw_hollow_circle_mut, draw_line_segment_mut, draw_text_mut, text_size,
};
use imageproc::rect::Rect;
use nsrm::srgb8;
use nsrm::Frame;
use nsrm::{apply_mat3 as apply, OutputSpace};

const FONT: &[u8] = include_bytes!("../../../assets/DejaVuSans.ttf");

/// Long side of the picture (the frame is scaled down to it).
pub(crate) const MAX_SIDE: usize = 1600;

/// One patch of the swatch panel.
#[derive(Debug, Clone, PartialEq)]
pub struct Swatch {
    /// The patch's label (`01 dark skin`, `A1`).
    pub label: String,
    /// The chart reference's XYZ.
    pub reference_xyz: [f64; 3],
    /// The model's XYZ for the patch's camera RGB.
    pub corrected_xyz: [f64; 3],
    /// ΔE00 between the two.
    pub delta_e: f64,
}

fn font() -> FontRef<'static> {
    FontRef::try_from_slice(FONT).expect("the embedded font parses (tested)")
}

/// Smallest and largest label size on the picture, in pixels.
pub(crate) const LABEL_PX: (f32, f32) = (15.0, 28.0);

/// Text in `colour` on an opaque dark box (a 2-pixel margin), readable on any part of the
/// picture; `(x, y)` is the box's top-left corner.
fn label(img: &mut RgbImage, colour: Rgb<u8>, x: i32, y: i32, px: f32, font: &FontRef, text: &str) {
    let (tw, th) = text_size(PxScale::from(px), font, text);
    draw_filled_rect_mut(
        img,
        Rect::at(x, y).of_size(tw + 4, (th + 4).max(px.ceil() as u32 + 4)),
        Rgb([0, 0, 0]),
    );
    draw_text_mut(img, colour, x + 2, y + 2, PxScale::from(px), font, text);
}

/// Draws the overlay. `swatches`: (patches, reference white) after a fit. The steps: the
/// white balance and exposure (`balance`), the frame scaled down (`preview`), the
/// candidates (`draw_candidates`), the reading (`draw_reading`), the swatch panel.
pub fn render(
    frame: &Frame,
    reading: Option<&Extraction>,
    candidates: &[Candidate],
    swatches: Option<(&[Swatch], [f64; 3])>,
) -> RgbImage {
    let s = frame.width.max(frame.height).div_ceil(MAX_SIDE).max(1);
    let mut img = picture(frame, reading);
    let font = font();
    let sc = 1.0 / s as f32;
    draw_candidates(&mut img, candidates, sc);
    if let Some(ex) = reading {
        draw_reading(&mut img, ex, sc, &font);
    }
    match swatches {
        Some((sw, white)) if !sw.is_empty() => append_swatches(img, sw, white, &font),
        _ => img,
    }
}

/// The frame as the overlay shows it, without marks: scaled down to at most [`MAX_SIDE`],
/// white-balanced and exposed as [`balance`] says (the studio's un-corrected preview).
pub fn picture(frame: &Frame, reading: Option<&Extraction>) -> RgbImage {
    let s = frame.width.max(frame.height).div_ceil(MAX_SIDE).max(1);
    let (gain, level) = balance(frame, reading);
    let k = if level > 0.0 { 0.9 / level } else { 1.0 };
    preview(frame, s, gain, k)
}

/// The preview's white balance (per-channel gains, G = 1) and the level to show at 90 %: from
/// the reading's neutral patches (a* and b* within 4) and its brightest usable patch; else the
/// frame's grey world ([`grey_world`]) and its 99th percentile of balanced green (every 7th
/// pixel).
fn balance(frame: &Frame, reading: Option<&Extraction>) -> ([f64; 3], f64) {
    match reading {
        Some(ex) => {
            let usable: Vec<_> = ex.patches.iter().filter(|p| p.usable()).collect();
            let neutral: Vec<_> = usable
                .iter()
                .filter(|p| {
                    let lab = nsrm::xyz_to_lab(p.xyz, [96.42, 100.0, 82.51]);
                    lab[1].hypot(lab[2]) < 4.0
                })
                .collect();
            let mut sum = [0.0; 3];
            for p in &neutral {
                for k in 0..3 {
                    sum[k] += p.rgb[k];
                }
            }
            let gain = if neutral.is_empty() || sum.iter().any(|&v| v <= 0.0) {
                [1.0; 3]
            } else {
                [sum[1] / sum[0], 1.0, sum[1] / sum[2]]
            };
            let top = usable
                .iter()
                .map(|p| (0..3).map(|k| p.rgb[k] * gain[k]).fold(0.0, f64::max))
                .fold(0.0, f64::max);
            (gain, top)
        }
        None => {
            let gain = grey_world(frame);
            let ch = frame.layout.channels();
            let mut g: Vec<f32> = frame
                .data
                .chunks_exact(ch)
                .step_by(7)
                .map(|p| p[1])
                .filter(|v| v.is_finite())
                .collect();
            g.sort_by(f32::total_cmp);
            let p = g.get(g.len() * 99 / 100).copied().unwrap_or(1.0) as f64;
            (gain, p)
        }
    }
}

/// Per-channel gains (G = 1) that make the frame's mean grey (the grey-world assumption), from
/// every 7th pixel with finite, positive channels; each gain within [1/8, 8], and none at all
/// (1, 1, 1) when no pixel counts. A camera's raw frame is green-heavy: shown unbalanced it is
/// green, which no person reading a chart wants to see.
fn grey_world(frame: &Frame) -> [f64; 3] {
    let ch = frame.layout.channels();
    let mut sum = [0.0f64; 3];
    for p in frame.data.chunks_exact(ch).step_by(7) {
        if p[..3].iter().all(|v| v.is_finite() && *v > 0.0) {
            for c in 0..3 {
                sum[c] += p[c] as f64;
            }
        }
    }
    if sum.iter().any(|&v| v <= 0.0 || !v.is_finite()) {
        return [1.0; 3];
    }
    [sum[1] / sum[0], 1.0, sum[1] / sum[2]].map(|g| g.clamp(0.125, 8.0))
}

/// The frame as 8-bit sRGB, each `s × s` block averaged and scaled by `gain` per channel and
/// by `k` (an incomplete block at the right or bottom edge is left out).
fn preview(frame: &Frame, s: usize, gain: [f64; 3], k: f64) -> RgbImage {
    let (w, h) = ((frame.width / s).max(1), (frame.height / s).max(1));
    let ch = frame.layout.channels();
    let mut img = RgbImage::new(w as u32, h as u32);
    for y in 0..h {
        for x in 0..w {
            let mut acc = [0.0f64; 3];
            for yy in y * s..(y + 1) * s {
                for xx in x * s..(x + 1) * s {
                    let p = &frame.data[(yy * frame.width + xx) * ch..][..3];
                    for c in 0..3 {
                        acc[c] += p[c] as f64;
                    }
                }
            }
            let n = (s * s) as f64;
            let px = [0, 1, 2].map(|c| srgb8(acc[c] / n * gain[c] * k));
            img.put_pixel(x as u32, y as u32, Rgb(px));
        }
    }
    img
}

/// The detection's candidate regions (frame pixels × `sc`): cyan when linked into a grid,
/// yellow when rejected.
fn draw_candidates(img: &mut RgbImage, candidates: &[Candidate], sc: f32) {
    for c in candidates {
        let colour = if c.accepted {
            Rgb([0, 230, 230])
        } else {
            Rgb([255, 220, 0])
        };
        draw_hollow_circle_mut(
            img,
            (
                (c.centre[0] as f32 * sc) as i32,
                (c.centre[1] as f32 * sc) as i32,
            ),
            ((c.radius as f32 * sc) as i32).max(2),
            colour,
        );
    }
}

/// Each sampled area outlined and labelled (frame pixels × `sc`): green when used, red with its
/// flags when not; labels a third of the patch wide, within [`LABEL_PX`].
fn draw_reading(img: &mut RgbImage, ex: &Extraction, sc: f32, font: &FontRef) {
    let text_px = (0.3
        * ((ex.patches[0].outline[1][0] - ex.patches[0].outline[0][0])
            .hypot(ex.patches[0].outline[1][1] - ex.patches[0].outline[0][1])) as f32
        * sc)
        .clamp(LABEL_PX.0, LABEL_PX.1);
    for p in &ex.patches {
        let colour = if p.usable() {
            Rgb([0, 255, 0])
        } else {
            Rgb([255, 0, 0])
        };
        for q in 0..4 {
            let (a, b) = (p.outline[q], p.outline[(q + 1) % 4]);
            draw_line_segment_mut(
                img,
                (a[0] as f32 * sc, a[1] as f32 * sc),
                (b[0] as f32 * sc, b[1] as f32 * sc),
                colour,
            );
        }
        let short = p.label.split(' ').next().unwrap_or(&p.label).to_string();
        let text = if p.usable() {
            short
        } else {
            let f: Vec<&str> = p.flags.iter().map(|f| f.name()).collect();
            format!("{short} {}", f.join(","))
        };
        let (tw, _) = text_size(PxScale::from(text_px), font, &text);
        label(
            img,
            colour,
            (p.centre[0] as f32 * sc) as i32 - tw as i32 / 2 - 2,
            (p.centre[1] as f32 * sc) as i32 - (text_px as i32) / 2 - 2,
            text_px,
            font,
            &text,
        );
    }
}

/// The caption of the swatch panel: each swatch is split in two halves.
pub(crate) const SWATCH_CAPTION: &str =
    "each swatch: upper half reference, lower half corrected by the model; label and its ΔE00";

/// The panel of swatches below the picture.
fn append_swatches(img: RgbImage, sw: &[Swatch], white: [f64; 3], font: &FontRef) -> RgbImage {
    let m = nsrm::output_matrix(white, OutputSpace::LinearSrgb);
    let to8 = |xyz: [f64; 3]| Rgb(apply(&m, xyz).map(srgb8));
    let cell = 64u32;
    let cols = (img.width() / cell).clamp(6, 24);
    let rows = (sw.len() as u32).div_ceil(cols);
    let panel_w = img.width().max(cols * cell);
    let mut out = RgbImage::from_pixel(panel_w, img.height() + rows * cell + 30, Rgb([40, 40, 40]));
    image::imageops::overlay(&mut out, &img, 0, 0);
    let y0 = img.height() as i32 + 4;
    draw_text_mut(
        &mut out,
        Rgb([240, 240, 240]),
        4,
        y0,
        PxScale::from(16.0),
        font,
        SWATCH_CAPTION,
    );
    for (i, s) in sw.iter().enumerate() {
        let (cx, cy) = ((i as u32 % cols) * cell, (i as u32 / cols) * cell);
        let (x, y) = (cx as i32, y0 + 26 + cy as i32);
        draw_filled_rect_mut(
            &mut out,
            Rect::at(x + 2, y + 2).of_size(cell - 4, cell / 2 - 2),
            to8(s.reference_xyz),
        );
        draw_filled_rect_mut(
            &mut out,
            Rect::at(x + 2, y + cell as i32 / 2).of_size(cell - 4, cell / 2 - 4),
            to8(s.corrected_xyz),
        );
        let short = s.label.split(' ').next().unwrap_or(&s.label);
        let txt = format!("{short} {:.1}", s.delta_e);
        label(
            &mut out,
            Rgb([255, 255, 255]),
            x + 2,
            y + 2,
            13.0,
            font,
            &txt,
        );
    }
    out
}

/// PNG bytes of an overlay.
pub fn encode(img: &RgbImage) -> Result<Vec<u8>, nsrm_io::IoError> {
    use image::codecs::png::PngEncoder;
    use image::{ExtendedColorType, ImageEncoder};
    let mut png = Vec::new();
    PngEncoder::new(&mut png)
        .write_image(
            img.as_raw(),
            img.width(),
            img.height(),
            ExtendedColorType::Rgb8,
        )
        .map_err(|e| nsrm_io::IoError::Invalid(format!("encoding the overlay PNG: {e}")))?;
    Ok(png)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::extract::PatchReading;
    use crate::{ChartKind, Homography};
    use nsrm::Layout;

    fn patch(rgb: [f64; 3], xyz: [f64; 3]) -> PatchReading {
        PatchReading {
            label: "p".into(),
            rgb,
            std: [0.0; 3],
            count: 1,
            flags: Vec::new(),
            xyz,
            centre: [0.0; 2],
            outline: [[0.0; 2]; 4],
            flat: 1.0,
        }
    }

    #[test]
    fn the_balance_comes_from_the_neutrals_else_the_frame() {
        let frame = Frame::from_data(
            10,
            1,
            Layout::Rgb,
            (0..10).flat_map(|i| [0.0, i as f32, 0.0]).collect(),
        )
        .unwrap();
        // Every 7th pixel's green: 0 and 7; the 99th percentile of two is the larger.
        assert_eq!(balance(&frame, None), ([1.0; 3], 7.0));
        let ex = Extraction {
            chart: ChartKind::Cc24,
            homography: Homography([1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]),
            white_level: None,
            white_level_inferred: false,
            patches: vec![
                patch([0.5, 1.0, 0.25], [96.42, 100.0, 82.51]),
                patch([1.0, 0.2, 0.1], [40.0, 20.0, 5.0]),
            ],
        };
        // The grey sets the gains; the red patch, balanced, is the brightest.
        assert_eq!(balance(&frame, Some(&ex)), ([2.0, 1.0, 4.0], 2.0));
    }

    #[test]
    fn without_a_reading_a_green_heavy_frame_is_shown_grey() {
        // A raw frame of a grey scene: green twice red, four times blue, with a brighter strip.
        let data: Vec<f32> = (0..64)
            .flat_map(|i| {
                let v = if i % 8 == 0 { 2.0 } else { 1.0 };
                [0.25 * v, 0.5 * v, 0.125 * v]
            })
            .collect();
        let frame = Frame::from_data(8, 8, Layout::Rgb, data).unwrap();
        let (gain, _) = balance(&frame, None);
        assert!(
            (gain[0] - 2.0).abs() < 1e-9 && (gain[2] - 4.0).abs() < 1e-9,
            "{gain:?}"
        );
        let img = picture(&frame, None);
        for p in img.pixels() {
            let [r, g, b] = p.0;
            assert!(r.abs_diff(g) <= 1 && b.abs_diff(g) <= 1, "{:?}", p.0);
        }
        // A frame with no positive pixel keeps gains of 1, and extreme casts are bounded.
        let black = Frame::from_data(2, 1, Layout::Rgb, vec![0.0; 6]).unwrap();
        assert_eq!(grey_world(&black), [1.0; 3]);
        let red = Frame::from_data(1, 1, Layout::Rgb, vec![1.0, 1e-6, 1.0]).unwrap();
        assert_eq!(grey_world(&red), [0.125, 1.0, 0.125]);
    }

    #[test]
    fn the_preview_averages_blocks() {
        let data = vec![
            0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, //
            1.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, //
        ];
        let frame = Frame::from_data(4, 2, Layout::Rgb, data).unwrap();
        let img = preview(&frame, 2, [1.0; 3], 1.0);
        assert_eq!(img.dimensions(), (2, 1));
        assert_eq!(img.get_pixel(0, 0), img.get_pixel(1, 0));
        assert_eq!(img.get_pixel(0, 0).0, [srgb8(0.5); 3]);
        let dark = preview(&frame, 2, [1.0, 0.0, 1.0], 0.5);
        assert_eq!(dark.get_pixel(1, 0).0, [srgb8(0.25), 0, srgb8(0.25)]);
    }
}
