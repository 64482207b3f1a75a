//! `nsrm bench`: per-pixel throughput of the apply paths, as a fraction of a memcpy of the same
//! bytes measured in the same run.
//!
//! * CPU (`cpu-1`: one thread; `cpu-all`: rayon's global pool): the fast path
//!   ([`FastModel::apply_into`]) from the input frame into a separate, pre-faulted output frame.
//!   Its reference is a memcpy of the same bytes into a separate pre-faulted buffer, done the same
//!   way (`copy_from_slice` over the same 64 Ki-pixel chunks, one thread for `cpu-1`, the pool for
//!   `cpu-all`). Kernel and memcpy repetitions alternate, so both see the same machine state; the
//!   ratio is median / median.
//! * GPU: [`nsrm::gpu::Engine::timed_apply`] — kernel time from timestamp queries (when the adapter has
//!   them) and end-to-end time including upload and read-back. Its reference is the device's own
//!   buffer-to-buffer copy of the frame's bytes ([`nsrm::gpu::Engine::copy_bandwidth`]).

use super::bench_aids::{memcpy_chunked, synthetic_camera_rgb};
use super::common::{parse_models, UsageError};
use super::values;
use anyhow::{Context, Result};
use clap::ValueEnum;
use nsrm::gpu::{DeviceChoice, GpuOptions, Opened};
use nsrm::{fit, Kind, Model};
use nsrm::{simulate_named, Grid};
use nsrm::{FastModel, Threads, CHUNK_PIXELS};
use nsrm::{Frame, Layout};
use rayon::prelude::*;
use serde::Serialize;
use std::process::ExitCode;
use std::time::Instant;

#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Frame size, WIDTHxHEIGHT. The default (8.4 Mpixel, 100 MB of RGB f32 each way) is much
    /// larger than the caches and keeps the whole run (lavapipe included) under a minute.
    #[arg(long, default_value = "4096x2048", value_name = "WxH")]
    size: String,
    #[command(flatten)]
    layout: values::LayoutArg,
    /// Model kinds to time, comma-separated (`--models` is the old spelling).
    #[arg(
        long,
        alias = "models",
        default_value = "lrm,prm,rprm,nsrm",
        value_name = "LIST"
    )]
    kinds: String,
    /// Order of PRM, RPRM and NSRM (LRM is always linear).
    #[arg(long, default_value_t = 3)]
    order: u8,
    /// Where to run: `cpu` (one thread and all threads), `gpu` (the GPU only, any adapter),
    /// `auto` (the CPU, and the GPU that `apply --device auto` would choose: a hardware one) or
    /// `all` (the CPU and any GPU adapter, software ones included).
    #[arg(long, value_enum, ignore_case = true, default_value_t = DeviceArg::Auto)]
    device: DeviceArg,
    /// Timed repetitions per CPU measurement, after one warm-up; the median is reported.
    #[arg(long, default_value_t = 7, value_name = "N")]
    reps: usize,
    /// Timed repetitions per GPU measurement; default the smaller of --reps and 3 (a software
    /// adapter such as lavapipe is slow).
    #[arg(long, value_name = "N")]
    gpu_reps: Option<usize>,
    /// Print one JSON object instead of the table.
    #[arg(long)]
    json: bool,
}

/// `apply --device`'s values, plus `all`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum DeviceArg {
    Auto,
    Gpu,
    Cpu,
    All,
}

/// One measured (model, device).
#[derive(Debug, Clone, Serialize)]
struct Row {
    /// `LRM`, `PRM3`, … (the table's label).
    #[serde(skip)]
    label: String,
    model: &'static str,
    order: u8,
    device: &'static str,
    /// CPU: the fast path; GPU: kernel only (timestamps), else end-to-end.
    mpix_s: f64,
    /// `mpix_s` over the memcpy reference in Mpixel/s (`null`: the GPU copy could not be timed).
    ratio_to_memcpy: Option<f64>,
    /// The reference itself (same bytes, same threads / device), in Mpixel/s.
    memcpy_mpix_s: Option<f64>,
    /// GPU: upload + compute + read-back.
    #[serde(skip_serializing_if = "Option::is_none")]
    end_to_end_mpix_s: Option<f64>,
    /// GPU: whether `mpix_s` is kernel-only (`timestamps`) or end-to-end (`none`).
    #[serde(skip_serializing_if = "Option::is_none")]
    kernel_timing: Option<&'static str>,
}

