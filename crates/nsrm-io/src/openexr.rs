//! OpenEXR in and out, keeping everything but the corrected `R`, `G`, `B`.
//!
//! Every file's headers and offset tables are checked first ([`chunks::Table::read`]): sizes
//! against [`super::Limits`], every chunk present exactly once and inside the file. Single-part
//! scanline files (none, RLE, ZIPS, ZIP or PIZ; the common camera-plate case) then take the
//! chunk-level path of [`chunks`]: parallel within the frame, libdeflate for ZIP. Everything else
//! (tiles, mip/rip levels, multi-part, subsampled channels, lossy or decreasing-y inputs) goes
//! through the `exr` crate's whole-image reader and writer.

mod canonical;
mod chunks;
mod piz;

use nsrm::{Concern, Param};

use super::WriteSeek;
use super::{Container, Decoded, ExrCompression, FileFormat, IoError, ReadOptions, WriteOptions};
use ::exr::compression::Compression;
use ::exr::image::{
    AnyChannel, AnyChannels, AnyImage, Blocks, Encoding, FlatSamples, Image, Layer, Levels,
};
use ::exr::math::Vec2;
use ::exr::meta::attribute::{AttributeValue, Chromaticities, IntegerBounds, LineOrder, Text};
use ::exr::meta::header::{ImageAttributes, LayerAttributes};
use ::exr::prelude::f16;
use ::exr::prelude::traits::*;
use nsrm::OutputSpace;
use nsrm::{Frame, Layout};
use std::path::Path;

/// The standard attribute naming the colour space of the pixels (ASWF colour interop).
pub(crate) const COLOR_INTEROP_ID: &str = "colorInteropID";

/// A decoded EXR minus its camera RGB samples.
#[derive(Debug)]
pub(crate) enum ExrContainer {
    /// Through the `exr` crate's whole-image reader.
    Image(Box<ImageContainer>),
    /// Through the chunk-level fast path.
    Chunked(Box<chunks::Chunked>),
}

/// A whole decoded image minus its camera RGB samples (moved into the frames while they are
/// corrected).
#[derive(Debug)]
pub(crate) struct ImageContainer {
    image: AnyImage,
    /// The part holding the camera RGB.
    layer: usize,
    /// Indices of `R`, `G`, `B` in that part's (sorted) channel list.
    rgb: [usize; 3],
    alpha: Option<usize>,
}

fn exr_err(path: &Path, err: ::exr::error::Error) -> IoError {
    IoError::Exr {
        path: path.to_path_buf(),
        err,
    }
}

/// The names a part offers to [`locate`]: its name and its channels' names.
struct PartNames {
    name: Option<String>,
    channels: Vec<String>,
}

pub(super) fn read(
    path: &Path,
    opts: &ReadOptions,
    pool: Option<&super::FramePool>,
) -> Result<Decoded, IoError> {
    let file = std::fs::File::open(path).map_err(|err| IoError::Read {
        path: path.to_path_buf(),
        err,
    })?;
    let table = chunks::Table::read(path, &file, &opts.limits)?;
    let channels_err = |(why, concern)| IoError::Channels {
        path: path.to_path_buf(),
        why,
        concern,
    };
    if table.fast() {
        let h = &table.meta.headers[0];
        let names = [PartNames {
            name: h.own_attributes.layer_name.as_ref().map(|t| t.to_string()),
            channels: h.channels.list.iter().map(|c| c.name.to_string()).collect(),
        }];
        let (_, rgb, alpha) = locate(&names, opts.layer.as_deref()).map_err(channels_err)?;
        let (frame, container) = chunks::decode(path, &file, table, rgb, alpha, pool)?;
        return Ok(Decoded {
            path: path.to_path_buf(),
            format: FileFormat::Exr,
            frame,
            levels: Vec::new(),
            container: Container::Exr(Box::new(ExrContainer::Chunked(Box::new(container)))),
        });
    }
    drop(table);
    let mut file = file;
    std::io::Seek::seek(&mut file, std::io::SeekFrom::Start(0)).map_err(|err| IoError::Read {
        path: path.to_path_buf(),
        err,
    })?;
    let image: AnyImage = ::exr::image::read::read()
        .no_deep_data()
        .all_resolution_levels()
        .all_channels()
        .all_layers()
        .all_attributes()
        .from_buffered(std::io::BufReader::new(file))
        .map_err(|e| exr_err(path, e))?;
    let (layer, rgb, alpha) =
        locate(&part_names(&image), opts.layer.as_deref()).map_err(channels_err)?;
    let mut container = ImageContainer {
        image,
        layer,
        rgb,
        alpha,
    };
    let mut frames = container.take_frames(path)?;
    let frame = frames.remove(0);
    Ok(Decoded {
        path: path.to_path_buf(),
        format: FileFormat::Exr,
        frame,
        levels: frames,
        container: Container::Exr(Box::new(ExrContainer::Image(Box::new(container)))),
    })
}

