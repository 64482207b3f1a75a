//! Embedding nsrm's colour correction in a wgpu renderer.
//!
//! The renderer owns the device and the command encoder; nsrm's [`Corrector`] only records a
//! compute pass into it. This example
//! 1. simulates a ColorChecker 24 seen by a Nikon D5100 under D65 and fits NSRM (order 3),
//! 2. opens its own wgpu device (as any renderer would),
//! 3. uploads the chart (camera RGB) to an `rgba32float` texture, records the [`Corrector`]
//!    pass (→ `rgba16float` XYZ) and a small render pass that draws the corrected texture as
//!    sRGB (XYZ → linear sRGB → sRGB encoding in the fragment shader) to an offscreen target,
//!    all in one encoder and one submit ([`nsrm::gpu::demo::render_corrected`]),
//! 4. reads the target back, saves it as PNG and compares it with the f64 CPU path (exit status 1
//!    if any byte differs by more than 1/255; CI runs this example).
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
use nsrm::gpu::demo;
use nsrm::model::{fit, Kind};
use nsrm::spectral::{simulate_named, Grid};
use std::path::PathBuf;

fn main() -> Result<()> {
    let out = std::env::args_os()
        .nth(1)
        .map(PathBuf::from)
        .unwrap_or_else(|| std::env::temp_dir().join("nsrm-embed.png"));

    // 1. The chart and the model.
    let data = simulate_named("nikon-d5100", "D65", "cc24", &Grid::default())?;
    let model = fit(Kind::Nsrm, 3, &data)?;
    let frame = demo::chart_frame(&data, 6, 48);

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
    let rgba8 = demo::render_corrected(&device, &queue, &model, &frame)?;

    // 4. Save, and compare with the CPU reference.
    demo::save_png(&out, frame.width as u32, frame.height as u32, &rgba8)?;
    let cpu = demo::cpu_srgb8(&model, &frame);
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
