//! The WGSL printer on pixel programs that are no kind's, run on the GPU: each program is printed
//! ([`super::shader::wgsl_program`]), built into a [`Corrector`], run on frames of awkward pixels
//! (lavapipe in CI) and compared with the f64 evaluator ([`Program::eval`]) within the one f32
//! bound of the kit. The four kinds' programs are held to the same check by
//! `tests/all/pixel_policy.rs`; these hold the printer to the description, not to a kind.
//!
//! Constructible ([`Program::check`]): the steps are an ordered subset of Gain, Normalise,
//! Combine, Rescale with Combine, and Rescale only after Normalise, over any term list whose roots
//! are 1..=4. Of those, {Combine} and {Gain, Normalise, Combine, Rescale} are the kinds' policies;
//! every other step set is run here, over term lists of several kinds and over lists no kind has.
//! Not constructible, so not run:
//! * Normalise over a term list that reads B (PRM's, RPRM's, LRM's): after Normalise the
//!   variables are `(r, g, 0)`, so `x₂` is no variable (`b = 1 − r − g` is not a term); `check`
//!   refuses it;
//! * Rescale without Normalise: there is no signal `s` to rescale by;
//! * no Combine, a step twice or out of order: nothing would produce `y`, or a step would read
//!   variables another step has not made.
//!
//! Without an adapter the test prints `SKIP: …` and passes, unless `CI=true`, where it fails.

use super::gpu_tests::engine;
use super::gpu_tests::read_buffer;
use super::{Corrector, Target};
use crate::kit::{awkward_frame, f32_bound, Rng, F32_REL};
use crate::model::pixel::{Program, Step};
use crate::model::terms::{terms, Term};
use crate::{Frame, Kind, Layout};

/// Input gains exact in f32, and passed to every program: one without a Gain step must ignore
/// them.
const GAINS: [f64; 3] = [1.75, 0.875, 0.625];

/// The programs run: (name, kind for the printed comments, steps, terms).
fn programs() -> Vec<(&'static str, Kind, &'static [Step], Vec<Term>)> {
    // RPRM order 4's terms that read only R and G: roots of chromaticities (no kind's list).
    let rooted_rg: Vec<Term> = terms(Kind::Rprm, 4)
        .into_iter()
        .filter(|t| t.exps[2] == 0)
        .collect();
    // RPRM order 3's terms reversed, then PRM order 2's and a constant: plain and rooted terms
    // mixed, in no kind's order.
    let mut mixed: Vec<Term> = terms(Kind::Rprm, 3).into_iter().rev().collect();
    mixed.extend(terms(Kind::Prm, 2));
    mixed.push(Term {
        exps: [0, 0, 0],
        root: 1,
    });
    use Step::{Combine, Gain, Normalise, Rescale};
    vec![
        (
            "Gain + Combine over PRM 3",
            Kind::Prm,
            &[Gain, Combine],
            terms(Kind::Prm, 3),
        ),
        (
            "Gain + Combine over RPRM 4",
            Kind::Rprm,
            &[Gain, Combine],
            terms(Kind::Rprm, 4),
        ),
        (
            "Gain + Combine over LRM",
            Kind::Lrm,
            &[Gain, Combine],
            terms(Kind::Lrm, 1),
        ),
        (
            "Normalise + Combine over NSRM 3",
            Kind::Nsrm,
            &[Normalise, Combine],
            terms(Kind::Nsrm, 3),
        ),
        (
            "Gain + Normalise + Combine over NSRM 4",
            Kind::Nsrm,
            &[Gain, Normalise, Combine],
            terms(Kind::Nsrm, 4),
        ),
        (
            "Normalise + Combine + Rescale over NSRM 2",
            Kind::Nsrm,
            &[Normalise, Combine, Rescale],
            terms(Kind::Nsrm, 2),
        ),
        (
            "NSRM's steps over rooted r, g terms",
            Kind::Nsrm,
            &[Gain, Normalise, Combine, Rescale],
            rooted_rg.clone(),
        ),
        (
            "Normalise + Combine over rooted r, g terms",
            Kind::Nsrm,
            &[Normalise, Combine],
            rooted_rg,
        ),
        (
            "Combine over mixed plain and rooted terms",
            Kind::Rprm,
            &[Combine],
            mixed.clone(),
        ),
        (
            "Gain + Combine over mixed terms",
            Kind::Rprm,
            &[Gain, Combine],
            mixed,
        ),
    ]
}