#[derive(Debug, Serialize)]
struct Report {
    size: [usize; 2],
    layout: &'static str,
    /// Multi-threaded memcpy of the frame's bytes (the cpu-all reference), Mpixel/s.
    memcpy_mpix_s: f64,
    /// Single-threaded memcpy (the cpu-1 reference), Mpixel/s.
    memcpy_1t_mpix_s: f64,
    /// One single `copy_from_slice` of the whole frame (glibc may use streaming stores), Mpixel/s.
    memcpy_whole_1t_mpix_s: f64,
    memcpy_method: &'static str,
    threads: usize,
    reps: usize,
    gpu_reps: usize,
    adapter: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    gpu_error: Option<String>,
    /// Whether the GPU's kernel times come from timestamp queries (the table says so).
    #[serde(skip)]
    gpu_timestamps: bool,
    /// The GPU's buffer copy of the frame's bytes, Mpixel/s.
    gpu_copy_mpix_s: Option<f64>,
    results: Vec<Row>,
    /// NSRM throughput / RPRM throughput per device (> 1: NSRM is cheaper).
    nsrm_over_rprm: serde_json::Map<String, serde_json::Value>,
}

const MEMCPY_METHOD: &str = "copy_from_slice of the same bytes into a separate pre-faulted buffer, \
    in the fast path's 64 Ki-pixel chunks (one thread / rayon pool); repetitions alternate with the kernel's";

/// What `nsrm bench` will measure, checked from its flags before anything runs.
#[derive(Debug, Clone)]
struct Plan {
    width: usize,
    height: usize,
    layout: Layout,
    kinds: Vec<Kind>,
    order: u8,
    reps: usize,
    gpu_reps: usize,
    cpu: bool,
    /// The GPU to time, by `apply --device`'s policy; `None`: no GPU.
    gpu: Option<DeviceChoice>,
}

/// The flags as a [`Plan`] (usage errors for sizes, orders and repetition counts out of range).
fn plan(a: &Args) -> Result<Plan> {
    let (width, height) = parse_size(&a.size)?;
    let kinds = parse_models(&a.kinds)?;
    if !(1..=4).contains(&a.order) {
        return Err(UsageError(format!("--order {} is out of range (1..4)", a.order)).into());
    }
    if a.reps == 0 || a.gpu_reps == Some(0) {
        return Err(UsageError("--reps and --gpu-reps must be at least 1".into()).into());
    }
    let (cpu, gpu) = match a.device {
        DeviceArg::Cpu => (true, None),
        DeviceArg::Gpu => (false, Some(DeviceChoice::Gpu)),
        DeviceArg::Auto => (true, Some(DeviceChoice::Auto)),
        DeviceArg::All => (true, Some(DeviceChoice::Gpu)),
    };
    Ok(Plan {
        width,
        height,
        layout: a.layout.layout,
        kinds,
        order: a.order,
        reps: a.reps,
        gpu_reps: a.gpu_reps.unwrap_or(a.reps.min(3)),
        cpu,
        gpu,
    })
}

/// `nsrm bench`: plan → measure → report (the table, or one JSON object).
pub(crate) fn run(a: Args) -> Result<ExitCode> {
    let plan = plan(&a)?;
    let report = measure(&plan)?;
    if a.json {
        println!("{}", serde_json::to_string(&report)?);
    } else {
        print!("{}", table(&plan, &report));
    }
    Ok(ExitCode::SUCCESS)
}

