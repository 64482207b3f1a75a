//! The GPU path against the f64 CPU reference (`Model::apply_f64` on every pixel: the test kit's
//! `apply_reference`). (Moved from `tests/all/gpu.rs`: it reads the engine's crate-private
//! unwritten-output sentinel.)
//!
//! Without an adapter these tests print `SKIP: no GPU adapter ...` and pass, unless `CI=true`,
//! where they fail with the driver message.
//!
//! Tolerance per value: `|gpu − ref| ≤ 1e-5 · max(|ref|, floor)`, where the floor for output
//! channel `i` of a pixel is the magnitude of its summands, `floor_i = |s| · Σ_j |M_ij · p_j|`
//! (`p` the pixel's terms, `s` NSRM's scale or 1; computed in f64), and at least 1e-30. Where
//! nothing cancels, `floor_i = |ref_i|` and the test is a plain relative error; where the terms
//! cancel to near 0 (e.g. Z of a saturated red), f32 summation cannot do better than the
//! rounding of the summands, and that is what the floor allows. A NaN reference needs a NaN;
//! an infinite reference needs a non-finite value (Inf of the same sign, or NaN); alpha must
//! come back bit for bit; no value may be the engine's unwritten-output sentinel.

use crate::gpu::{self, Corrector, Engine, GpuError, GpuOptions, Target, TexelFormat};
use crate::{fit, Kind, Model, MAX_ORDER};
use crate::{fit_with, FitOptions, Normalise};
use crate::{Frame, Layout};

/// The embedding example, for its functions (chart → Corrector pass → display pass → RGBA8).
#[path = "../../examples/embed.rs"]
#[allow(dead_code, unreachable_pub)]
mod embed;

const SKIP: &str = "no GPU adapter (install mesa-vulkan-drivers libvulkan1)";
const REL_TOL: f64 = 1e-5;

/// The engine, or `None` (after one loud line) when there is no adapter; with `CI=true` a
/// missing adapter fails the test.
pub(super) fn engine(tile_pixels: Option<usize>) -> Option<Engine> {
    let opts = GpuOptions {
        adapter: None,
        tile_pixels,
    };
    match Engine::new(&opts) {
        // Debug builds (the tests) fill every output tile with the sentinel NaN first.
        Ok(e) => Some(e),
        Err(e @ GpuError::NoAdapter { .. }) => {
            crate::kit::skip_or_fail(&format!("{SKIP}: {e}"));
            None
        }
        Err(e) => panic!("cannot open the GPU engine: {e}"),
    }
}

use crate::kit as common;
use common::{awkward_frame as random_frame, f32_bound, summands, training, Rng};

fn model(kind: Kind, order: u8) -> Model {
    fit(kind, order, training()).unwrap()
}

/// White-balanced NSRM (non-unit input gains) at `order`.
fn white_balanced(order: u8) -> Model {
    let opts = FitOptions {
        normalise: Normalise::WhiteBalanced,
        ..Default::default()
    };
    let m = fit_with(Kind::Nsrm, order, training(), &opts)
        .unwrap()
        .model;
    assert_ne!(m.input_gains(), [1.0; 3]);
    m
}