/// A 3×L matrix of both signs and several magnitudes, exact in f32 (so the reference and the
/// GPU use the same coefficients).
fn matrix(l: usize, seed: u64) -> Vec<f64> {
    let mut rng = Rng(seed);
    (0..3 * l)
        .map(|_| (rng.range(-2.0, 2.0) * 10f32.powi(rng.below(3) as i32 - 1)) as f64)
        .collect()
}

/// `program` on the GPU over `input` (RGB in place, RGBA source → destination).
fn run(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    program: &Program<'_>,
    m: &[f64],
    input: &Frame,
) -> Vec<f32> {
    let layout = input.layout;
    let in_place = layout == Layout::Rgb;
    let target = Target::Buffer { layout, in_place };
    let c = Corrector::for_program(device, program, m, GAINS, target)
        .unwrap_or_else(|e| panic!("{program:?}: {e}"));
    let bytes: &[u8] = bytemuck::cast_slice(&input.data);
    use wgpu::BufferUsages as U;
    let make = |usage| {
        device.create_buffer(&wgpu::BufferDescriptor {
            label: None,
            size: bytes.len() as u64,
            usage,
            mapped_at_creation: false,
        })
    };
    let a = make(U::STORAGE | U::COPY_DST | U::COPY_SRC);
    queue.write_buffer(&a, 0, bytes);
    let mut enc = device.create_command_encoder(&Default::default());
    if in_place {
        c.record_in_place(device, &mut enc, a.slice(..), None)
            .unwrap();
        queue.submit([enc.finish()]);
        read_buffer(device, queue, &a)
    } else {
        let b = make(U::STORAGE | U::COPY_SRC);
        c.record_buffers(device, &mut enc, a.slice(..), b.slice(..), None)
            .unwrap();
        queue.submit([enc.finish()]);
        read_buffer(device, queue, &b)
    }
}

/// Holds one pixel's GPU output to the f64 evaluator: a non-finite reference needs a non-finite
/// output (NaN for NaN), else `|got − ref| ≤ f32_bound(ref, T_k)` with `T_k = |scale|·Σ|m_kj·p_j|`.
fn check_pixel(name: &str, program: &Program<'_>, m: &[f64], rgb: [f32; 3], got: [f32; 3]) {
    let l = program.terms.len();
    let x = rgb.map(f64::from);
    let mut p = vec![0.0; l];
    let want = program.eval(m, GAINS, x, &mut p);
    let summands = match program.features(GAINS, x, &mut p) {
        None => [0.0; 3],
        Some(scale) => [0, 1, 2]
            .map(|k| scale.abs() * (0..l).map(|j| (m[k * l + j] * p[j]).abs()).sum::<f64>()),
    };
    for k in 0..3 {
        let (w, g) = (want[k], f64::from(got[k]));
        let ok = if w.is_nan() {
            g.is_nan()
        } else if !w.is_finite() {
            !g.is_finite()
        } else {
            (g - w).abs() <= f32_bound(w, summands[k], F32_REL)
        };
        assert!(
            ok,
            "{name}: pixel {rgb:?} channel {k}: GPU {g:e}, f64 {w:e} (T {:e})",
            summands[k]
        );
    }
}

#[test]
fn printed_programs_that_are_no_kinds_match_the_f64_evaluator_on_the_gpu() {
    let Some(e) = engine(None) else { return };
    let ctx = e.context();
    let (device, queue) = (&ctx.device, &ctx.queue);
    for (i, (name, kind, steps, list)) in programs().iter().enumerate() {
        let program = Program::custom(*kind, steps, list).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(
            !Kind::ALL.iter().any(|&k| *steps == Program::steps_of(k)
                && Kind::ALL
                    .iter()
                    .any(|&o| (1..=4).any(|n| terms(o, o.effective_order(n)) == *list))),
            "{name} is a kind's program"
        );
        let m = matrix(list.len(), 40 + i as u64);
        for layout in [Layout::Rgb, Layout::Rgba] {
            let input = awkward_frame(61, 7, layout, 7 + i as u64);
            let out = run(device, queue, &program, &m, &input);
            let ch = layout.channels();
            for (px, o) in input.data.chunks(ch).zip(out.chunks(ch)) {
                check_pixel(
                    name,
                    &program,
                    &m,
                    [px[0], px[1], px[2]],
                    [o[0], o[1], o[2]],
                );
                if ch == 4 {
                    assert_eq!(px[3].to_bits(), o[3].to_bits(), "{name}: alpha");
                }
            }
        }
    }
}
