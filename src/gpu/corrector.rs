//! [`Corrector`]: one model's compute pipeline and matrix uniform, recording into a caller's
//! command encoder on the caller's buffers or textures.

use super::shader::{
    self, Coefficients, Target, TexelFormat, ROW_GROUPS, TILE_SIZE, WORKGROUP_SIZE,
};
use super::GpuError;
use crate::model::{Kind, Model};
use wgpu::util::DeviceExt;

/// The compute pipeline and matrix uniform of one model kind and order for one [`Target`].
///
/// It never creates a device or submits: [`record_buffers`](Self::record_buffers),
/// [`record_in_place`](Self::record_in_place) and [`record_textures`](Self::record_textures)
/// add a compute pass to the caller's [`wgpu::CommandEncoder`]. [`set_model`](Self::set_model)
/// swaps the matrix of a model of the same kind and order at run time (it writes the uniform
/// through the queue, so it takes effect at the next submit).
///
/// Bindings (group 0): 0 the matrix uniform; buffers: 1 `src` (read-only storage, or the
/// in-place buffer), 2 `dst` (storage); textures: 1 `src` (`texture_2d<f32>`, any float
/// format, read with `textureLoad`), 2 `dst` (write-only `rgba32float` / `rgba16float` storage
/// texture). Write-only storage is what WebGPU guarantees for both formats; read-write
/// `rgba16float` is adapter-specific, so textures are never corrected in place.
///
/// ```no_run
/// use nsrm::gpu::{Corrector, GpuContext, GpuOptions, Target};
/// use nsrm::Layout;
/// # fn main() -> Result<(), Box<dyn std::error::Error>> {
/// # let model: nsrm::Model = unimplemented!();
/// let ctx = GpuContext::new(&GpuOptions::default())?;
/// let corrector = Corrector::new(
///     &ctx.device,
///     &model,
///     Target::Buffer { layout: Layout::Rgba, in_place: true },
/// )?;
/// let pixels = ctx.device.create_buffer(&wgpu::BufferDescriptor {
///     label: Some("frame"),
///     size: 1920 * 1080 * 16,
///     usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
///     mapped_at_creation: false,
/// });
/// let mut encoder = ctx.device.create_command_encoder(&Default::default());
/// corrector.record_in_place(&ctx.device, &mut encoder, pixels.slice(..), None)?;
/// ctx.queue.submit([encoder.finish()]);
/// # Ok(()) }
/// ```
#[derive(Debug)]
pub struct Corrector {
    kind: Kind,
    order: u8,
    target: Target,
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    uniform: wgpu::Buffer,
    max_binding: u64,
    offset_alignment: u64,
    max_groups: u32,
}

/// Runs `f` inside a validation and an out-of-memory error scope; a captured error becomes
/// [`GpuError::Wgpu`] instead of reaching the device's uncaptured-error handler (a panic).
pub(crate) fn scoped<T>(device: &wgpu::Device, f: impl FnOnce() -> T) -> Result<T, GpuError> {
    let oom = device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
    let val = device.push_error_scope(wgpu::ErrorFilter::Validation);
    let out = f();
    let v = pollster::block_on(val.pop());
    let o = pollster::block_on(oom.pop());
    match v.or(o) {
        Some(e) => Err(GpuError::Wgpu(e.to_string())),
        None => Ok(out),
    }
}

impl Corrector {
    /// Builds the pipeline for `model`'s kind and order on `target` and uploads its matrix.
    pub fn new(
        device: &wgpu::Device,
        model: &Model,
        target: Target,
    ) -> Result<Corrector, GpuError> {
        let (kind, order) = (model.kind(), model.order());
        let src = shader::wgsl(kind, order, target, Coefficients::Uniform);
        Corrector::build(
            device,
            (kind, order),
            &src,
            &shader::uniform_data(model),
            target,
        )
    }

    /// A corrector for any well-formed pixel program, a kind's or not (the printer's numeric
    /// tests): `matrix` is 3×L row-major over the program's terms, `gains` its input gains. Its
    /// order is 0, so [`set_model`](Self::set_model) refuses every model.
    #[cfg(test)]
    pub(crate) fn for_program(
        device: &wgpu::Device,
        program: &crate::model::pixel::Program<'_>,
        matrix: &[f64],
        gains: [f64; 3],
        target: Target,
    ) -> Result<Corrector, GpuError> {
        let src = shader::wgsl_program(program, 0, target, Coefficients::Uniform);
        let uniform = shader::uniform_data_of(matrix, program.terms.len(), gains);
        Corrector::build(device, (program.kind, 0), &src, &uniform, target)
    }