fn part_names(image: &AnyImage) -> Vec<PartNames> {
    image
        .layer_data
        .iter()
        .map(|l| PartNames {
            name: l.attributes.layer_name.as_ref().map(|t| t.to_string()),
            channels: l
                .channel_data
                .list
                .iter()
                .map(|c| c.name.to_string())
                .collect(),
        })
        .collect()
}

impl ExrContainer {
    /// The alpha channel's full-resolution samples as f32.
    pub(super) fn alpha_f32(&self) -> Option<Vec<f32>> {
        match self {
            ExrContainer::Image(c) => c.alpha_f32(),
            ExrContainer::Chunked(c) => c.alpha_f32(),
        }
    }

    /// Names of the channels passed through besides alpha (`part/name` for other parts).
    pub(super) fn extra_channels(&self) -> Vec<String> {
        match self {
            ExrContainer::Image(c) => c.extra_channels(),
            ExrContainer::Chunked(c) => c
                .header
                .channels
                .list
                .iter()
                .enumerate()
                .filter(|(i, _)| !c.rgb.contains(i) && c.alpha != Some(*i))
                .map(|(_, ch)| ch.name.to_string())
                .collect(),
        }
    }

    /// Puts the corrected frames back and writes the whole image to `dest`.
    pub(super) fn write(
        self,
        frame: &Frame,
        levels: &[Frame],
        dest: &Path,
        opts: &WriteOptions,
        w: &mut dyn WriteSeek,
    ) -> Result<(), IoError> {
        match self {
            ExrContainer::Image(c) => (*c).write(frame, levels, dest, opts, w),
            ExrContainer::Chunked(c) => {
                if !levels.is_empty() {
                    return Err(IoError::Encode {
                        path: dest.to_path_buf(),
                        why: format!(
                            "{} resolution levels given for a scanline file",
                            levels.len() + 1
                        ),
                    });
                }
                let compression = chosen(opts.compression, c.header.compression);
                c.write(frame, w, compression, opts.half, opts.zip_level, |h| {
                    set_header_colour(
                        &mut h.shared_attributes,
                        &mut h.own_attributes,
                        Some(opts.space),
                    )
                })
                .map_err(|e| encode_err(dest, e))
            }
        }
    }
}

fn encode_err(dest: &Path, e: ::exr::error::Error) -> IoError {
    match e {
        ::exr::error::Error::Io(err) => IoError::Write {
            path: dest.to_path_buf(),
            err,
        },
        other => IoError::Encode {
            path: dest.to_path_buf(),
            why: other.to_string(),
        },
    }
}

/// The part, the R, G, B channel indices and the alpha channel index of the camera RGB.
type Located = (usize, [usize; 3], Option<usize>);

/// Finds the part and channel indices of the camera RGB; the error says whether the layer is its
/// cause (one was named that is not there) or the way out (several offer R, G, B).
fn locate(image: &[PartNames], want: Option<&str>) -> Result<Located, (String, Option<Concern>)> {
    let find = |li: usize, prefix: &str| -> Option<([usize; 3], Option<usize>)> {
        let list = &image[li].channels;
        let idx = |n: &str| {
            let name = format!("{prefix}{n}");
            list.iter().position(|c| *c == name)
        };
        Some(([idx("R")?, idx("G")?, idx("B")?], idx("A")))
    };
    let parts = image.len();
    let part_name = |li: usize| image[li].name.clone();
    match want {
        Some(name) => {
            for li in 0..parts {
                if part_name(li).as_deref() == Some(name) {
                    if let Some((rgb, a)) = find(li, "") {
                        return Ok((li, rgb, a));
                    }
                }
            }
            let prefix = format!("{name}.");
            for li in 0..parts {
                if let Some((rgb, a)) = find(li, &prefix) {
                    return Ok((li, rgb, a));
                }
            }
            Err((
                format!(
                    "no layer `{name}` with R, G and B channels ({})",
                    describe(image).0
                ),
                Some(Concern::Value(Param::Layer)),
            ))
        }
        None => {
            for li in 0..parts {
                if let Some((rgb, a)) = find(li, "") {
                    return Ok((li, rgb, a));
                }
            }
            let list = &image[0].channels;
            let missing: Vec<&str> = ["R", "G", "B"]
                .into_iter()
                .filter(|n| !list.iter().any(|c| c == n))
                .collect();
            let (described, layers) = describe(image);
            Err((
                format!(
                    "no {} channel{} ({described})",
                    missing.join(", "),
                    if missing.len() == 1 { "" } else { "s" },
                ),
                layers.then_some(Concern::Remedy(Param::Layer)),
            ))
        }
    }
}

