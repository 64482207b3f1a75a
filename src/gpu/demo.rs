//! The embedding demo behind `examples/embed.rs`: a chart frame uploaded to a texture, corrected
//! by a [`Corrector`] pass recorded into the caller's encoder, then drawn by a small render pass
//! (XYZ → linear sRGB → sRGB encoding in the fragment shader, `shaders/display.wgsl`) to an
//! offscreen `rgba8unorm` target that is read back. [`cpu_srgb8`] is the same picture from the
//! f64 reference, for comparison.
//!
//! Everything here works on the caller's `Device` and `Queue`; nothing creates a device.

use super::corrector::scoped;
use super::{Corrector, GpuError, Target, TexelFormat};
use crate::colorimetry::spaces::{Mat3, OutputSpace};
use crate::frame::{Frame, Layout};
use crate::model::Model;
use crate::training::TrainingSet;
use wgpu::util::DeviceExt;

/// The display shader (`shaders/display.wgsl`): entry points `vs_main`, `fs_main`.
pub const DISPLAY_WGSL: &str = include_str!("../../shaders/display.wgsl");

/// The corrected texture's format in the demo: half floats, as a renderer would keep them.
pub const CORRECTED_FORMAT: TexelFormat = TexelFormat::Rgba16Float;

/// A chart frame: the training set's patches (camera RGB) as `cols`-wide rows of
/// `patch × patch` squares, RGBA with alpha 1; leftover cells are black.
pub fn chart_frame(data: &TrainingSet, cols: usize, patch: usize) -> Frame {
    let cols = cols.max(1);
    let rows = data.len().div_ceil(cols).max(1);
    let (w, h) = (cols * patch, rows * patch);
    let mut frame = Frame::new(w, h, Layout::Rgba);
    for y in 0..h {
        for x in 0..w {
            let i = (y / patch) * cols + x / patch;
            let rgb = data.rgb.get(i).copied().unwrap_or([0.0; 3]);
            let o = 4 * (y * w + x);
            frame.data[o..o + 4].copy_from_slice(&[
                rgb[0] as f32,
                rgb[1] as f32,
                rgb[2] as f32,
                1.0,
            ]);
        }
    }
    frame
}

/// XYZ (in the model's scale: its white has `Y = white_xyz[1]`) → linear sRGB with the white
/// at 1, adapting the model's white to D65.
pub fn xyz_to_display(model: &Model) -> Mat3 {
    let mut m = OutputSpace::LinearSrgb.from_xyz(model.white_xyz());
    let y = if model.white_xyz()[1] > 0.0 {
        model.white_xyz()[1]
    } else {
        100.0
    };
    for row in &mut m {
        for v in row.iter_mut() {
            *v /= y;
        }
    }
    m
}