/// Checks `gpu` against `reference` (see the module docs); returns the largest error
/// `|gpu − ref| / max(|ref|, floor)` over finite values, and the largest plain relative error
/// `|gpu − ref| / |ref|` over values with `|ref| ≥ floor / 10` (no strong cancellation).
fn compare_stats(
    what: &str,
    model: &Model,
    input: &Frame,
    gpu: &Frame,
    reference: &Frame,
    rel_tol: f64,
) -> (f64, f64) {
    let ch = input.layout.channels();
    let mut worst = 0.0f64;
    let mut worst_plain = 0.0f64;
    for (i, ((g, r), x)) in gpu
        .data
        .chunks_exact(ch)
        .zip(reference.data.chunks_exact(ch))
        .zip(input.data.chunks_exact(ch))
        .enumerate()
    {
        let floor = summands(model, [x[0] as f64, x[1] as f64, x[2] as f64]).map(|t| t.max(1e-30));
        for k in 0..ch {
            let (gv, rv) = (g[k], r[k]);
            let at = || {
                format!("{what}: pixel {i} channel {k}: input {x:?}, gpu {g:?}, reference {r:?}")
            };
            assert_ne!(
                gv.to_bits(),
                gpu::engine::OUTPUT_SENTINEL_BITS,
                "{}: not written",
                at()
            );
            if k == 3 {
                assert_eq!(gv.to_bits(), x[3].to_bits(), "{}: alpha changed", at());
                continue;
            }
            if rv.is_nan() {
                assert!(gv.is_nan(), "{}: NaN expected", at());
            } else if rv.is_infinite() {
                assert!(
                    gv.is_nan() || gv == rv,
                    "{}: non-finite value expected",
                    at()
                );
            } else {
                assert!(gv.is_finite(), "{}: finite value expected", at());
                let diff = (gv as f64 - rv as f64).abs();
                assert!(
                    diff <= f32_bound(rv as f64, floor[k], rel_tol),
                    "{}: relative error {:e}",
                    at(),
                    diff / (rv as f64).abs().max(floor[k])
                );
                let err = diff / (rv as f64).abs().max(floor[k]);
                worst = worst.max(err);
                if (rv as f64).abs() >= floor[k] / 10.0 {
                    worst_plain = worst_plain.max(diff / (rv as f64).abs());
                }
            }
        }
    }
    (worst, worst_plain)
}

fn compare(
    what: &str,
    model: &Model,
    input: &Frame,
    gpu: &Frame,
    reference: &Frame,
    rel_tol: f64,
) -> f64 {
    compare_stats(what, model, input, gpu, reference, rel_tol).0
}

fn check_kind(kind: Kind) {
    check_models(kind, |order| model(kind, order));
}

fn check_models(kind: Kind, model: impl Fn(u8) -> Model) {
    let Some(mut big_tiles) = engine(None) else {
        return;
    };
    let Some(mut small_tiles) = engine(Some(1000)) else {
        return;
    };
    let orders = if kind == Kind::Lrm {
        1..=1
    } else {
        1..=MAX_ORDER
    };
    for order in orders {
        let m = model(order);
        let wb = if m.input_gains() == [1.0; 3] {
            ""
        } else {
            " white-balanced"
        };
        let (mut worst, mut worst_plain) = (0.0f64, 0.0f64);
        for layout in [Layout::Rgb, Layout::Rgba] {
            for (i, (w, h)) in [(1, 1), (7, 13), (4097, 3), (100, 37)]
                .into_iter()
                .enumerate()
            {
                let input = random_frame(w, h, layout, 1000 * order as u64 + i as u64);
                let mut reference = input.clone();
                common::apply_reference(&m, &mut reference);
                let mut out = input.clone();
                let engine = if w * h > 1000 {
                    &mut small_tiles
                } else {
                    &mut big_tiles
                };
                engine.apply(&m, &mut out).unwrap();
                let what = format!("{kind} order {order}{wb} {layout:?} {w}×{h}");
                let (w, p) = compare_stats(&what, &m, &input, &out, &reference, REL_TOL);
                worst = worst.max(w);
                worst_plain = worst_plain.max(p);
            }
        }
        eprintln!(
            "{kind} order {order}{wb}: GPU vs f64: max error (floored) {worst:.2e}, max plain relative error {worst_plain:.2e}"
        );
    }
}

#[test]
fn lrm_matches_the_f64_reference() {
    check_kind(Kind::Lrm);
}

#[test]
fn prm_matches_the_f64_reference_every_order() {
    check_kind(Kind::Prm);
}

#[test]
fn rprm_matches_the_f64_reference_every_order() {
    check_kind(Kind::Rprm);
}

#[test]
fn nsrm_matches_the_f64_reference_every_order() {
    check_kind(Kind::Nsrm);
}

#[test]
fn white_balanced_nsrm_matches_the_f64_reference_every_order() {
    check_models(Kind::Nsrm, white_balanced);
}