/// `channels: …; layers with R, G, B: … (pick one)` for error messages, and whether there are
/// such layers.
fn describe(image: &[PartNames]) -> (String, bool) {
    let mut names = Vec::new();
    let mut layers: Vec<String> = Vec::new();
    for l in image {
        let part = l.name.clone();
        let list = &l.channels;
        for n in list {
            names.push(match &part {
                Some(p) if image.len() > 1 => format!("{p}/{n}"),
                _ => n.clone(),
            });
            if let Some(prefix) = n.strip_suffix(".R") {
                let has = |c: &str| list.iter().any(|m| *m == format!("{prefix}.{c}"));
                if has("G") && has("B") && !layers.iter().any(|x| x == prefix) {
                    layers.push(prefix.to_string());
                }
            }
        }
        if let Some(p) = part {
            let has = |c: &str| list.iter().any(|m| m == c);
            if has("R") && has("G") && has("B") && !layers.contains(&p) {
                layers.push(p);
            }
        }
    }
    const SHOWN: usize = 24;
    let mut s = if names.is_empty() {
        "the file has no channels".to_string()
    } else if names.len() > SHOWN {
        format!(
            "channels: {}, … ({} in all)",
            names[..SHOWN].join(", "),
            names.len()
        )
    } else {
        format!("channels: {}", names.join(", "))
    };
    if !layers.is_empty() {
        s += &format!("; layers with R, G, B: {} (pick one)", layers.join(", "));
    }
    (s, !layers.is_empty())
}

fn push_f32(out: &mut [f32], stride: usize, offset: usize, samples: &FlatSamples) {
    let dst = out.iter_mut().skip(offset).step_by(stride);
    match samples {
        FlatSamples::F16(v) => dst.zip(v).for_each(|(d, s)| *d = s.to_f32()),
        FlatSamples::F32(v) => dst.zip(v).for_each(|(d, s)| *d = *s),
        FlatSamples::U32(v) => dst.zip(v).for_each(|(d, s)| *d = *s as f32),
    }
}

fn samples_of(frame: &Frame, c: usize, half: bool) -> FlatSamples {
    let it = frame
        .data
        .chunks_exact(frame.layout.channels())
        .map(|px| px[c]);
    if half {
        FlatSamples::F16(it.map(f16::from_f32).collect())
    } else {
        FlatSamples::F32(it.collect())
    }
}

impl ImageContainer {
    fn part(&self) -> &Layer<AnyChannels<Levels<FlatSamples>>> {
        &self.image.layer_data[self.layer]
    }

    /// Moves the camera RGB of every resolution level into frames, leaving empty sample
    /// vectors in the image (refilled by [`ExrContainer::write`]).
    fn take_frames(&mut self, path: &Path) -> Result<Vec<Frame>, IoError> {
        let part = self.part();
        let list = &part.channel_data.list;
        for &c in &self.rgb {
            if list[c].sampling != Vec2(1, 1) {
                return Err(IoError::Unsupported {
                    path: path.to_path_buf(),
                    why: format!(
                        "channel `{}` is subsampled ({}×{}); colour channels must be full resolution",
                        list[c].name, list[c].sampling.0, list[c].sampling.1
                    ),
                });
            }
        }
        let sizes: Vec<Vec2<usize>> = part
            .levels_with_resolution(&list[self.rgb[0]].sample_data)
            .map(|(_, size)| size)
            .collect();
        let mut frames = Vec::with_capacity(sizes.len());
        for (k, size) in sizes.iter().enumerate() {
            let n = size.0 * size.1;
            let mut data = vec![0.0f32; 3 * n];
            for (ci, &c) in self.rgb.iter().enumerate() {
                let levels = list[c].sample_data.levels_as_slice();
                let samples =
                    levels
                        .get(k)
                        .filter(|s| s.len() == n)
                        .ok_or_else(|| IoError::Unsupported {
                            path: path.to_path_buf(),
                            why: format!(
                                "channel `{}` level {k} does not hold {}×{} samples",
                                list[c].name, size.0, size.1
                            ),
                        })?;
                push_f32(&mut data, 3, ci, samples);
            }
            frames.push(Frame {
                width: size.0,
                height: size.1,
                layout: Layout::Rgb,
                data,
            });
        }
        let rgb = self.rgb;
        let list = &mut self.image.layer_data[self.layer].channel_data.list;
        for c in rgb {
            for s in list[c].sample_data.levels_as_slice_mut() {
                *s = FlatSamples::F32(Vec::new());
            }
        }
        Ok(frames)
    }