    /// The pipeline of the WGSL `src` (for `kind` at `order`) on `target`, its uniform holding
    /// `uniform` ([`shader::uniform_data`]'s layout).
    fn build(
        device: &wgpu::Device,
        (kind, order): (Kind, u8),
        src: &str,
        uniform: &[[f32; 4]],
        target: Target,
    ) -> Result<Corrector, GpuError> {
        shader::validate(src)?;
        let limits = device.limits();
        let label = format!("nsrm {kind} {order} {target:?}");
        let uniform_bytes = 16 * uniform.len() as u64;
        let storage = |read_only| wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only },
            has_dynamic_offset: false,
            min_binding_size: None,
        };
        let mut entries = vec![wgpu::BindGroupLayoutEntry {
            binding: 0,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Uniform,
                has_dynamic_offset: false,
                min_binding_size: std::num::NonZeroU64::new(uniform_bytes),
            },
            count: None,
        }];
        let entry = |binding, ty| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty,
            count: None,
        };
        match target {
            Target::Buffer { in_place: true, .. } => entries.push(entry(1, storage(false))),
            Target::Buffer {
                in_place: false, ..
            } => {
                entries.push(entry(1, storage(true)));
                entries.push(entry(2, storage(false)));
            }
            Target::Texture { format } => {
                entries.push(entry(
                    1,
                    wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: false },
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                ));
                entries.push(entry(
                    2,
                    wgpu::BindingType::StorageTexture {
                        access: wgpu::StorageTextureAccess::WriteOnly,
                        format: format.texture_format(),
                        view_dimension: wgpu::TextureViewDimension::D2,
                    },
                ));
            }
        }
        let (pipeline, layout, uniform) = scoped(device, || {
            let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some(&label),
                entries: &entries,
            });
            let pl = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some(&label),
                bind_group_layouts: &[Some(&layout)],
                immediate_size: 0,
            });
            let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some(&label),
                source: wgpu::ShaderSource::Wgsl(src.into()),
            });
            let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(&label),
                layout: Some(&pl),
                module: &module,
                entry_point: Some(shader::ENTRY_POINT),
                compilation_options: Default::default(),
                cache: None,
            });
            let uniform = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("nsrm model matrix"),
                contents: bytemuck::cast_slice(uniform),
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            });
            (pipeline, layout, uniform)
        })?;
        Ok(Corrector {
            kind,
            order,
            target,
            pipeline,
            layout,
            uniform,
            max_binding: limits.max_storage_buffer_binding_size,
            offset_alignment: limits.min_storage_buffer_offset_alignment as u64,
            max_groups: limits.max_compute_workgroups_per_dimension,
        })
    }

    /// Whether [`set_model`](Self::set_model) takes `model` (same kind and order).
    pub(crate) fn accepts(&self, model: &Model) -> bool {
        model.kind() == self.kind && model.order() == self.order
    }

    /// Swaps in the matrix of another model of the same kind and order (written through
    /// `queue`, effective from the next submit). Another kind or order needs a new corrector:
    /// [`GpuError::ModelMismatch`].
    pub fn set_model(&self, queue: &wgpu::Queue, model: &Model) -> Result<(), GpuError> {
        if !self.accepts(model) {
            return Err(GpuError::ModelMismatch {
                expected: format!("{} order {}", self.kind, self.order),
                got: format!("{} order {}", model.kind(), model.order()),
            });
        }
        queue.write_buffer(
            &self.uniform,
            0,
            bytemuck::cast_slice(&shader::uniform_data(model)),
        );
        Ok(())
    }

    fn channels(&self) -> Result<u64, GpuError> {
        match self.target {
            Target::Buffer { layout, .. } => Ok(layout.channels() as u64),
            Target::Texture { .. } => Err(GpuError::Usage(
                "this corrector is for textures: use record_textures".into(),
            )),
        }
    }

    /// The most pixels one binding may hold (a multiple of the step that keeps every chunk's
    /// offset aligned to `min_storage_buffer_offset_alignment`).
    pub(crate) fn max_pixels_per_binding(&self) -> u64 {
        let px = match self.target {
            Target::Buffer { layout, .. } => 4 * layout.channels() as u64,
            Target::Texture { .. } => 16,
        };
        let step = self.offset_alignment / gcd(self.offset_alignment, px);
        // Also keep float indices within u32 and the dispatch within the workgroup limits.
        let by_index = u32::MAX as u64 / (px / 4) - 1;
        let by_groups =
            self.max_groups.min(65535) as u64 * ROW_GROUPS as u64 * WORKGROUP_SIZE as u64;
        let cap = (self.max_binding / px).min(by_index).min(by_groups);
        (cap / step * step).max(step)
    }

    fn check_slice(&self, what: &str, s: &wgpu::BufferSlice<'_>, px: u64) -> Result<(), GpuError> {
        let usage = s.buffer().usage();
        if !usage.contains(wgpu::BufferUsages::STORAGE) {
            return Err(GpuError::Usage(format!(
                "the {what} buffer lacks BufferUsages::STORAGE"
            )));
        }
        if s.offset() % self.offset_alignment != 0 {
            return Err(GpuError::Usage(format!(
                "the {what} slice starts at byte {}, not a multiple of min_storage_buffer_offset_alignment ({})",
                s.offset(),
                self.offset_alignment
            )));
        }
        if s.size() % px != 0 {
            return Err(GpuError::Usage(format!(
                "the {what} slice is {} bytes, not a whole number of {px}-byte pixels",
                s.size()
            )));
        }
        Ok(())
    }

    /// Records the correction of the packed pixels in `src` into `dst` (same size; alpha is
    /// copied). Slices must start at a multiple of `min_storage_buffer_offset_alignment`; any
    /// size is taken (it is split into bindings of at most
    /// `max_pixels_per_binding` pixels, in one compute pass).
    /// `timestamps` go to that pass.
    pub fn record_buffers(
        &self,
        device: &wgpu::Device,
        encoder: &mut wgpu::CommandEncoder,
        src: wgpu::BufferSlice<'_>,
        dst: wgpu::BufferSlice<'_>,
        timestamps: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) -> Result<(), GpuError> {
        if let Target::Buffer { in_place: true, .. } = self.target {
            return Err(GpuError::Usage(
                "this corrector works in place: use record_in_place".into(),
            ));
        }
        let px = 4 * self.channels()?;
        self.check_slice("source", &src, px)?;
        self.check_slice("destination", &dst, px)?;
        if src.size() != dst.size() {
            return Err(GpuError::Usage(format!(
                "source ({} bytes) and destination ({} bytes) differ in size",
                src.size(),
                dst.size()
            )));
        }
        self.record_chunks(device, encoder, src, Some(dst), timestamps)
    }

    /// Records the correction of the packed pixels in `pixels`, in place (alpha untouched).
    /// Same rules as [`record_buffers`](Self::record_buffers).
    pub fn record_in_place(
        &self,
        device: &wgpu::Device,
        encoder: &mut wgpu::CommandEncoder,
        pixels: wgpu::BufferSlice<'_>,
        timestamps: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) -> Result<(), GpuError> {
        if let Target::Buffer {
            in_place: false, ..
        } = self.target
        {
            return Err(GpuError::Usage(
                "this corrector reads and writes separate buffers: use record_buffers".into(),
            ));
        }
        let px = 4 * self.channels()?;
        self.check_slice("pixel", &pixels, px)?;
        self.record_chunks(device, encoder, pixels, None, timestamps)
    }

    fn record_chunks(
        &self,
        device: &wgpu::Device,
        encoder: &mut wgpu::CommandEncoder,
        first: wgpu::BufferSlice<'_>,
        second: Option<wgpu::BufferSlice<'_>>,
        timestamps: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) -> Result<(), GpuError> {
        let px = 4 * self.channels()?;
        let pixels = first.size() / px;
        let chunk = self.max_pixels_per_binding();
        let mut groups = Vec::new();
        let mut start = 0;
        while start < pixels {
            let n = chunk.min(pixels - start);
            let range = start * px..(start + n) * px;
            fn bind<'a>(
                s: &wgpu::BufferSlice<'a>,
                range: std::ops::Range<u64>,
            ) -> wgpu::BindingResource<'a> {
                let part = s.slice(range);
                wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                    buffer: part.buffer(),
                    offset: part.offset(),
                    size: std::num::NonZeroU64::new(part.size()),
                })
            }
            let mut entries = vec![
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: self.uniform.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: bind(&first, range.clone()),
                },
            ];
            if let Some(d) = &second {
                entries.push(wgpu::BindGroupEntry {
                    binding: 2,
                    resource: bind(d, range.clone()),
                });
            }
            let bg = scoped(device, || {
                device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("nsrm frame"),
                    layout: &self.layout,
                    entries: &entries,
                })
            })?;
            groups.push((bg, dispatch_size(n)));
            start += n;
        }
        if groups.is_empty() && timestamps.is_none() {
            return Ok(());
        }
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("nsrm correct"),
            timestamp_writes: timestamps,
        });
        pass.set_pipeline(&self.pipeline);
        for (bg, [x, y]) in &groups {
            pass.set_bind_group(0, bg, &[]);
            pass.dispatch_workgroups(*x, *y, 1);
        }
        Ok(())
    }

    /// Records the correction of texture `src` (any float format with
    /// `TextureUsages::TEXTURE_BINDING`) into `dst` (the corrector's [`TexelFormat`], with
    /// `TextureUsages::STORAGE_BINDING`, same size); alpha is copied.
    pub fn record_textures(
        &self,
        device: &wgpu::Device,
        encoder: &mut wgpu::CommandEncoder,
        src: &wgpu::Texture,
        dst: &wgpu::Texture,
        timestamps: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) -> Result<(), GpuError> {
        let Target::Texture { format } = self.target else {
            return Err(GpuError::Usage(
                "this corrector is for buffers: use record_buffers / record_in_place".into(),
            ));
        };
        if TexelFormat::from_texture_format(dst.format()) != Some(format) {
            return Err(GpuError::Usage(format!(
                "the destination texture is {:?}; this corrector writes {:?}",
                dst.format(),
                format.texture_format()
            )));
        }
        if !dst.usage().contains(wgpu::TextureUsages::STORAGE_BINDING) {
            return Err(GpuError::Usage(
                "the destination texture lacks TextureUsages::STORAGE_BINDING".into(),
            ));
        }
        if !src.usage().contains(wgpu::TextureUsages::TEXTURE_BINDING) {
            return Err(GpuError::Usage(
                "the source texture lacks TextureUsages::TEXTURE_BINDING".into(),
            ));
        }
        let (s, d) = (src.size(), dst.size());
        if (s.width, s.height) != (d.width, d.height) {
            return Err(GpuError::Usage(format!(
                "source {}×{} and destination {}×{} differ in size",
                s.width, s.height, d.width, d.height
            )));
        }
        let view = |t: &wgpu::Texture| {
            t.create_view(&wgpu::TextureViewDescriptor {
                dimension: Some(wgpu::TextureViewDimension::D2),
                mip_level_count: Some(1),
                array_layer_count: Some(1),
                ..Default::default()
            })
        };
        let bg = scoped(device, || {
            let (sv, dv) = (view(src), view(dst));
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("nsrm textures"),
                layout: &self.layout,
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: self.uniform.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: wgpu::BindingResource::TextureView(&sv),
                    },
                    wgpu::BindGroupEntry {
                        binding: 2,
                        resource: wgpu::BindingResource::TextureView(&dv),
                    },
                ],
            })
        })?;
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("nsrm correct texture"),
            timestamp_writes: timestamps,
        });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &bg, &[]);
        pass.dispatch_workgroups(d.width.div_ceil(TILE_SIZE), d.height.div_ceil(TILE_SIZE), 1);
        Ok(())
    }
}