#[test]
fn gains_swap_with_the_model() {
    // One corrector (NSRM 3 on RGBA) takes raw, white-balanced, raw: the uniform's gains follow.
    let Some(mut e) = engine(Some(500)) else {
        return;
    };
    let raw = model(Kind::Nsrm, 3);
    let wb = white_balanced(3);
    for (round, m) in [&raw, &wb, &raw, &wb].into_iter().enumerate() {
        let input = random_frame(33, 40, Layout::Rgba, 90 + round as u64);
        let mut reference = input.clone();
        common::apply_reference(m, &mut reference);
        let mut out = input.clone();
        e.apply(m, &mut out).unwrap();
        compare(
            &format!("gain swap round {round}"),
            m,
            &input,
            &out,
            &reference,
            REL_TOL,
        );
    }
}

#[test]
fn frames_larger_than_one_dispatch_row_and_many_tiles() {
    let Some(mut e) = engine(None) else { return };
    // 120 000 pixels: 469 workgroups, dispatched as 256 × 2.
    let m = model(Kind::Nsrm, 2);
    let input = random_frame(400, 300, Layout::Rgb, 7);
    let mut reference = input.clone();
    common::apply_reference(&m, &mut reference);
    let mut out = input.clone();
    e.apply(&m, &mut out).unwrap();
    compare("NSRM 2 400×300", &m, &input, &out, &reference, REL_TOL);
    // The same frame through 7-pixel tiles (17 143 tiles, both buffer sets cycling).
    let Some(mut tiny) = engine(Some(7)) else {
        return;
    };
    let input = random_frame(97, 61, Layout::Rgba, 8);
    let mut reference = input.clone();
    common::apply_reference(&m, &mut reference);
    let mut out = input.clone();
    tiny.apply(&m, &mut out).unwrap();
    compare(
        "NSRM 2 97×61 in 7-pixel tiles",
        &m,
        &input,
        &out,
        &reference,
        REL_TOL,
    );
}

#[test]
fn models_swap_and_pipelines_are_reused() {
    let Some(mut e) = engine(Some(500)) else {
        return;
    };
    let a = model(Kind::Rprm, 3);
    let mut b = a.clone();
    b.set_matrix(
        a.matrix()
            .iter()
            .enumerate()
            .map(|(i, v)| v * (1.0 + 0.01 * i as f64))
            .collect(),
    )
    .unwrap();
    for (round, m) in [&a, &b, &a].into_iter().enumerate() {
        let input = random_frame(33, 40, Layout::Rgba, 50 + round as u64);
        let mut reference = input.clone();
        common::apply_reference(m, &mut reference);
        let mut out = input.clone();
        e.apply(m, &mut out).unwrap();
        compare(
            &format!("swap round {round}"),
            m,
            &input,
            &out,
            &reference,
            REL_TOL,
        );
    }
    // Empty frames are fine.
    let mut empty = Frame::new(0, 5, Layout::Rgb);
    e.apply(&a, &mut empty).unwrap();
    // A frame whose data does not match its size is refused, not read out of bounds.
    let mut bad = Frame::new(2, 2, Layout::Rgb);
    bad.data.pop();
    assert!(matches!(e.apply(&a, &mut bad), Err(GpuError::Usage(_))));
}

#[test]
fn exposure_invariance_on_the_gpu() {
    let Some(mut e) = engine(None) else { return };
    let mut rng = Rng(99);
    let data: Vec<f32> = (0..3 * 2000).map(|_| rng.range(0.01, 1.0)).collect();
    let base = Frame::from_data(50, 40, Layout::Rgb, data).unwrap();
    for kind in [Kind::Nsrm, Kind::Rprm, Kind::Lrm] {
        let m = model(kind, 3);
        let mut out = base.clone();
        e.apply(&m, &mut out).unwrap();
        for k in [0.01f32, 0.37, 8.0, 100.0] {
            let mut scaled = base.clone();
            scaled.data.iter_mut().for_each(|v| *v *= k);
            let scaled_input = scaled.clone();
            e.apply(&m, &mut scaled).unwrap();
            let want = Frame {
                data: out.data.iter().map(|v| v * k).collect(),
                ..out.clone()
            };
            // Both sides carry f32 rounding (k·S is rounded before the model sees it).
            let worst = compare(
                &format!("{kind} exposure ×{k}"),
                &m,
                &scaled_input,
                &scaled,
                &want,
                2e-5,
            );
            eprintln!("{kind} exposure ×{k}: max relative deviation {worst:.2e}");
        }
    }
}