    /// The alpha channel's full-resolution samples as f32.
    fn alpha_f32(&self) -> Option<Vec<f32>> {
        let a = &self.part().channel_data.list[self.alpha?];
        let s = &a.sample_data.levels_as_slice()[0];
        let mut out = vec![0.0; s.len()];
        push_f32(&mut out, 1, 0, s);
        Some(out)
    }

    fn extra_channels(&self) -> Vec<String> {
        let mut out = Vec::new();
        for (li, l) in self.image.layer_data.iter().enumerate() {
            for (ci, c) in l.channel_data.list.iter().enumerate() {
                if li == self.layer && (self.rgb.contains(&ci) || self.alpha == Some(ci)) {
                    continue;
                }
                if li == self.layer {
                    out.push(c.name.to_string());
                } else {
                    let part = l
                        .attributes
                        .layer_name
                        .as_ref()
                        .map(|t| t.to_string())
                        .unwrap_or_else(|| format!("part {li}"));
                    out.push(format!("{part}/{}", c.name));
                }
            }
        }
        out
    }

    /// Puts the corrected frames back and writes the whole image to `dest`.
    fn write(
        self,
        frame: &Frame,
        levels: &[Frame],
        dest: &Path,
        opts: &WriteOptions,
        w: &mut dyn WriteSeek,
    ) -> Result<(), IoError> {
        let ImageContainer {
            mut image,
            layer,
            rgb,
            ..
        } = self;
        let frames: Vec<&Frame> = std::iter::once(frame).chain(levels).collect();
        let list = &mut image.layer_data[layer].channel_data.list;
        for (ci, &c) in rgb.iter().enumerate() {
            let slots = list[c].sample_data.levels_as_slice_mut();
            if slots.len() != frames.len() {
                return Err(IoError::Encode {
                    path: dest.to_path_buf(),
                    why: format!(
                        "{} resolution levels given for {} in the file",
                        frames.len(),
                        slots.len()
                    ),
                });
            }
            for (slot, f) in slots.iter_mut().zip(&frames) {
                *slot = samples_of(f, ci, opts.half);
            }
        }
        drop(frames);
        for l in image.layer_data.iter_mut() {
            l.encoding.compression = chosen(opts.compression, l.encoding.compression);
        }
        set_colour_attributes(&mut image, layer, Some(opts.space));
        write_image(&image, dest, w)
    }
}

/// The compression to write with: the one asked for, or with [`ExrCompression::Keep`] the
/// input's when it is lossless and writable, else ZIP. Re-encoding with a lossy codec would
/// change the pass-through channels again.
fn chosen(want: ExrCompression, input: Compression) -> Compression {
    match want {
        ExrCompression::Keep => match input {
            Compression::Uncompressed
            | Compression::RLE
            | Compression::ZIP1
            | Compression::ZIP16
            | Compression::PIZ => input,
            _ => Compression::ZIP16,
        },
        ExrCompression::None => Compression::Uncompressed,
        ExrCompression::Rle => Compression::RLE,
        ExrCompression::Zips => Compression::ZIP1,
        ExrCompression::Zip => Compression::ZIP16,
        ExrCompression::Piz => Compression::PIZ,
    }
}

/// Sets `colorInteropID` on the corrected part and the image's `chromaticities` to match
/// `space` (removed for XYZ, and when `space` is `None`: camera RGB has no standard primaries).
fn set_colour_attributes(image: &mut AnyImage, layer: usize, space: Option<OutputSpace>) {
    set_header_colour(
        &mut image.attributes,
        &mut image.layer_data[layer].attributes,
        space,
    );
}

