//! Embedding nsrm's colour correction in a wgpu renderer: the whole frame, in one file.
//!
//! The renderer owns the device and the command encoder; nsrm's [`Corrector`] only records a
//! compute pass into it. This example
//! 1. simulates a ColorChecker 24 seen by a Nikon D5100 under D65 and fits NSRM (order 3),
//! 2. opens its own wgpu device (as any renderer would),
//! 3. uploads the chart (camera RGB) to an `rgba32float` texture, records the [`Corrector`]
//!    pass (→ `rgba16float` XYZ) and a small render pass that draws the corrected texture as
//!    sRGB (XYZ → linear sRGB → sRGB encoding in the fragment shader, `shaders/display.wgsl`) to
//!    an offscreen `rgba8unorm` target, all in one encoder and one submit ([`render_corrected`]),
//! 4. reads the target back, saves it as PNG and compares it with the f64 CPU path
//!    ([`cpu_srgb8`]; exit status 1 if any byte differs by more than 1/255; CI runs this example,
//!    and `tests/gpu.rs` runs the same functions).
//!
//! ```text
//! cargo run --example embed [-- OUT.png]     (default: $TMPDIR/nsrm-embed.png)
//! ```
//!
//! The heart of it, on your own `device`, `queue` and `encoder`:
//!
//! ```ignore
//! let corrector = Corrector::new(&device, &model, Target::Texture { format: TexelFormat::Rgba16Float })?;
//! corrector.record_textures(&device, &mut encoder, &camera_rgb_texture, &xyz_texture, None)?;
//! // ... your passes read `xyz_texture` ...
//! corrector.set_model(&queue, &other_model_of_the_same_kind_and_order)?; // swap at run time
//! ```
//!
//! [`Corrector`]: nsrm::gpu::Corrector

use anyhow::{Context, Result};
use nsrm::gpu::{Corrector, Target, TexelFormat};
use nsrm::OutputSpace;
use nsrm::{fit, Kind, Model};
use nsrm::{simulate_named, Grid};
use nsrm::{Frame, Layout, TrainingSet};
use std::path::{Path, PathBuf};
use wgpu::util::DeviceExt;

/// The display shader: a full-screen triangle whose fragment shader converts the corrected XYZ
/// to sRGB with the matrix in its uniform (entry points `vs_main`, `fs_main`).
pub const DISPLAY_WGSL: &str = include_str!("../shaders/display.wgsl");

/// The corrected texture's format: half floats, as a renderer would keep them.
pub const CORRECTED_FORMAT: TexelFormat = TexelFormat::Rgba16Float;

#[allow(dead_code)] // `tests/gpu.rs` includes this file for its functions, not for `main`.
fn main() -> Result<()> {
    let out = std::env::args_os()
        .nth(1)
        .map(PathBuf::from)
        .unwrap_or_else(|| std::env::temp_dir().join("nsrm-embed.png"));

    // 1. The chart and the model.
    let data = simulate_named("nikon-d5100", "D65", "cc24", &Grid::default())?;
    let model = fit(Kind::Nsrm, 3, &data)?;
    let frame = chart_frame(&data, 6, 48);

    // 2. The renderer's device: plain wgpu (WGPU_BACKEND is honoured, Vulkan/Metal/DX12 else).
    let mut desc = wgpu::InstanceDescriptor::new_without_display_handle();
    desc.backends = wgpu::Backends::from_env().unwrap_or(wgpu::Backends::PRIMARY);
    let instance = wgpu::Instance::new(desc);
    let adapter = pollster::block_on(instance.request_adapter(&Default::default())).context(
        "no GPU adapter found: install a Vulkan driver (e.g. apt-get install mesa-vulkan-drivers libvulkan1)",
    )?;
    let (device, queue) = pollster::block_on(adapter.request_device(&Default::default()))?;
    let info = adapter.get_info();
    eprintln!("adapter: {} ({:?})", info.name, info.backend);

    // 3. Correct and draw in one encoder.
    let rgba8 = render_corrected(&device, &queue, &model, &frame)?;

    // 4. Save, and compare with the CPU reference.
    save_png(&out, frame.width as u32, frame.height as u32, &rgba8)?;
    let cpu = cpu_srgb8(&model, &frame);
    let max_diff = rgba8
        .iter()
        .zip(&cpu)
        .map(|(a, b)| a.abs_diff(*b))
        .max()
        .unwrap_or(0);
    eprintln!(
        "{}×{} chart corrected with {} order {} on the GPU, written to {} \
         (largest difference from the CPU path: {max_diff}/255)",
        frame.width,
        frame.height,
        model.kind(),
        model.order(),
        out.display()
    );
    anyhow::ensure!(
        max_diff <= 1,
        "the GPU picture differs from the CPU path by {max_diff}/255 (at most 1 expected)"
    );
    Ok(())
}

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
            let [r, g, b] = data.rgb.get(i).copied().unwrap_or([0.0; 3]);
            let o = 4 * (y * w + x);
            frame.data[o..o + 4].copy_from_slice(&[r as f32, g as f32, b as f32, 1.0]);
        }
    }
    frame
}