/// Runs a corrector on the caller's own encoder and buffers, in place and src → dst, with a
/// chunk smaller than the whole buffer (offsets into the middle of a buffer).
#[test]
fn corrector_records_into_the_callers_encoder_on_buffers() {
    let Some(e) = engine(None) else { return };
    let ctx = e.context();
    let (dev, queue) = (&ctx.device, &ctx.queue);
    let m = model(Kind::Nsrm, 3);
    for layout in [Layout::Rgb, Layout::Rgba] {
        let input = random_frame(64, 10, layout, 11);
        let mut reference = input.clone();
        common::apply_reference(&m, &mut reference);
        let bytes: &[u8] = bytemuck::cast_slice(&input.data);
        let size = bytes.len() as u64;
        use wgpu::BufferUsages as U;
        let make = |usage| {
            dev.create_buffer(&wgpu::BufferDescriptor {
                label: None,
                size,
                usage,
                mapped_at_creation: false,
            })
        };
        let a = make(U::STORAGE | U::COPY_DST | U::COPY_SRC);
        let b = make(U::STORAGE | U::COPY_SRC);
        queue.write_buffer(&a, 0, bytes);
        let sep = Corrector::new(
            dev,
            &m,
            Target::Buffer {
                layout,
                in_place: false,
            },
        )
        .unwrap();
        let inplace = Corrector::new(
            dev,
            &m,
            Target::Buffer {
                layout,
                in_place: true,
            },
        )
        .unwrap();
        let mut enc = dev.create_command_encoder(&Default::default());
        sep.record_buffers(dev, &mut enc, a.slice(..), b.slice(..), None)
            .unwrap();
        // In place on the second half (an aligned offset: 320 pixels × 12 or 16 bytes).
        let half = size / 2;
        inplace
            .record_in_place(dev, &mut enc, a.slice(half..), None)
            .unwrap();
        queue.submit([enc.finish()]);
        let out_b = read_buffer(dev, queue, &b);
        let out_a = read_buffer(dev, queue, &a);
        let sep_frame = Frame::from_data(64, 10, layout, out_b).unwrap();
        compare(
            "corrector src→dst",
            &m,
            &input,
            &sep_frame,
            &reference,
            REL_TOL,
        );
        let n = out_a.len() / 2;
        let bits = |d: &[f32]| d.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        assert!(
            bits(&out_a[..n]) == bits(&input.data[..n]),
            "the first half is untouched"
        );
        let second = |d: &[f32]| Frame::from_data(64, 5, layout, d[n..].to_vec()).unwrap();
        compare(
            "corrector in place",
            &m,
            &second(&input.data),
            &second(&out_a),
            &second(&reference.data),
            REL_TOL,
        );
        // Misuse is an error, not a panic.
        let mut enc = dev.create_command_encoder(&Default::default());
        let odd = sep.record_buffers(dev, &mut enc, a.slice(4..), b.slice(4..), None);
        assert!(matches!(odd, Err(GpuError::Usage(_))), "{odd:?}");
        assert!(inplace
            .record_buffers(dev, &mut enc, a.slice(..), b.slice(..), None)
            .is_err());
    }
    // Swapping in a model of another kind is refused.
    let c = Corrector::new(
        dev,
        &m,
        Target::Buffer {
            layout: Layout::Rgb,
            in_place: true,
        },
    )
    .unwrap();
    let err = c.set_model(queue, &model(Kind::Rprm, 3)).unwrap_err();
    assert!(matches!(err, GpuError::ModelMismatch { .. }), "{err}");
    c.set_model(queue, &model(Kind::Nsrm, 3)).unwrap();
}