/// [`set_colour_attributes`] on one header's shared (image) and own (part) attributes.
fn set_header_colour(
    shared: &mut ImageAttributes,
    own: &mut LayerAttributes,
    space: Option<OutputSpace>,
) {
    let key = Text::from(COLOR_INTEROP_ID);
    shared.other.remove(&key);
    let attrs = &mut own.other;
    match space {
        Some(s) => {
            attrs.insert(key, AttributeValue::Text(Text::from(s.interop_id())));
        }
        None => {
            attrs.remove(&key);
        }
    }
    shared.chromaticities = space.and_then(|s| s.primaries()).map(|(p, w)| {
        let v = |xy: [f64; 2]| Vec2(xy[0] as f32, xy[1] as f32);
        Chromaticities {
            red: v(p[0]),
            green: v(p[1]),
            blue: v(p[2]),
            white: v(w),
        }
    });
}

/// How [`write_new`] writes a new EXR.
#[derive(Debug, Clone, Copy)]
pub(super) struct NewExr<'a> {
    pub half: bool,
    /// [`ExrCompression::Keep`]: ZIP (16 lines a block), as for an input whose compression is
    /// not written.
    pub compression: ExrCompression,
    /// The deflate level of ZIP and ZIPS (libdeflate's, as for EXR inputs).
    pub zip_level: u8,
    /// `None`: camera RGB (no `colorInteropID`, no `chromaticities`).
    pub space: Option<OutputSpace>,
    /// Extra text attributes (`comments` goes to the standard attribute).
    pub text: &'a [(&'a str, &'a str)],
    /// The camera of a raw input: make, model, ISO, exposure time and aperture in the standard
    /// attributes, the as-shot neutral (camera RGB) in `nsrmAsShotNeutral`.
    pub camera: Option<&'a super::raw::CameraInfo>,
}

impl NewExr<'static> {
    /// The settings of a corrected output.
    pub(super) fn output(opts: &WriteOptions) -> NewExr<'static> {
        NewExr {
            half: opts.half,
            compression: opts.compression,
            zip_level: opts.zip_level,
            space: Some(opts.space),
            text: &[],
            camera: None,
        }
    }
}

/// Writes a new single-part scanline EXR (ZIP unless told otherwise) with `R`, `G`, `B` (and
/// `A`) from `rgb` (RGB, or RGBA whose alpha then takes the place of `alpha`) and `alpha`,
/// colour attributes for `space` and extra text attributes. The header is the one the `exr`
/// crate's whole-image writer makes for these channels; the chunks go through the chunk-level
/// writer ([`chunks::Chunked::write`]: blocks encoded in parallel, ZIP by libdeflate), as for
/// EXR inputs.
pub(super) fn write_new(
    rgb: &Frame,
    alpha: Option<&[f32]>,
    dest: &Path,
    how: &NewExr<'_>,
    w: &mut dyn WriteSeek,
) -> Result<(), IoError> {
    let split;
    let (rgb, alpha) = match rgb.layout {
        Layout::Rgb => (rgb, alpha),
        Layout::Rgba => {
            split = super::split_alpha(rgb);
            (&split.0, split.1.as_deref())
        }
    };
    // The compression is set by the chunk writer.
    let header = new_header(rgb, alpha.is_some(), dest, how)?;
    let compression = chosen(how.compression, Compression::ZIP16);
    let names: Vec<String> = header
        .channels
        .list
        .iter()
        .map(|c| c.name.to_string())
        .collect();
    let at = |n: &str| names.iter().position(|c| c == n);
    let (Some(r), Some(g), Some(b)) = (at("R"), at("G"), at("B")) else {
        return Err(IoError::Encode {
            path: dest.to_path_buf(),
            why: "the new header lacks R, G or B".into(),
        });
    };
    // The pass-through bytes: alpha, line by line, as the file stores it (little-endian).
    let rest: Vec<u8> = match alpha {
        None => Vec::new(),
        Some(a) if a.len() == rgb.pixels() => {
            if how.half {
                a.iter()
                    .flat_map(|&v| f16::from_f32(v).to_bits().to_le_bytes())
                    .collect()
            } else {
                a.iter().flat_map(|&v| v.to_le_bytes()).collect()
            }
        }
        Some(a) => {
            return Err(IoError::Encode {
                path: dest.to_path_buf(),
                why: format!(
                    "{} alpha samples for a {}×{} frame",
                    a.len(),
                    rgb.width,
                    rgb.height
                ),
            })
        }
    };
    let alpha_at = alpha.and(at("A"));
    let chunked = chunks::Chunked::new(header, [r, g, b], alpha_at, rest);
    chunked
        .write(rgb, w, compression, how.half, how.zip_level, |_| {})
        .map_err(|e| encode_err(dest, e))
}