/// The sRGB transfer function on a linear value clamped to [0, 1].
pub fn srgb_encode(v: f64) -> f64 {
    let x = v.clamp(0.0, 1.0);
    if x <= 0.0031308 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

/// The demo's picture on the CPU: the f64 reference, then [`xyz_to_display`] and
/// [`srgb_encode`], as RGBA8 (alpha 255).
pub fn cpu_srgb8(model: &Model, frame: &Frame) -> Vec<u8> {
    let mut xyz = frame.clone();
    model.apply_frame_f64(&mut xyz);
    let m = xyz_to_display(model);
    let ch = xyz.layout.channels();
    let mut out = Vec::with_capacity(4 * xyz.pixels());
    for px in xyz.data.chunks_exact(ch) {
        let v = [px[0] as f64, px[1] as f64, px[2] as f64];
        let rgb = crate::colorimetry::spaces::apply(&m, v);
        for c in rgb {
            out.push((srgb_encode(c) * 255.0).round() as u8);
        }
        out.push(255);
    }
    out
}

fn extent(w: u32, h: u32) -> wgpu::Extent3d {
    wgpu::Extent3d {
        width: w,
        height: h,
        depth_or_array_layers: 1,
    }
}

fn frame_size(frame: &Frame) -> Result<(u32, u32), GpuError> {
    let ok = |v: usize| u32::try_from(v).ok().filter(|v| *v > 0);
    match (ok(frame.width), ok(frame.height)) {
        (Some(w), Some(h)) if frame.data.len() == frame.pixels() * frame.layout.channels() => {
            Ok((w, h))
        }
        _ => Err(GpuError::Usage(format!(
            "frame {}×{} with {} floats cannot be a texture",
            frame.width,
            frame.height,
            frame.data.len()
        ))),
    }
}

/// Uploads a frame (RGB or RGBA; RGB gets alpha 1) to a new `rgba32float` texture usable as a
/// corrector's source (`TEXTURE_BINDING | COPY_DST | COPY_SRC`).
pub fn upload_rgba32f(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    frame: &Frame,
) -> Result<wgpu::Texture, GpuError> {
    let (w, h) = frame_size(frame)?;
    let rgba: Vec<f32> = match frame.layout {
        Layout::Rgba => frame.data.clone(),
        Layout::Rgb => frame
            .data
            .chunks_exact(3)
            .flat_map(|p| [p[0], p[1], p[2], 1.0])
            .collect(),
    };
    scoped(device, || {
        let tex = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("nsrm camera RGB"),
            size: extent(w, h),
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::Rgba32Float,
            usage: wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::COPY_DST
                | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        queue.write_texture(
            wgpu::TexelCopyTextureInfo {
                texture: &tex,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            bytemuck::cast_slice(&rgba),
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(16 * w),
                rows_per_image: Some(h),
            },
            extent(w, h),
        );
        tex
    })
}

/// Reads a 2D texture back as tightly packed rows of bytes (needs `COPY_SRC`).
pub fn read_texture_bytes(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    texture: &wgpu::Texture,
) -> Result<Vec<u8>, GpuError> {
    let bpp = texture
        .format()
        .block_copy_size(None)
        .ok_or_else(|| GpuError::Usage(format!("cannot read back {:?}", texture.format())))?;
    let (w, h) = (texture.width(), texture.height());
    let row = bpp * w;
    let padded =
        row.div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
    let buffer = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("nsrm texture read-back"),
        size: padded as u64 * h as u64,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut enc = device.create_command_encoder(&Default::default());
    enc.copy_texture_to_buffer(
        wgpu::TexelCopyTextureInfo {
            texture,
            mip_level: 0,
            origin: wgpu::Origin3d::ZERO,
            aspect: wgpu::TextureAspect::All,
        },
        wgpu::TexelCopyBufferInfo {
            buffer: &buffer,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(padded),
                rows_per_image: Some(h),
            },
        },
        extent(w, h),
    );
    let submission = queue.submit([enc.finish()]);
    let (tx, rx) = std::sync::mpsc::channel();
    buffer.map_async(wgpu::MapMode::Read, .., move |r| {
        let _ = tx.send(r);
    });
    device.poll(wgpu::PollType::Wait {
        submission_index: Some(submission),
        timeout: None,
    })?;
    rx.recv()
        .map_err(|_| GpuError::Wgpu("the read-back callback was dropped".into()))??;
    let mut out = Vec::with_capacity((row * h) as usize);
    {
        let view = buffer.get_mapped_range(..)?;
        for y in 0..h as usize {
            let start = y * padded as usize;
            out.extend_from_slice(&view[start..start + row as usize]);
        }
    }
    buffer.unmap();
    Ok(out)
}

/// Reads an `rgba32float` or `rgba16float` texture back as RGBA f32.
pub fn read_texture_rgba_f32(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    texture: &wgpu::Texture,
) -> Result<Vec<f32>, GpuError> {
    let bytes = read_texture_bytes(device, queue, texture)?;
    match texture.format() {
        wgpu::TextureFormat::Rgba32Float => Ok(bytes
            .chunks_exact(4)
            .map(|b| f32::from_ne_bytes([b[0], b[1], b[2], b[3]]))
            .collect()),
        wgpu::TextureFormat::Rgba16Float => Ok(bytes
            .chunks_exact(2)
            .map(|b| half::f16::from_ne_bytes([b[0], b[1]]).to_f32())
            .collect()),
        f => Err(GpuError::Usage(format!("{f:?} is not a float RGBA format"))),
    }
}