#[test]
fn corrector_on_textures() {
    let Some(e) = engine(None) else { return };
    let ctx = e.context();
    let (dev, queue) = (&ctx.device, &ctx.queue);
    let m = model(Kind::Rprm, 2);
    let (w, h) = (37u32, 21u32);
    let input = random_frame(w as usize, h as usize, Layout::Rgba, 21);
    let mut reference = input.clone();
    common::apply_reference(&m, &mut reference);
    let src = embed::upload_rgba32f(dev, queue, &input);
    for (format, tol) in [
        (TexelFormat::Rgba32Float, REL_TOL),
        (TexelFormat::Rgba16Float, 1e-3),
    ] {
        let dst = dev.create_texture(&wgpu::TextureDescriptor {
            label: None,
            size: wgpu::Extent3d {
                width: w,
                height: h,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: format.texture_format(),
            usage: wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        let c = Corrector::new(dev, &m, Target::Texture { format }).unwrap();
        let mut enc = dev.create_command_encoder(&Default::default());
        c.record_textures(dev, &mut enc, &src, &dst, None).unwrap();
        queue.submit([enc.finish()]);
        let out = read_texture_rgba_f32(dev, queue, &dst);
        let got = Frame::from_data(w as usize, h as usize, Layout::Rgba, out).unwrap();
        if format == TexelFormat::Rgba32Float {
            compare("texture rgba32float", &m, &input, &got, &reference, tol);
        } else {
            // Half floats: compare finite, in-range values; alpha goes through f16 too.
            let mut worst = 0.0f64;
            for (g, r) in got.data.chunks_exact(4).zip(reference.data.chunks_exact(4)) {
                for k in 0..3 {
                    let rv = r[k] as f64;
                    if rv.is_finite() && rv.abs() < 60000.0 && rv.abs() > 1e-3 {
                        let err = (g[k] as f64 - rv).abs() / rv.abs();
                        assert!(err <= tol, "rgba16float {g:?} vs {r:?}");
                        worst = worst.max(err);
                    } else if rv.is_nan() {
                        assert!(g[k].is_nan());
                    }
                }
            }
            eprintln!("rgba16float output: max relative error {worst:.2e}");
        }
    }
}

/// An `rgba32float` or `rgba16float` texture (with `COPY_SRC`) read back as RGBA f32.
fn read_texture_rgba_f32(dev: &wgpu::Device, queue: &wgpu::Queue, tex: &wgpu::Texture) -> Vec<f32> {
    let bpp = tex.format().block_copy_size(None).unwrap();
    let (w, h) = (tex.width(), tex.height());
    let row = bpp * w;
    let padded =
        row.div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
    let rb = dev.create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size: u64::from(padded) * u64::from(h),
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut enc = dev.create_command_encoder(&Default::default());
    enc.copy_texture_to_buffer(
        tex.as_image_copy(),
        wgpu::TexelCopyBufferInfo {
            buffer: &rb,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(padded),
                rows_per_image: Some(h),
            },
        },
        tex.size(),
    );
    queue.submit([enc.finish()]);
    rb.map_async(wgpu::MapMode::Read, .., |r| r.unwrap());
    dev.poll(wgpu::PollType::wait_indefinitely()).unwrap();
    let bytes: Vec<u8> = {
        let view = rb.get_mapped_range(..).unwrap();
        (0..h as usize)
            .flat_map(|y| &view[y * padded as usize..y * padded as usize + row as usize])
            .copied()
            .collect()
    };
    match tex.format() {
        wgpu::TextureFormat::Rgba32Float => bytemuck::pod_collect_to_vec(&bytes),
        wgpu::TextureFormat::Rgba16Float => bytes
            .chunks_exact(2)
            .map(|b| half::f16::from_ne_bytes([b[0], b[1]]).to_f32())
            .collect(),
        f => panic!("{f:?} is not a float RGBA format"),
    }
}

/// The display shader of the embedding example validates and has its two entry points.
#[test]
fn embed_display_shader_validates() {
    let module = naga::front::wgsl::parse_str(embed::DISPLAY_WGSL).unwrap();
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::default(),
    )
    .validate(&module)
    .unwrap();
    let names: Vec<_> = module
        .entry_points
        .iter()
        .map(|e| e.name.as_str())
        .collect();
    assert_eq!(names, ["vs_main", "fs_main"]);
}

/// The embedding example (`examples/embed.rs`, the same functions): chart → texture → Corrector
/// pass → display render pass → PNG, against the f64 CPU path (±1 of 255 per channel: the
/// corrected texture is half float and the GPU's unorm conversion rounds on its own).
#[test]
fn embed_demo_png_matches_the_cpu_path() {
    let Some(e) = engine(None) else { return };
    let ctx = e.context();
    let data = crate::kit::simulated("D65", "cc24");
    let m = fit(Kind::Nsrm, 3, &data).unwrap();
    let frame = embed::chart_frame(&data, 6, 8);
    assert_eq!((frame.width, frame.height), (48, 32));
    let rgba8 = embed::render_corrected(&ctx.device, &ctx.queue, &m, &frame).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("embed.png");
    embed::save_png(&path, 48, 32, &rgba8).unwrap();
    let png = image::open(&path).unwrap().to_rgba8();
    assert_eq!(png.dimensions(), (48, 32));
    assert_eq!(png.as_raw(), &rgba8);
    let cpu = embed::cpu_srgb8(&m, &frame);
    let mut exact = 0;
    for (i, (g, c)) in png.as_raw().iter().zip(&cpu).enumerate() {
        assert!(g.abs_diff(*c) <= 1, "byte {i}: GPU {g}, CPU {c}");
        exact += (g == c) as usize;
    }
    // Not a flat picture: the 24 patches differ.
    let mut colours: Vec<&[u8]> = png.as_raw().chunks_exact(4).collect();
    colours.sort();
    colours.dedup();
    assert!(colours.len() >= 20, "{} distinct colours", colours.len());
    eprintln!(
        "embed demo: {exact} of {} bytes equal to the CPU path, the rest within 1",
        cpu.len()
    );
}

/// An exported (baked, uniform-free) WGSL shader runs as-is and matches the reference.
#[test]
fn exported_wgsl_runs_and_matches_the_reference() {
    let Some(e) = engine(None) else { return };
    let ctx = e.context();
    let (dev, queue) = (&ctx.device, &ctx.queue);
    for (kind, order, layout, wb) in [
        (Kind::Nsrm, 4, Layout::Rgba, false),
        (Kind::Nsrm, 3, Layout::Rgb, true),
        (Kind::Rprm, 3, Layout::Rgb, false),
        (Kind::Prm, 2, Layout::Rgba, false),
    ] {
        let m = if wb {
            white_balanced(order)
        } else {
            model(kind, order)
        };
        let src = gpu::baked_wgsl(&m, layout);
        let input = random_frame(300, 5, layout, 77);
        let mut reference = input.clone();
        common::apply_reference(&m, &mut reference);
        let buf = dev.create_buffer(&wgpu::BufferDescriptor {
            label: None,
            size: (input.data.len() * 4) as u64,
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_DST
                | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        queue.write_buffer(&buf, 0, bytemuck::cast_slice(&input.data));
        let module = dev.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: None,
            source: wgpu::ShaderSource::Wgsl(src.into()),
        });
        let pipeline = dev.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: None,
            layout: None,
            module: &module,
            entry_point: Some("main"),
            compilation_options: Default::default(),
            cache: None,
        });
        let bg = dev.create_bind_group(&wgpu::BindGroupDescriptor {
            label: None,
            layout: &pipeline.get_bind_group_layout(0),
            entries: &[wgpu::BindGroupEntry {
                binding: 1,
                resource: buf.as_entire_binding(),
            }],
        });
        let mut enc = dev.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_pipeline(&pipeline);
            pass.set_bind_group(0, &bg, &[]);
            // 1500 pixels: 6 workgroups of 256.
            pass.dispatch_workgroups(6, 1, 1);
        }
        queue.submit([enc.finish()]);
        let out = Frame::from_data(300, 5, layout, read_buffer(dev, queue, &buf)).unwrap();
        compare(
            &format!("exported {kind} {order} white-balanced {wb}"),
            &m,
            &input,
            &out,
            &reference,
            REL_TOL,
        );
    }
}