/// The header the `exr` crate's writer makes for a single-part scanline image of `rgb`'s size
/// with `R`, `G`, `B` (and `A`: f32, or f16 with `half`), the colour attributes of `how.space`,
/// its text attributes and camera. No samples are held: the chunk writer takes them from the
/// frame.
fn new_header(
    rgb: &Frame,
    with_alpha: bool,
    dest: &Path,
    how: &NewExr<'_>,
) -> Result<::exr::meta::header::Header, IoError> {
    let empty = || {
        if how.half {
            FlatSamples::F16(Vec::new())
        } else {
            FlatSamples::F32(Vec::new())
        }
    };
    let mut list = ::exr::prelude::SmallVec::new();
    let alpha = with_alpha.then_some("A");
    for name in ["R", "G", "B"].into_iter().chain(alpha) {
        list.push(AnyChannel::new(name, Levels::Singular(empty())));
    }
    let size = Vec2(rgb.width, rgb.height);
    let mut attributes = LayerAttributes::default();
    for (k, v) in how.text {
        let (Some(k), Some(v)) = (Text::new_or_none(k), Text::new_or_none(v)) else {
            return Err(IoError::Encode {
                path: dest.to_path_buf(),
                why: format!("attribute `{k}` cannot be stored in an EXR header"),
            });
        };
        if k.eq("comments") {
            attributes.comments = Some(v);
        } else {
            attributes.other.insert(k, AttributeValue::Text(v));
        }
    }
    if let Some(c) = how.camera {
        camera_attributes(&mut attributes, c);
    }
    let layer = Layer::new(
        size,
        attributes,
        Encoding {
            compression: Compression::ZIP16,
            blocks: Blocks::ScanLines,
            line_order: LineOrder::Increasing,
        },
        AnyChannels::sort(list),
    );
    let mut image = Image::from_layers(
        ImageAttributes::new(IntegerBounds::from_dimensions(size)),
        ::exr::prelude::SmallVec::from_vec(vec![layer]),
    );
    set_colour_attributes(&mut image, 0, how.space);
    let mut headers = image.write().infer_meta_data();
    if headers.len() != 1 {
        return Err(IoError::Encode {
            path: dest.to_path_buf(),
            why: format!("{} headers for one part", headers.len()),
        });
    }
    Ok(headers.remove(0))
}

/// Encodes `image` into `w` (`dest` names it in errors).
fn write_image(image: &AnyImage, dest: &Path, w: &mut dyn WriteSeek) -> Result<(), IoError> {
    // Attributes sorted by name: the same image gives the same bytes (canonical.rs).
    let mut sorted = canonical::SortedHeader::new(w);
    image
        .write()
        .to_buffered(&mut sorted)
        .map_err(|e| encode_err(dest, e))?;
    sorted
        .finish()
        .map(|_| ())
        .map_err(|e| encode_err(dest, e.into()))
}

/// OpenEXR's standard attributes for what a raw file says (`cameraMake`, `cameraModel`,
/// `isoSpeed`, `expTime`, `aperture`), and the as-shot neutral in camera RGB, which has no
/// standard attribute (`adoptedNeutral` is a CIE xy chromaticity), as `nsrmAsShotNeutral` (v3f).
fn camera_attributes(attributes: &mut LayerAttributes, c: &super::raw::CameraInfo) {
    let mut text = |k: &str, v: &str| {
        if v.trim().is_empty() {
            return;
        }
        if let (Some(k), Some(v)) = (Text::new_or_none(k), Text::new_or_none(v.trim())) {
            attributes.other.insert(k, AttributeValue::Text(v));
        }
    };
    text("cameraMake", &c.make);
    text("cameraModel", &c.model);
    // What was done to the sensor's frame: the file's orientation, applied as LibRaw does.
    text(
        "nsrmOrientation",
        &format!(
            "{}: {}",
            c.orientation,
            super::raw::describe_orientation(c.orientation)
        ),
    );
    attributes.iso_speed = c.iso;
    attributes.exposure = c.exposure_time;
    attributes.aperture = c.aperture;
    if let Some([r, g, b]) = c.as_shot_neutral {
        if let Some(k) = Text::new_or_none("nsrmAsShotNeutral") {
            attributes
                .other
                .insert(k, AttributeValue::FloatVec3((r, g, b)));
        }
    }
}
