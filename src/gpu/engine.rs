//! [`Engine`]: frames of any size corrected on the GPU, streamed through fixed-size tiles.
//!
//! Each tile is uploaded (`queue.write_buffer`), corrected by the [`Corrector`] from an input
//! buffer into an output buffer, copied into a mappable read-back buffer and submitted on its
//! own; the read-back is mapped asynchronously. Two sets of tile buffers alternate, so while the
//! GPU corrects tile `t` the CPU copies tile `t−1` back into the frame and uploads tile `t+1`.
//! Buffers and pipelines are created once and reused: one [`Corrector`] per
//! (kind, order, layout), its matrix rewritten for every frame.

use super::context::GpuContext;
use super::corrector::Corrector;
use super::shader::Target;
use super::{GpuError, GpuOptions};
use crate::frame::{Frame, Layout};
use crate::model::{Kind, Model};
use std::collections::HashMap;
use std::sync::mpsc;
use std::time::Instant;

/// Default pixels per tile (1 Mpixel: 16 MiB per RGBA tile buffer).
pub(crate) const DEFAULT_TILE_PIXELS: usize = 1 << 20;

/// The bit pattern of the quiet NaN the output tiles are filled with before the shader runs, in
/// builds with debug assertions (the tests): a pixel the shader failed to write comes back as
/// exactly this value (the shader itself never produces this payload). Release builds skip the
/// fill.
pub(crate) const OUTPUT_SENTINEL_BITS: u32 = 0x7FC0_BAD5;

/// Timing of one [`Engine::timed_apply`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GpuTiming {
    /// GPU time of the correction passes (sum over tiles) from timestamp queries; `None` if
    /// the adapter has no timestamp queries.
    pub kernel_seconds: Option<f64>,
    /// Wall time of the whole apply: upload, compute and read-back.
    pub total_seconds: f64,
}

struct InFlight {
    /// The tile's float range in the frame.
    floats: std::ops::Range<usize>,
    submission: wgpu::SubmissionIndex,
    mapped: mpsc::Receiver<Result<(), wgpu::BufferAsyncError>>,
    timed: bool,
}

struct Slot {
    input: wgpu::Buffer,
    output: wgpu::Buffer,
    readback: wgpu::Buffer,
    in_flight: Option<InFlight>,
}

struct Timestamps {
    set: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    period_ns: f64,
}

/// Applies models to frames on one GPU device.
///
/// ```
/// use nsrm::gpu::{Engine, GpuError, GpuOptions};
/// use nsrm::{Frame, Kind, Layout, Model};
/// let model = Model::from_matrix(Kind::Lrm, 1, vec![2.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0])?;
/// let mut engine = match Engine::new(&GpuOptions::default()) {
///     Ok(e) => e,
///     Err(GpuError::NoAdapter { .. }) => return Ok(()), // no GPU here: nothing to show
///     Err(e) => return Err(e.into()),
/// };
/// let mut frame = Frame::from_data(1, 1, Layout::Rgba, vec![0.25, 0.5, 0.75, 1.0]).unwrap();
/// engine.apply(&model, &mut frame)?;
/// assert_eq!(frame.data, [0.5, 0.5, 0.75, 1.0]);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub struct Engine {
    ctx: GpuContext,
    tile_pixels: usize,
    correctors: HashMap<(Kind, u8, Layout), Corrector>,
    slots: Vec<Slot>,
    /// Pixels each slot's buffers hold (≤ `tile_pixels`).
    slot_pixels: usize,
    timestamps: Option<Timestamps>,
    poison: bool,
    sentinel: Vec<u8>,
}

impl std::fmt::Debug for Engine {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Engine")
            .field("adapter", &self.adapter_name())
            .field("tile_pixels", &self.tile_pixels)
            .finish_non_exhaustive()
    }
}