/// A GPU buffer read back to the CPU as f32s (blocking): the GPU tests' read-back.
pub(super) fn read_buffer(
    device: &nsrm::gpu::wgpu::Device,
    queue: &nsrm::gpu::wgpu::Queue,
    buf: &nsrm::gpu::wgpu::Buffer,
) -> Vec<f32> {
    use nsrm::gpu::wgpu;
    let rb = device.create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size: buf.size(),
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut enc = device.create_command_encoder(&Default::default());
    enc.copy_buffer_to_buffer(buf, 0, &rb, 0, buf.size());
    queue.submit([enc.finish()]);
    rb.map_async(wgpu::MapMode::Read, .., |r| r.unwrap());
    device.poll(wgpu::PollType::wait_indefinitely()).unwrap();
    let v = bytemuck::cast_slice(&rb.get_mapped_range(..).unwrap()).to_vec();
    rb.unmap();
    v
}

/// A frame across the highlight policy's blend and clip (ramps of several colours from half
/// the clip to 1.3 times it), then the awkward pixels (NaN, ±Inf, negatives, huge values).
fn highlight_frame(layout: Layout) -> Frame {
    let ch = layout.channels();
    let n = 2400;
    let awkward = random_frame(300, 1, layout, 5);
    let mut f = Frame::new(n + 300, 1, layout);
    for (i, px) in f.data.chunks_exact_mut(ch).take(n).enumerate() {
        let k = 0.5 + 0.8 * i as f32 / n as f32;
        let hue = (i % 11) as f32 / 11.0;
        px[0] = k * (0.2 + 0.8 * hue);
        px[1] = k;
        px[2] = k * (1.0 - 0.7 * hue);
        if ch == 4 {
            px[3] = hue;
        }
    }
    f.data[n * ch..].copy_from_slice(&awkward.data);
    f
}