/// The model's XYZ (its white at `Y = white_xyz[1]`) → linear sRGB with the white at 1, the white
/// adapted to D65: the display matrix, on the CPU and in the display shader's uniform.
fn xyz_to_display(model: &Model) -> [[f64; 3]; 3] {
    let white = model.white_xyz();
    OutputSpace::LinearSrgb
        .from_xyz(white)
        .map(|row| row.map(|v| v / white[1]))
}

/// A linear value as an 8-bit sRGB code (IEC 61966-2-1): clipped to `[0, 1]`, encoded, rounded;
/// NaN is 0.
fn srgb8(v: f64) -> u8 {
    let v = if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) };
    let e = if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    };
    (e * 255.0).round() as u8
}

/// The same picture on the CPU: the f64 reference (rounded to f32, as the GPU's XYZ texture
/// holds it), then the display matrix and the sRGB encoding, as RGBA8 (alpha 255).
pub fn cpu_srgb8(model: &Model, frame: &Frame) -> Vec<u8> {
    let m = xyz_to_display(model);
    let ch = frame.layout.channels();
    let mut out = Vec::with_capacity(4 * frame.pixels());
    for px in frame.data.chunks_exact(ch) {
        let xyz = model.apply_f64([px[0], px[1], px[2]].map(f64::from));
        let xyz = xyz.map(|v| f64::from(v as f32));
        let rgb = m.map(|row| row[0] * xyz[0] + row[1] * xyz[1] + row[2] * xyz[2]);
        out.extend(rgb.map(srgb8));
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

/// Uploads an RGBA frame to a new `rgba32float` texture usable as a corrector's source.
pub fn upload_rgba32f(device: &wgpu::Device, queue: &wgpu::Queue, frame: &Frame) -> wgpu::Texture {
    let (w, h) = (frame.width as u32, frame.height as u32);
    device.create_texture_with_data(
        queue,
        &wgpu::TextureDescriptor {
            label: Some("camera RGB"),
            size: extent(w, h),
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::Rgba32Float,
            usage: wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        },
        wgpu::util::TextureDataOrder::LayerMajor,
        bytemuck::cast_slice(&frame.data),
    )
}

/// Uploads `frame` (RGBA) to a texture, records the [`Corrector`] pass (→ an `rgba16float`
/// texture) and the display render pass (→ `rgba8unorm`) into one encoder, submits it, and
/// returns the picture as RGBA8 rows (`width × height × 4` bytes).
// One render pass written out as a renderer would write it, top to bottom: longer than the
// library's 120-line limit on purpose (docs/ARCHITECTURE.md).
#[allow(clippy::too_many_lines)]
pub fn render_corrected(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    model: &Model,
    frame: &Frame,
) -> Result<Vec<u8>> {
    anyhow::ensure!(
        frame.layout == Layout::Rgba && frame.width > 0 && frame.height > 0,
        "the demo draws non-empty RGBA frames"
    );
    let (w, h) = (u32::try_from(frame.width)?, u32::try_from(frame.height)?);

    // The renderer's textures: camera RGB in, corrected XYZ between the passes, 8-bit out.
    let camera_rgb = upload_rgba32f(device, queue, frame);
    let corrected = device.create_texture(&wgpu::TextureDescriptor {
        label: Some("corrected XYZ"),
        size: extent(w, h),
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: CORRECTED_FORMAT.texture_format(),
        // The corrector writes it as a storage texture; the display pass reads it.
        usage: wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::TEXTURE_BINDING,
        view_formats: &[],
    });
    let target = device.create_texture(&wgpu::TextureDescriptor {
        label: Some("display"),
        size: extent(w, h),
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Rgba8Unorm,
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
        view_formats: &[],
    });

    // nsrm's part: one pipeline and one uniform for the model.
    let corrector = Corrector::new(
        device,
        model,
        Target::Texture {
            format: CORRECTED_FORMAT,
        },
    )?;

    // The display pass: the XYZ → linear sRGB rows as a uniform, the corrected texture bound
    // for `textureLoad`, a full-screen triangle.
    let rows: Vec<[f32; 4]> = xyz_to_display(model)
        .iter()
        .map(|r| [r[0] as f32, r[1] as f32, r[2] as f32, 0.0])
        .collect();
    let uniform = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("display matrix"),
        contents: bytemuck::cast_slice(&rows),
        usage: wgpu::BufferUsages::UNIFORM,
    });
    let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("display"),
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
        label: Some("display"),
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
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("display"),
        bind_group_layouts: &[Some(&layout)],
        immediate_size: 0,
    });
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("display"),
        source: wgpu::ShaderSource::Wgsl(DISPLAY_WGSL.into()),
    });
    let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("display"),
        layout: Some(&pipeline_layout),
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

    // One encoder, one submit: the correction is recorded like any other pass of the renderer.
    let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
        label: Some("frame"),
    });
    corrector.record_textures(device, &mut encoder, &camera_rgb, &corrected, None)?;
    {
        let view = target.create_view(&Default::default());
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("display"),
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
    // The read-back of the 8-bit target, in the same submit (rows padded to 256 bytes).
    let row = 4 * w;
    let padded =
        row.div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
    let readback = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("display read-back"),
        size: u64::from(padded) * u64::from(h),
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    encoder.copy_texture_to_buffer(
        target.as_image_copy(),
        wgpu::TexelCopyBufferInfo {
            buffer: &readback,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(padded),
                rows_per_image: Some(h),
            },
        },
        extent(w, h),
    );
    let submission = queue.submit([encoder.finish()]);

    let (tx, rx) = std::sync::mpsc::channel();
    readback.map_async(wgpu::MapMode::Read, .., move |r| {
        let _ = tx.send(r);
    });
    device.poll(wgpu::PollType::Wait {
        submission_index: Some(submission),
        timeout: None,
    })?;
    rx.recv()??;
    let view = readback.get_mapped_range(..)?;
    let mut out = Vec::with_capacity((row * h) as usize);
    for y in 0..h as usize {
        let start = y * padded as usize;
        out.extend_from_slice(&view[start..start + row as usize]);
    }
    Ok(out)
}

/// Writes RGBA8 rows as a PNG.
pub fn save_png(path: &Path, width: u32, height: u32, rgba8: &[u8]) -> Result<()> {
    let img = image::RgbaImage::from_raw(width, height, rgba8.to_vec())
        .context("the picture's size does not match its pixels")?;
    img.save_with_format(path, image::ImageFormat::Png)
        .with_context(|| format!("writing {}", path.display()))
}