/// Runs the plan: the memcpy references, the fast CPU path ([`measure_cpu`]) and the GPU
/// engine ([`measure_gpu`]; an engine that cannot start is recorded in the report, not an
/// error), then the NSRM/RPRM ratios ([`nsrm_over_rprm`]).
fn measure(plan: &Plan) -> Result<Report> {
    let (width, height, layout, reps) = (plan.width, plan.height, plan.layout, plan.reps);
    let threads = rayon::current_num_threads();
    let pixels = width * height;
    let ch = layout.channels();

    let models = fit_models(&plan.kinds, plan.order)?;
    let input = synthetic_camera_rgb(width, height, layout, 0x5eed_0005);
    let mut output = Frame::new(width, height, layout);
    prefault(&mut output.data);

    // The plain memcpy figures (also when only the GPU is timed: they frame the numbers).
    let mut memcpy = MemcpyTimes {
        all: time_reps(reps, || {
            memcpy_chunked(&input.data, &mut output.data, CHUNK_PIXELS * ch, true)
        }),
        one: time_reps(reps, || {
            memcpy_chunked(&input.data, &mut output.data, CHUNK_PIXELS * ch, false)
        }),
    };
    let whole = median(&time_reps(reps, || {
        output.data.copy_from_slice(&input.data)
    }));

    let mut results = Vec::new();
    if plan.cpu {
        results = measure_cpu(&models, &input, &mut output, reps, &mut memcpy)?;
    }
    let gpu = match plan.gpu {
        Some(choice) => measure_gpu(choice, plan.gpu_reps, &models, &input)?,
        None => GpuRun::default(),
    };
    results.extend(gpu.rows);
    let nsrm_over_rprm = nsrm_over_rprm(&results);
    Ok(Report {
        size: [width, height],
        layout: layout.name(),
        memcpy_mpix_s: mpix(pixels, median(&memcpy.all)),
        memcpy_1t_mpix_s: mpix(pixels, median(&memcpy.one)),
        memcpy_whole_1t_mpix_s: mpix(pixels, whole),
        memcpy_method: MEMCPY_METHOD,
        threads,
        reps,
        gpu_reps: plan.gpu_reps,
        adapter: gpu.adapter,
        gpu_error: gpu.error,
        gpu_timestamps: gpu.timestamps,
        gpu_copy_mpix_s: gpu.copy,
        results,
        nsrm_over_rprm,
    })
}

/// Mpixel/s of `pixels` done in `secs`.
fn mpix(pixels: usize, secs: f64) -> f64 {
    pixels as f64 / secs / 1e6
}

/// The memcpy repetitions' times, all threads and one (the CPU rows add theirs).
struct MemcpyTimes {
    all: Vec<f64>,
    one: Vec<f64>,
}

/// The fast CPU path of each model, one thread and all, from `input` into `output`: after a
/// warm-up, `reps` kernel repetitions each after a memcpy of the same bytes by the same threads
/// (added to `memcpy`); the row's ratio is median over median.
fn measure_cpu(
    models: &[Model],
    input: &Frame,
    output: &mut Frame,
    reps: usize,
    memcpy: &mut MemcpyTimes,
) -> Result<Vec<Row>> {
    let pixels = input.pixels();
    let ch = input.layout.channels();
    let mut results = Vec::new();
    for model in models {
        let fast = FastModel::new(model);
        for (device, th) in [("cpu-1", Threads::Single), ("cpu-all", Threads::All)] {
            let mut k_times = Vec::with_capacity(reps);
            let mut m_times = Vec::with_capacity(reps);
            fast.apply_into(input, output, th)?; // warm-up
            for _ in 0..reps {
                m_times.push(time(|| {
                    memcpy_chunked(
                        &input.data,
                        &mut output.data,
                        CHUNK_PIXELS * ch,
                        th == Threads::All,
                    )
                }));
                let t = Instant::now();
                fast.apply_into(input, output, th)?;
                k_times.push(t.elapsed().as_secs_f64());
            }
            match th {
                Threads::Single => memcpy.one.extend(&m_times),
                Threads::All => memcpy.all.extend(&m_times),
            }
            let (k, m) = (
                mpix(pixels, median(&k_times)),
                mpix(pixels, median(&m_times)),
            );
            results.push(Row {
                label: label(model),
                model: model.kind().name(),
                order: model.order(),
                device,
                mpix_s: k,
                ratio_to_memcpy: Some(k / m),
                memcpy_mpix_s: Some(m),
                end_to_end_mpix_s: None,
                kernel_timing: None,
            });
        }
    }
    Ok(results)
}

/// What the GPU part of a run found: its rows, the adapter (or why none was timed), its copy
/// bandwidth (Mpixel/s) and whether kernel times came from timestamps.
#[derive(Default)]
struct GpuRun {
    rows: Vec<Row>,
    adapter: Option<String>,
    error: Option<String>,
    copy: Option<f64>,
    timestamps: bool,
}

