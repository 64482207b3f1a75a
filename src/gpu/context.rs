//! Instance, adapter and device: backend and adapter selection (see the [module docs](super)).

use super::{GpuError, GpuOptions};

/// An opened adapter with its device and queue.
#[derive(Debug)]
pub struct GpuContext {
    /// The wgpu instance the adapter came from.
    pub instance: wgpu::Instance,
    /// The adapter chosen (see the module docs for how).
    pub adapter: wgpu::Adapter,
    /// The device opened on it, with the adapter's own limits.
    pub device: wgpu::Device,
    /// The device's queue.
    pub queue: wgpu::Queue,
}

/// The backends to look at: `WGPU_BACKEND` if set, else Vulkan / Metal / DX12.
pub(crate) fn backends() -> wgpu::Backends {
    wgpu::Backends::from_env().unwrap_or(wgpu::Backends::PRIMARY)
}

/// `name (Backend, DeviceType)`, e.g. `llvmpipe (LLVM 15.0.6, 256 bits) (Vulkan, Cpu)`.
pub(crate) fn describe(info: &wgpu::AdapterInfo) -> String {
    format!("{} ({:?}, {:?})", info.name, info.backend, info.device_type)
}

impl GpuContext {
    /// Opens the adapter `opts` (or `NSRM_ADAPTER`) names, else the default one, and a device
    /// with the adapter's limits and (where offered) timestamp queries.
    ///
    /// ```no_run
    /// let ctx = nsrm::gpu::GpuContext::new(&nsrm::gpu::GpuOptions::default())?;
    /// println!("{}", ctx.adapter.get_info().name);
    /// # Ok::<(), nsrm::gpu::GpuError>(())
    /// ```
    pub fn new(opts: &GpuOptions) -> Result<GpuContext, GpuError> {
        GpuContext::open(opts, true)
    }

    /// Like [`GpuContext::new`], but without an adapter named (by `opts` or `NSRM_ADAPTER`)
    /// only a hardware adapter is taken: when the default one is a software rasteriser (device
    /// type `Cpu`, e.g. lavapipe) another adapter that is not is looked for, else
    /// [`GpuError::SoftwareOnly`].
    pub(crate) fn new_hardware(opts: &GpuOptions) -> Result<GpuContext, GpuError> {
        GpuContext::open(opts, false)
    }

    fn open(opts: &GpuOptions, software_ok: bool) -> Result<GpuContext, GpuError> {
        let backends = backends();
        let mut desc = wgpu::InstanceDescriptor::new_without_display_handle();
        desc.backends = backends;
        desc.flags = wgpu::InstanceFlags::from_build_config().with_env();
        let instance = wgpu::Instance::new(desc);
        let wanted = opts
            .adapter
            .clone()
            .or_else(|| std::env::var("NSRM_ADAPTER").ok())
            .filter(|s| !s.trim().is_empty());
        let adapter = match wanted {
            Some(w) => {
                let adapters = pollster::block_on(instance.enumerate_adapters(backends));
                if adapters.is_empty() {
                    return Err(GpuError::NoAdapter {
                        detail: format!("backends {backends:?}"),
                    });
                }
                let needle = w.trim().to_lowercase();
                let names: Vec<String> = adapters.iter().map(|a| describe(&a.get_info())).collect();
                match names
                    .iter()
                    .position(|n| n.to_lowercase().contains(&needle))
                {
                    Some(i) => adapters.into_iter().nth(i).expect("index from position"),
                    None => {
                        return Err(GpuError::AdapterNotFound {
                            wanted: w,
                            available: names,
                        })
                    }
                }
            }
            None => pollster::block_on(
                instance.request_adapter(&wgpu::RequestAdapterOptions {
                    power_preference: wgpu::PowerPreference::from_env()
                        .unwrap_or(wgpu::PowerPreference::HighPerformance),
                    force_fallback_adapter: false,
                    compatible_surface: None,
                    apply_limit_buckets: false,
                }),
            )
            .map_err(|e| GpuError::NoAdapter {
                detail: e.to_string(),
            })
            .and_then(|default| {
                if software_ok || default.get_info().device_type != wgpu::DeviceType::Cpu {
                    return Ok(default);
                }
                let software = describe(&default.get_info());
                pollster::block_on(instance.enumerate_adapters(backends))
                    .into_iter()
                    .find(|a| a.get_info().device_type != wgpu::DeviceType::Cpu)
                    .ok_or(GpuError::SoftwareOnly { adapter: software })
            })?,
        };
        let wanted_features =
            wgpu::Features::TIMESTAMP_QUERY | wgpu::Features::TIMESTAMP_QUERY_INSIDE_ENCODERS;
        let (device, queue) =
            pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
                label: Some("nsrm"),
                required_features: adapter.features() & wanted_features,
                required_limits: adapter.limits(),
                ..Default::default()
            }))?;
        Ok(GpuContext {
            instance,
            adapter,
            device,
            queue,
        })
    }

    /// `name (Backend, DeviceType)`, e.g. `llvmpipe (LLVM 15.0.6, 256 bits) (Vulkan, Cpu)`.
    pub(crate) fn adapter_name(&self) -> String {
        describe(&self.adapter.get_info())
    }
}