/// The demo on the caller's device: uploads `frame` to a texture, records the [`Corrector`]
/// pass (→ an `rgba16float` texture) and the display render pass (→ `rgba8unorm`) into one
/// encoder, submits it, and returns the picture as RGBA8 rows (`width × height × 4` bytes).
pub fn render_corrected(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    model: &Model,
    frame: &Frame,
) -> Result<Vec<u8>, GpuError> {
    let (w, h) = frame_size(frame)?;
    let src = upload_rgba32f(device, queue, frame)?;
    let corrector = Corrector::new(
        device,
        model,
        Target::Texture {
            format: CORRECTED_FORMAT,
        },
    )?;
    super::shader::validate(DISPLAY_WGSL)?;
    let m = xyz_to_display(model);
    let rows: Vec<[f32; 4]> = m
        .iter()
        .map(|r| [r[0] as f32, r[1] as f32, r[2] as f32, 0.0])
        .collect();
    let (corrected, target, pipeline, bind_group) = scoped(device, || {
        let corrected = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("nsrm corrected XYZ"),
            size: extent(w, h),
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: CORRECTED_FORMAT.texture_format(),
            usage: wgpu::TextureUsages::STORAGE_BINDING
                | wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        let target = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("nsrm display"),
            size: extent(w, h),
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::Rgba8Unorm,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        let uniform = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("nsrm display matrix"),
            contents: bytemuck::cast_slice(&rows),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("nsrm display"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: false },
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                    count: None,
                },
            ],
        });
        let corrected_view = corrected.create_view(&Default::default());
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("nsrm display"),
            layout: &layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: uniform.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::TextureView(&corrected_view),
                },
            ],
        });
        let pl = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("nsrm display"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("nsrm display"),
            source: wgpu::ShaderSource::Wgsl(DISPLAY_WGSL.into()),
        });
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("nsrm display"),
            layout: Some(&pl),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs_main"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            primitive: wgpu::PrimitiveState::default(),
            depth_stencil: None,
            multisample: wgpu::MultisampleState::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("fs_main"),
                compilation_options: Default::default(),
                targets: &[Some(wgpu::ColorTargetState {
                    format: wgpu::TextureFormat::Rgba8Unorm,
                    blend: None,
                    write_mask: wgpu::ColorWrites::ALL,
                })],
            }),
            multiview_mask: None,
            cache: None,
        });
        (corrected, target, pipeline, bind_group)
    })?;

    let mut enc = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
        label: Some("nsrm demo"),
    });
    // 1. The correction, recorded into our encoder like any other pass of a renderer.
    corrector.record_textures(device, &mut enc, &src, &corrected, None)?;
    // 2. The display pass reads the corrected texture.
    {
        let view = target.create_view(&Default::default());
        let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("nsrm display"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: None,
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &bind_group, &[]);
        pass.draw(0..3, 0..1);
    }
    queue.submit([enc.finish()]);
    read_texture_bytes(device, queue, &target)
}

/// Writes RGBA8 rows as a PNG (atomically; an existing file is replaced).
pub fn save_png(
    path: &std::path::Path,
    width: u32,
    height: u32,
    rgba8: &[u8],
) -> Result<(), GpuError> {
    let img = image::RgbaImage::from_raw(width, height, rgba8.to_vec())
        .ok_or_else(|| GpuError::Usage("the picture's size does not match its pixels".into()))?;
    let mut png = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)?;
    Ok(crate::atomic::write_atomic(path, &png, true)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn display_shader_validates() {
        let (module, _) = super::super::shader::validate(DISPLAY_WGSL).unwrap();
        let names: Vec<_> = module
            .entry_points
            .iter()
            .map(|e| e.name.as_str())
            .collect();
        assert_eq!(names, ["vs_main", "fs_main"]);
    }

    #[test]
    fn srgb_encoding_and_white() {
        assert_eq!(srgb_encode(0.0), 0.0);
        assert!((srgb_encode(1.0) - 1.0).abs() < 1e-12);
        assert!((srgb_encode(0.18) - 0.4613561295).abs() < 1e-6);
        let model = Model::from_matrix(
            crate::model::Kind::Lrm,
            1,
            vec![1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        )
        .unwrap();
        // The model's white maps to display white.
        let rgb = crate::colorimetry::spaces::apply(&xyz_to_display(&model), model.white_xyz());
        for c in rgb {
            assert!((c - 1.0).abs() < 1e-3, "{rgb:?}");
        }
    }
}