/// The `(x, y)` workgroup counts for `pixels` pixels of a buffer shader: `(G, 1)` when
/// `G = ceil(pixels / WORKGROUP_SIZE) <= ROW_GROUPS`, else `(ROW_GROUPS, ceil(G / ROW_GROUPS))`.
pub(crate) fn dispatch_size(pixels: u64) -> [u32; 2] {
    let g = pixels.div_ceil(WORKGROUP_SIZE as u64);
    if g <= ROW_GROUPS as u64 {
        [g as u32, 1]
    } else {
        [ROW_GROUPS, g.div_ceil(ROW_GROUPS as u64) as u32]
    }
}

fn gcd(a: u64, b: u64) -> u64 {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dispatch_stays_within_limits_and_covers_every_pixel() {
        for n in [
            1u64,
            255,
            256,
            257,
            65_536,
            65_537,
            12_291,
            16_777_216,
            1 << 30,
        ] {
            let [x, y] = dispatch_size(n);
            assert!(x <= 65535 && y <= 65535, "{n}: {x}×{y}");
            assert!(x as u64 * y as u64 * WORKGROUP_SIZE as u64 >= n);
            // No whole row of workgroups is idle.
            assert!((x as u64 * (y as u64 - 1)) * (WORKGROUP_SIZE as u64) < n);
        }
        assert_eq!(dispatch_size(1), [1, 1]);
        assert_eq!(dispatch_size(4097 * 3), [49, 1]);
    }
}