/// The GPU runs the highlight policy (`shaders/highlights.wgsl`, parameters in the uniform) as
/// the f64 reference does, for every kind, and it is not a no-op: the policy changes the output
/// of pixels at the clip. Swapping to the model without it turns it off.
#[test]
fn the_highlight_policy_matches_the_f64_reference() {
    let Some(mut e) = engine(None) else { return };
    for kind in Kind::ALL {
        let plain = model(kind, if kind == Kind::Lrm { 1 } else { 2 });
        let m = plain
            .clone()
            .with_highlights(Some([0.7, 0.75, 0.8]))
            .unwrap();
        for layout in [Layout::Rgb, Layout::Rgba] {
            let input = highlight_frame(layout);
            let mut reference = input.clone();
            common::apply_reference(&m, &mut reference);
            let mut out = input.clone();
            e.apply(&m, &mut out).unwrap();
            let what = format!("{kind} {layout:?} with the highlight policy");
            let worst = compare(&what, &m, &input, &out, &reference, REL_TOL);
            let mut without = input.clone();
            e.apply(&plain, &mut without).unwrap();
            let mut plain_ref = input.clone();
            common::apply_reference(&plain, &mut plain_ref);
            compare(
                &format!("{kind} {layout:?} without"),
                &plain,
                &input,
                &without,
                &plain_ref,
                REL_TOL,
            );
            let ch = layout.channels();
            let changed = out
                .data
                .chunks_exact(ch)
                .zip(without.data.chunks_exact(ch))
                .filter(|(a, b)| (0..3).any(|k| (a[k] - b[k]).abs() > 1e-3 * b[k].abs()))
                .count();
            assert!(changed > 500, "{what}: the policy changed {changed} pixels");
            eprintln!(
                "{what}: GPU vs f64 max error (floored) {worst:.2e}, {changed} pixels changed"
            );
        }
    }
}