/// The GPU engine `choice` opens, if any: its buffer copy of the frame's bytes, then per model
/// `gpu_reps` timed corrections of `input` after one warm-up (kernel time from timestamps when
/// every repetition has one, else end-to-end).
fn measure_gpu(
    choice: DeviceChoice,
    gpu_reps: usize,
    models: &[Model],
    input: &Frame,
) -> Result<GpuRun> {
    let mut engine = match nsrm::gpu::open_device(choice, &GpuOptions::default()) {
        Err(e) => {
            return Ok(GpuRun {
                error: Some(e.to_string()),
                ..GpuRun::default()
            })
        }
        Ok(Opened::Cpu(why)) => {
            return Ok(GpuRun {
                error: Some(format!("not timed (--device auto): {why}")),
                ..GpuRun::default()
            })
        }
        Ok(Opened::Gpu(engine)) => engine,
    };
    let pixels = input.pixels();
    let bpp = 4 * input.layout.channels();
    let name = engine.adapter_name();
    let timestamps = engine.has_timestamps();
    let copy = engine
        .copy_bandwidth((pixels * bpp) as u64)
        .context("timing the GPU buffer copy")?
        .map(|bytes_s| bytes_s / bpp as f64 / 1e6);
    let mut work = input.clone();
    let mut rows = Vec::new();
    for model in models {
        let mut kernel = Vec::new();
        let mut total = Vec::new();
        for rep in 0..=gpu_reps {
            // Every repetition corrects the same input (the engine works in place).
            work.data.copy_from_slice(&input.data);
            let t = engine
                .timed_apply(model, &mut work)
                .with_context(|| format!("{} on the GPU", label(model)))?;
            if rep > 0 {
                total.push(t.total_seconds);
                if let Some(k) = t.kernel_seconds {
                    kernel.push(k);
                }
            }
        }
        let e2e = mpix(pixels, median(&total));
        let (k, timing) = if kernel.len() == total.len() {
            (mpix(pixels, median(&kernel)), "timestamps")
        } else {
            (e2e, "none")
        };
        rows.push(Row {
            label: label(model),
            model: model.kind().name(),
            order: model.order(),
            device: "gpu",
            mpix_s: k,
            ratio_to_memcpy: copy.map(|c| k / c),
            memcpy_mpix_s: copy,
            end_to_end_mpix_s: Some(e2e),
            kernel_timing: Some(timing),
        });
    }
    Ok(GpuRun {
        rows,
        adapter: Some(name),
        error: None,
        copy,
        timestamps,
    })
}

/// NSRM's throughput over RPRM's per device where both were timed (> 1: NSRM is cheaper).
fn nsrm_over_rprm(results: &[Row]) -> serde_json::Map<String, serde_json::Value> {
    let mut ratio = serde_json::Map::new();
    let find = |kind: Kind, device: &str| {
        results
            .iter()
            .find(|r| r.model == kind.name() && r.device == device)
            .map(|r| r.mpix_s)
    };
    for device in ["cpu-1", "cpu-all", "gpu"] {
        if let (Some(n), Some(r)) = (find(Kind::Nsrm, device), find(Kind::Rprm, device)) {
            ratio.insert(device.into(), serde_json::json!(n / r));
        }
    }
    ratio
}