impl Engine {
    /// Opens an adapter and device (see [`GpuContext::new`]); [`GpuError::NoAdapter`] names
    /// the driver to install when there is none.
    pub fn new(opts: &GpuOptions) -> Result<Engine, GpuError> {
        Engine::on(GpuContext::new(opts)?, opts)
    }

    /// Like [`Engine::new`], but a software adapter (device type `Cpu`, e.g. Mesa's lavapipe)
    /// is refused with [`GpuError::SoftwareOnly`] unless `opts` or `NSRM_ADAPTER` names it:
    /// the policy of [`DeviceChoice::Auto`](super::DeviceChoice::Auto).
    pub(crate) fn new_hardware(opts: &GpuOptions) -> Result<Engine, GpuError> {
        Engine::on(GpuContext::new_hardware(opts)?, opts)
    }

    fn on(ctx: GpuContext, opts: &GpuOptions) -> Result<Engine, GpuError> {
        let limits = ctx.device.limits();
        // One RGBA tile must fit in a storage binding and a buffer.
        let max_tile = (limits
            .max_storage_buffer_binding_size
            .min(limits.max_buffer_size)
            / 16)
            .min(usize::MAX as u64) as usize;
        let tile_pixels = opts
            .tile_pixels
            .unwrap_or(DEFAULT_TILE_PIXELS)
            .clamp(1, max_tile.max(1));
        let features = ctx.device.features();
        let timestamps = features
            .contains(wgpu::Features::TIMESTAMP_QUERY)
            .then(|| Timestamps {
                set: ctx.device.create_query_set(&wgpu::QuerySetDescriptor {
                    label: Some("nsrm tile timestamps"),
                    ty: wgpu::QueryType::Timestamp,
                    count: 4,
                }),
                resolve: ctx.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("nsrm timestamp resolve"),
                    size: 2 * wgpu::QUERY_RESOLVE_BUFFER_ALIGNMENT,
                    usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                    mapped_at_creation: false,
                }),
                period_ns: ctx.queue.get_timestamp_period() as f64,
            });
        Ok(Engine {
            ctx,
            tile_pixels,
            correctors: HashMap::new(),
            slots: Vec::new(),
            slot_pixels: 0,
            timestamps,
            poison: cfg!(debug_assertions),
            sentinel: Vec::new(),
        })
    }

    /// `name (Backend, DeviceType)`, e.g. `llvmpipe (LLVM 15.0.6, 256 bits) (Vulkan, Cpu)`.
    pub fn adapter_name(&self) -> String {
        self.ctx.adapter_name()
    }

    /// The adapter, device and queue (the unit tests build [`Corrector`]s on them).
    #[cfg(test)]
    pub(crate) fn context(&self) -> &GpuContext {
        &self.ctx
    }

    /// Whether [`timed_apply`](Self::timed_apply) can report kernel time.
    pub fn has_timestamps(&self) -> bool {
        self.timestamps.is_some()
    }

    /// Corrects `frame` in place (alpha untouched) with `model`, following the pixel policy of
    /// `model::pixel` (the README's *Pixel policy*).
    pub fn apply(&mut self, model: &Model, frame: &mut Frame) -> Result<(), GpuError> {
        self.run(model, frame, false).map(|_| ())
    }

    /// [`apply`](Self::apply), timed: kernel time from timestamp queries (if the adapter has
    /// them) and the wall time of upload + compute + read-back.
    pub fn timed_apply(&mut self, model: &Model, frame: &mut Frame) -> Result<GpuTiming, GpuError> {
        self.run(model, frame, true)
    }

    fn run(
        &mut self,
        model: &Model,
        frame: &mut Frame,
        timed: bool,
    ) -> Result<GpuTiming, GpuError> {
        let start = Instant::now();
        let ch = frame.layout.channels();
        let pixels = frame.width.checked_mul(frame.height).ok_or_else(|| {
            GpuError::Usage(format!(
                "frame {}×{} is too large",
                frame.width, frame.height
            ))
        })?;
        if frame.data.len() != pixels * ch {
            return Err(GpuError::Usage(format!(
                "frame {}×{} {} holds {} floats, expected {}",
                frame.width,
                frame.height,
                frame.layout.name(),
                frame.data.len(),
                pixels * ch
            )));
        }
        let timed = timed && self.timestamps.is_some();
        let key = (model.kind(), model.order(), frame.layout);
        if !self.correctors.contains_key(&key) {
            let c = Corrector::new(
                &self.ctx.device,
                model,
                Target::Buffer {
                    layout: frame.layout,
                    in_place: false,
                },
            )?;
            self.correctors.insert(key, c);
        }
        self.correctors[&key].set_model(&self.ctx.queue, model)?;
        if pixels == 0 {
            return Ok(GpuTiming {
                kernel_seconds: timed.then_some(0.0),
                total_seconds: start.elapsed().as_secs_f64(),
            });
        }
        self.ensure_slots(pixels);
        let mut kernel_ns = 0.0;
        let result = self.stream(key, frame, timed, &mut kernel_ns);
        if result.is_err() {
            self.abandon();
        }
        result?;
        Ok(GpuTiming {
            kernel_seconds: timed.then_some(kernel_ns * 1e-9),
            total_seconds: start.elapsed().as_secs_f64(),
        })
    }

    /// Bytes each tile buffer holds (tiles of RGBA pixels).
    fn tile_bytes_capacity(&self) -> u64 {
        self.slot_pixels as u64 * 16
    }

    /// Makes sure both buffer sets hold tiles of `pixels` pixels (at most a full tile): they
    /// are sized for the largest frame seen so far, so a small frame does not allocate a
    /// full tile, and are created once and reused after that.
    fn ensure_slots(&mut self, pixels: usize) {
        let want = pixels.min(self.tile_pixels);
        if !self.slots.is_empty() && self.slot_pixels >= want {
            return;
        }
        self.slots.clear();
        self.slot_pixels = want;
        let cap = self.tile_bytes_capacity();
        let dev = &self.ctx.device;
        for i in 0..2 {
            let buf = |what: &str, size, usage| {
                dev.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(&format!("nsrm tile {i} {what}")),
                    size,
                    usage,
                    mapped_at_creation: false,
                })
            };
            use wgpu::BufferUsages as U;
            self.slots.push(Slot {
                input: buf("input", cap, U::STORAGE | U::COPY_DST),
                output: buf("output", cap, U::STORAGE | U::COPY_DST | U::COPY_SRC),
                // Room for the tile and its two u64 timestamps.
                readback: buf("read-back", cap + 16, U::MAP_READ | U::COPY_DST),
                in_flight: None,
            });
        }
    }

    fn stream(
        &mut self,
        key: (Kind, u8, Layout),
        frame: &mut Frame,
        timed: bool,
        kernel_ns: &mut f64,
    ) -> Result<(), GpuError> {
        let ch = frame.layout.channels();
        let pixels = frame.pixels();
        let tiles = pixels.div_ceil(self.tile_pixels);
        let cap = self.tile_bytes_capacity();
        for t in 0..tiles {
            let s = t % 2;
            self.finish(s, frame, kernel_ns)?;
            let first = t * self.tile_pixels;
            let last = (first + self.tile_pixels).min(pixels);
            let floats = first * ch..last * ch;
            let bytes = (floats.len() * 4) as u64;
            let dev = &self.ctx.device;
            let queue = &self.ctx.queue;
            let slot = &self.slots[s];
            queue.write_buffer(
                &slot.input,
                0,
                bytemuck::cast_slice(&frame.data[floats.clone()]),
            );
            if self.poison {
                if self.sentinel.len() < bytes as usize {
                    self.sentinel = OUTPUT_SENTINEL_BITS
                        .to_ne_bytes()
                        .repeat(self.slot_pixels * 4);
                }
                queue.write_buffer(&slot.output, 0, &self.sentinel[..bytes as usize]);
            }
            let mut enc = dev.create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("nsrm tile"),
            });
            let ts = self.timestamps.as_ref().filter(|_| timed);
            let writes = ts.map(|ts| wgpu::ComputePassTimestampWrites {
                query_set: &ts.set,
                beginning_of_pass_write_index: Some(2 * s as u32),
                end_of_pass_write_index: Some(2 * s as u32 + 1),
            });
            self.correctors[&key].record_buffers(
                dev,
                &mut enc,
                slot.input.slice(..bytes),
                slot.output.slice(..bytes),
                writes,
            )?;
            enc.copy_buffer_to_buffer(&slot.output, 0, &slot.readback, 0, bytes);
            if let Some(ts) = ts {
                let at = s as u64 * wgpu::QUERY_RESOLVE_BUFFER_ALIGNMENT;
                enc.resolve_query_set(&ts.set, 2 * s as u32..2 * s as u32 + 2, &ts.resolve, at);
                enc.copy_buffer_to_buffer(&ts.resolve, at, &slot.readback, cap, 16);
            }
            let submission = queue.submit([enc.finish()]);
            let (tx, rx) = mpsc::channel();
            slot.readback.map_async(wgpu::MapMode::Read, .., move |r| {
                let _ = tx.send(r);
            });
            self.slots[s].in_flight = Some(InFlight {
                floats,
                submission,
                mapped: rx,
                timed: ts.is_some(),
            });
            // Let finished work call back without blocking.
            let _ = self.ctx.device.poll(wgpu::PollType::Poll);
        }
        // The older tile first.
        for s in [tiles % 2, (tiles + 1) % 2] {
            self.finish(s, frame, kernel_ns)?;
        }
        Ok(())
    }

    /// Waits for slot `s`'s tile, copies it into `frame` and unmaps the read-back buffer.
    fn finish(&mut self, s: usize, frame: &mut Frame, kernel_ns: &mut f64) -> Result<(), GpuError> {
        let Some(job) = self.slots[s].in_flight.take() else {
            return Ok(());
        };
        let slot = &self.slots[s];
        wait_mapped(&self.ctx.device, &job)?;
        // Mapped from here on: unmap whatever the copy does.
        let copied = (|| -> Result<(), GpuError> {
            let view = slot.readback.get_mapped_range(..)?;
            let n = job.floats.len() * 4;
            let dst = &mut frame.data[job.floats.clone()];
            match bytemuck::try_cast_slice::<u8, f32>(&view[..n]) {
                Ok(src) => dst.copy_from_slice(src),
                Err(_) => {
                    for (d, b) in dst.iter_mut().zip(view[..n].chunks_exact(4)) {
                        *d = f32::from_ne_bytes([b[0], b[1], b[2], b[3]]);
                    }
                }
            }
            if job.timed {
                let cap = self.tile_bytes_capacity() as usize;
                let q = |i: usize| {
                    let b = &view[cap + 8 * i..cap + 8 * i + 8];
                    u64::from_ne_bytes(b.try_into().expect("8 bytes"))
                };
                let ticks = q(1).saturating_sub(q(0));
                *kernel_ns += ticks as f64 * self.timestamps.as_ref().map_or(1.0, |t| t.period_ns);
            }
            Ok(())
        })();
        slot.readback.unmap();
        copied
    }

    /// After an error: waits for every tile in flight and unmaps, copying nothing.
    fn abandon(&mut self) {
        for slot in &mut self.slots {
            if let Some(job) = slot.in_flight.take() {
                if wait_mapped(&self.ctx.device, &job).is_ok() {
                    slot.readback.unmap();
                }
            }
        }
    }

    /// Bytes per second of a `bytes`-byte buffer-to-buffer copy on the device, timed with
    /// timestamp queries (best of three after a warm-up); `None` if the device cannot write
    /// timestamps between commands. `bytes` is capped at the device's buffer size limit.
    pub fn copy_bandwidth(&mut self, bytes: u64) -> Result<Option<f64>, GpuError> {
        let dev = &self.ctx.device;
        let needed =
            wgpu::Features::TIMESTAMP_QUERY | wgpu::Features::TIMESTAMP_QUERY_INSIDE_ENCODERS;
        if !dev.features().contains(needed) {
            return Ok(None);
        }
        let bytes = bytes.min(dev.limits().max_buffer_size) / 4 * 4;
        if bytes == 0 {
            return Err(GpuError::Usage(
                "copy_bandwidth needs at least 4 bytes".into(),
            ));
        }
        let period_ns = self.ctx.queue.get_timestamp_period() as f64;
        let (src, dst, set, resolve, readback) = super::corrector::scoped(dev, || {
            let buf = |label, size, usage| {
                dev.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(label),
                    size,
                    usage,
                    mapped_at_creation: false,
                })
            };
            use wgpu::BufferUsages as U;
            (
                buf("nsrm copy source", bytes, U::COPY_SRC),
                buf("nsrm copy destination", bytes, U::COPY_DST),
                dev.create_query_set(&wgpu::QuerySetDescriptor {
                    label: Some("nsrm copy timestamps"),
                    ty: wgpu::QueryType::Timestamp,
                    count: 2,
                }),
                buf("nsrm copy resolve", 16, U::QUERY_RESOLVE | U::COPY_SRC),
                buf("nsrm copy read-back", 16, U::MAP_READ | U::COPY_DST),
            )
        })?;
        let mut best: Option<f64> = None;
        for run in 0..4 {
            let mut enc = dev.create_command_encoder(&Default::default());
            enc.write_timestamp(&set, 0);
            enc.copy_buffer_to_buffer(&src, 0, &dst, 0, bytes);
            enc.write_timestamp(&set, 1);
            enc.resolve_query_set(&set, 0..2, &resolve, 0);
            enc.copy_buffer_to_buffer(&resolve, 0, &readback, 0, 16);
            let submission = self.ctx.queue.submit([enc.finish()]);
            let (tx, rx) = mpsc::channel();
            readback.map_async(wgpu::MapMode::Read, .., move |r| {
                let _ = tx.send(r);
            });
            wait_map(dev, &submission, &rx)?;
            let ticks = {
                let view = readback.get_mapped_range(..)?;
                let q = |i: usize| u64::from_ne_bytes(view[8 * i..8 * i + 8].try_into().unwrap());
                q(1).saturating_sub(q(0))
            };
            readback.unmap();
            let secs = ticks as f64 * period_ns * 1e-9;
            if run > 0 && secs > 0.0 {
                let bw = bytes as f64 / secs;
                best = Some(best.map_or(bw, |b: f64| b.max(bw)));
            }
        }
        Ok(best)
    }
}

/// Waits until `job`'s read-back buffer is mapped (or its mapping failed).
fn wait_mapped(device: &wgpu::Device, job: &InFlight) -> Result<(), GpuError> {
    wait_map(device, &job.submission, &job.mapped)
}

/// Waits for `submission`, then for the map callback reporting on `mapped`.
fn wait_map(
    device: &wgpu::Device,
    submission: &wgpu::SubmissionIndex,
    mapped: &mpsc::Receiver<Result<(), wgpu::BufferAsyncError>>,
) -> Result<(), GpuError> {
    let mut poll = wgpu::PollType::Wait {
        submission_index: Some(submission.clone()),
        timeout: None,
    };
    for _ in 0..3 {
        device.poll(poll)?;
        match mapped.try_recv() {
            Ok(r) => return Ok(r?),
            Err(mpsc::TryRecvError::Disconnected) => break,
            // The callback runs once the map is processed: wait for everything submitted.
            Err(mpsc::TryRecvError::Empty) => poll = wgpu::PollType::wait_indefinitely(),
        }
    }
    Err(GpuError::Wgpu(
        "the read-back buffer was never mapped".into(),
    ))
}