/// The report as the table `nsrm bench` prints.
fn table(plan: &Plan, r: &Report) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let mut say = |line: String| {
        let _ = writeln!(s, "{line}");
    };
    let [width, height] = r.size;
    let pixels = width * height;
    let bpp = 4 * plan.layout.channels();
    say(format!(
        "nsrm bench: {width}×{height} {} f32 ({:.2} Mpixel, {:.1} MB in + {:.1} MB out), {} threads, \
         median of {} CPU / {} GPU repetitions after a warm-up",
        r.layout,
        pixels as f64 / 1e6,
        (pixels * bpp) as f64 / 1e6,
        (pixels * bpp) as f64 / 1e6,
        r.threads,
        r.reps,
        r.gpu_reps,
    ));
    say(format!("memcpy reference: {}.", r.memcpy_method));
    if plan.cpu {
        say(String::new());
        say(format!(
            "{:<8} {:<8} {:>10} {:>9} {:>16}",
            "model", "device", "Mpixel/s", "× memcpy", "memcpy Mpixel/s"
        ));
        for row in r.results.iter().filter(|row| row.device != "gpu") {
            say(format!(
                "{:<8} {:<8} {:>10.1} {:>9.2} {:>16.1}",
                row.label,
                row.device,
                row.mpix_s,
                row.ratio_to_memcpy.unwrap_or(f64::NAN),
                row.memcpy_mpix_s.unwrap_or(f64::NAN)
            ));
        }
    }
    if plan.gpu.is_some() {
        say(String::new());
        match (&r.adapter, &r.gpu_error) {
            (None, Some(e)) if e.starts_with("not timed") => say(format!("GPU: {e}")),
            (None, Some(e)) => say(format!("GPU: unavailable ({e})")),
            (Some(name), _) => {
                say(format!(
                    "GPU: {name}; kernel time {}; reference: its buffer copy of the frame's bytes, {}",
                    if r.gpu_timestamps {
                        "from timestamp queries"
                    } else {
                        "NOT available (no timestamp queries): Mpixel/s is end-to-end"
                    },
                    match r.gpu_copy_mpix_s {
                        Some(c) => format!("{c:.1} Mpixel/s ({:.2} GB/s)", c * bpp as f64 / 1e3),
                        None => "not measurable (no timestamp queries)".into(),
                    }
                ));
                say(format!(
                    "{:<8} {:<8} {:>10} {:>9} {:>16}",
                    "model", "device", "Mpixel/s", "× copy", "end-to-end Mp/s"
                ));
                for row in r.results.iter().filter(|row| row.device == "gpu") {
                    say(format!(
                        "{:<8} {:<8} {:>10.1} {:>9} {:>16.1}",
                        row.label,
                        "gpu",
                        row.mpix_s,
                        row.ratio_to_memcpy
                            .map_or("n/a".into(), |x| format!("{x:.2}")),
                        row.end_to_end_mpix_s.unwrap_or(f64::NAN)
                    ));
                }
            }
            (None, None) => {}
        }
    }
    say(String::new());
    say(format!(
        "memcpy: {:.1} Mpixel/s on 1 thread (the cpu-1 reference), {:.1} on {} \
         threads (the cpu-all reference), {:.1} as one whole-frame copy_from_slice on 1 thread; \
         × memcpy above uses the copies interleaved with each row's repetitions",
        r.memcpy_1t_mpix_s, r.memcpy_mpix_s, r.threads, r.memcpy_whole_1t_mpix_s
    ));
    if !r.nsrm_over_rprm.is_empty() {
        say(format!(
            "\nNSRM/RPRM cost ratio (NSRM {o} throughput / RPRM {o} throughput; > 1: NSRM is cheaper).",
            o = plan.order
        ));
        if plan.order == 3 {
            say("The paper: NSRM 29 add, 40 mul, 2 div vs RPRM 36 add, 56 mul, 3 sqrt, 7 cbrt per pixel (this \
                 RPRM kernel takes 3 sqrt + 3 cbrt: per-channel roots)."
                .into());
        }
        for (device, v) in &r.nsrm_over_rprm {
            let v = v.as_f64().unwrap_or(f64::NAN);
            let memory_bound = r
                .results
                .iter()
                .filter(|x| x.device == device && (x.model == "nsrm" || x.model == "rprm"))
                .all(|x| x.ratio_to_memcpy.is_some_and(|x| x > 0.85));
            let verdict = if v > 1.05 {
                "NSRM cheaper: the paper's claim holds here"
            } else if v >= 0.95 {
                if memory_bound {
                    "a tie: both run at memory speed, the arithmetic is hidden"
                } else {
                    "a tie within noise"
                }
            } else {
                "RPRM faster here: the claim does not hold on this device"
            };
            say(format!("  {device:<8} {v:.2}  {verdict}"));
        }
    }
    s
}

/// `LRM`, `PRM3`, …
fn label(m: &Model) -> String {
    if m.kind() == Kind::Lrm {
        "LRM".into()
    } else {
        format!("{}{}", m.kind(), m.order())
    }
}

/// `WxH` (or `W×H`), both at least 1.
fn parse_size(spec: &str) -> Result<(usize, usize)> {
    let bad = || {
        UsageError(format!(
            "--size `{spec}`: expected WIDTHxHEIGHT, e.g. 6000x4000"
        ))
    };
    let (w, h) = spec.split_once(['x', 'X', '×']).ok_or_else(bad)?;
    let w: usize = w.trim().parse().map_err(|_| bad())?;
    let h: usize = h.trim().parse().map_err(|_| bad())?;
    if w == 0 || h == 0 {
        return Err(bad().into());
    }
    // The bench holds several f32 RGBA copies of the frame: bound it like a frame read.
    let limit = nsrm_io::DEFAULT_MAX_PIXELS;
    if (w as u64).checked_mul(h as u64).is_none_or(|p| p > limit) {
        return Err(UsageError(format!(
            "--size `{spec}`: {w}×{h} is more than the limit of {limit} pixels (16384×16384)"
        ))
        .into());
    }
    Ok((w, h))
}

/// The models, fitted on built-in simulated data (Nikon D5100, D65, rawtoaces-190).
fn fit_models(kinds: &[Kind], order: u8) -> Result<Vec<Model>> {
    let data = simulate_named("nikon-d5100", "D65", "rawtoaces-190", &Grid::default())
        .context("simulating the training data")?;
    kinds
        .iter()
        .map(|&k| fit(k, order, &data).with_context(|| format!("fitting {k}")))
        .collect()
}

/// Writes every page so that no timing includes page faults.
fn prefault(data: &mut [f32]) {
    data.par_iter_mut().for_each(|v| *v = 1.0);
}

fn time(f: impl FnOnce()) -> f64 {
    let t = Instant::now();
    f();
    t.elapsed().as_secs_f64()
}

/// One warm-up, then `reps` timed runs.
fn time_reps(reps: usize, mut f: impl FnMut()) -> Vec<f64> {
    f();
    (0..reps).map(|_| time(&mut f)).collect()
}

fn median(v: &[f64]) -> f64 {
    let mut v = v.to_vec();
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n == 0 {
        f64::NAN
    } else if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Debug, Parser)]
    struct Cli {
        #[command(flatten)]
        args: Args,
    }

    fn args(extra: &[&str]) -> Args {
        Cli::try_parse_from(std::iter::once("bench").chain(extra.iter().copied()))
            .unwrap()
            .args
    }

    #[test]
    fn plan_checks_the_flags() {
        let p = plan(&args(&[
            "--size",
            "64x32",
            "--device",
            "cpu",
            "--models",
            "nsrm,rprm",
        ]))
        .unwrap();
        assert_eq!((p.width, p.height, p.cpu, p.gpu), (64, 32, true, None));
        assert_eq!(p.kinds, [Kind::Nsrm, Kind::Rprm]);
        assert_eq!(p.gpu_reps, 3);
        for bad in [&["--size", "0x3"][..], &["--order", "5"], &["--reps", "0"]] {
            let e = plan(&args(bad)).unwrap_err();
            assert!(e.downcast_ref::<UsageError>().is_some(), "{bad:?}: {e}");
        }
    }

    #[test]
    fn measure_and_report_a_small_cpu_run() {
        let p = plan(&args(&[
            "--size",
            "97x13",
            "--device",
            "cpu",
            "--kinds",
            "lrm,rprm,nsrm",
            "--reps",
            "1",
        ]))
        .unwrap();
        let r = measure(&p).unwrap();
        assert_eq!(r.results.len(), 6, "three models × cpu-1, cpu-all");
        assert!(r
            .results
            .iter()
            .all(|x| x.mpix_s > 0.0 && x.ratio_to_memcpy.is_some()));
        assert_eq!(r.nsrm_over_rprm.len(), 2);
        let t = table(&p, &r);
        assert!(t.starts_with("nsrm bench: 97×13 rgb f32"), "{t}");
        for needle in [
            "NSRM3    cpu-1",
            "RPRM3    cpu-all",
            "LRM      cpu-1",
            "NSRM/RPRM cost ratio",
        ] {
            assert!(t.contains(needle), "{needle}: {t}");
        }
        assert!(!t.contains("GPU:"), "{t}");
        let json: serde_json::Value = serde_json::to_value(&r).unwrap();
        assert_eq!(json["size"], serde_json::json!([97, 13]));
        assert!(json["results"][0].get("label").is_none());
        assert!(json.get("gpu_timestamps").is_none());
    }

    #[test]
    fn the_cost_ratio_pairs_nsrm_and_rprm_on_one_device() {
        let row = |model: &'static str, device: &'static str, mpix_s: f64| Row {
            label: model.into(),
            model,
            order: 3,
            device,
            mpix_s,
            ratio_to_memcpy: None,
            memcpy_mpix_s: None,
            end_to_end_mpix_s: None,
            kernel_timing: None,
        };
        let rows = [
            row(Kind::Nsrm.name(), "cpu-1", 30.0),
            row(Kind::Rprm.name(), "cpu-1", 20.0),
            row(Kind::Nsrm.name(), "gpu", 500.0),
            row(Kind::Rprm.name(), "cpu-all", 80.0),
        ];
        let r = nsrm_over_rprm(&rows);
        assert_eq!(r.len(), 1, "{r:?}");
        assert_eq!(r["cpu-1"], serde_json::json!(1.5));
        assert_eq!(mpix(2_000_000, 0.5), 4.0);
    }
}
