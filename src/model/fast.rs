//! The fast CPU apply path: f32, vectorised (by the compiler, and by hand for NSRM 3 and PRM 3),
//! multi-threaded with rayon.
//!
//! Why one file (about 1,850 lines): the four kernels (LRM, PRM, RPRM, NSRM) share the chunking,
//! the pixel policy and the prepared-matrix layout, and are checked against each other and against
//! the f64 reference by the same tests (`fast_tests.rs` and the module below); splitting them would
//! put the one pixel policy in four places. What is apart is what has its own subject: the
//! explicit-vector drivers and registers (`fast/explicit.rs`), which call the formulas here.
//!
//! [`apply_frame`] (every thread of rayon's global pool) and [`apply_frame_single`] (the calling
//! thread only) correct a [`Frame`] in place; [`FastModel`] holds the prepared kernel for repeated
//! use, and [`FastModel::apply_into`] writes into a second frame (the input is left alone).
//!
//! # How it is fast (without `unsafe`)
//! * A frame is cut into chunks of [`CHUNK_PIXELS`] pixels (one rayon task each). The channel
//!   count (3 or 4) is a const generic, so all indexing is by constants and the compiler emits
//!   packed SIMD without bounds checks.
//! * The hand-written kernels are functions of one pixel (`PixelKernel`: straight-line code
//!   with no branches; the NSRM `s ≤ 0` rule is a select), and the chunk loop calls them pixel by
//!   pixel on the interleaved data itself. LLVM's loop vectoriser turns that loop into
//!   interleaved loads (stride 3 or 4, de-interleaved by shuffles in registers), packed
//!   arithmetic over 8 or 16 pixels and interleaved stores. (Evaluating a block in per-channel
//!   lane arrays and interleaving those back, as this module did before, made LLVM spill the
//!   results to the stack and reload them at odd offsets: store-forwarding stalls that cost more
//!   than PRM 3's arithmetic.)
//! * PRM 3's nested form is only right on finite pixels: its per-pixel loop goes 16 pixels at a
//!   time with one cheap test (every value below `f32::MAX / 4`, no shuffles); a block of [`LANES`] pixels
//!   with a non-finite pixel, or one whose `R + G + B` overflows, takes the term sums instead.
//! * The generic kernel (`BlockKernel`) works on blocks of [`LANES`] pixels de-interleaved into
//!   one fixed-size array per channel (`[f32; LANES]`); its last partial block goes through a
//!   zero-padded copy.
//! * The chunk loops are compiled with the `multiversion` crate for baseline x86-64, AVX2 + FMA
//!   and (the per-pixel kernels only) AVX-512 (F + VL: 16 pixels per register, two-source permutes
//!   for the de-interleave), and the CPU is detected once at run time (safe code, no intrinsics:
//!   the loop vectoriser does the rest).
//!   The generic kernel stops at AVX2: its lane arrays ran 20–30 % slower in the AVX-512 clone.
//!   Only the FMA clones fuse multiply-adds (`madd`); the baseline never calls libm's software
//!   `fmaf`.
//! * NSRM 3 and PRM 3 on packed RGB have explicit-vector kernels (`fast/explicit.rs`, x86-64):
//!   AVX2 + FMA on a CPU without AVX-512, SSE2 where the CPU has no AVX2 + FMA and for the
//!   baseline code. They de-interleave with in-lane shuffles only and issue the next block's
//!   divisions before this block's multiply-adds (1.7× NSRM 3's per-pixel loop, 1.3× PRM 3's, a
//!   thread in L2 on AMD Zen 3; see BENCHMARKS.md). Their arithmetic is the per-pixel kernels'
//!   own text — [`nsrm3_front`], [`nsrm3_back`] and [`prm3_nested`] are generic over [`Arith`]:
//!   `f32`, or a register of 8 pixels — so they give the same bits (NaN payloads aside: where two
//!   different NaNs meet, which one comes out is the compiler's choice on either path; a NaN stays
//!   a NaN). The intrinsics are `pulp`'s safe wrappers, so the crate still has no `unsafe`.
//! * What a kernel computes is read from the model's pixel program ([`super::pixel::Program`],
//!   the one description of the per-pixel policy and terms). LRM (also PRM 1 and RPRM 1, the same
//!   three terms), PRM 3, RPRM 3 and NSRM 3 have hand-written kernels; each declares the steps and
//!   the terms (in its own column order) its arithmetic computes, runs only for a program with
//!   those steps and terms, and takes its matrix columns through the index map from the program's
//!   term order. Every other program runs a generic kernel whose policy flags (gains, normalise,
//!   rescale) are the program's steps and whose product plan is built once from its [`Term`]
//!   list: every term is one multiplication of two earlier values, so it is as cheap in
//!   arithmetic as the hand-written kernels and still allocation-free per pixel.
//! * RPRM: the sign-preserving square, cube and fourth roots are computed once per channel and the
//!   terms are products of them (`∛(R G²) = ∛R·(∛G)²`, exactly how [`super::terms::expand`]
//!   defines them). The cube root needs no libm and no division ([`cbrt_s`]): a bit-pattern first
//!   guess of `x^(-1/3)`, one third-order step, `x·z²` and one second-order correction (max
//!   relative error 1.3e-7, about 1 ulp, over all f32 including subnormals; `±0 → ±0`,
//!   `±∞ → ±∞`, NaN → NaN). The FMA clones fuse its steps and divide the bit pattern by 3 with
//!   one multiply. RPRM 3 goes 16 pixels at a time like PRM 3: a step whose values are all 0 or
//!   finite and at least 1e-30 in magnitude (integer compares) skips the cube root's rescaling
//!   of tiny values and its ±∞ select, with the same result.
//!
//! # Accuracy
//! Every kernel follows the [pixel policy](super::pixel) exactly (NaN/Inf propagate, NSRM `s ≤ 0 → 0`,
//! negative channels allowed, nothing clamped). Values are the f64 reference
//! ([`Model::apply_frame_f64`]) to f32 precision: `fast_tests.rs` checks every kind, order and
//! layout against it.

use crate::frame::{Frame, Layout};
use crate::model::pixel::{Program, Step};
use crate::model::terms::Term;
use crate::model::Model;
use rayon::prelude::*;
use std::collections::HashMap;

#[cfg(target_arch = "x86_64")]
mod explicit;
#[cfg(target_arch = "x86_64")]
use explicit::{Explicit, Halves};

/// No explicit-vector kernels off x86-64 (the per-pixel kernels run).
#[cfg(not(target_arch = "x86_64"))]
#[derive(Debug, Clone, Copy)]
enum Explicit {}

#[cfg(not(target_arch = "x86_64"))]
trait Halves {}
#[cfg(not(target_arch = "x86_64"))]
impl<K> Halves for K {}

#[cfg(not(target_arch = "x86_64"))]
impl Explicit {
    fn detect() -> Option<Explicit> {
        None
    }
    fn baseline() -> Option<Explicit> {
        None
    }
    fn avx2() -> Option<Explicit> {
        None
    }
    #[cfg(test)]
    fn name(self) -> &'static str {
        match self {}
    }
    fn into<K>(self, _: &K, _: &[f32], _: &mut [f32]) {
        match self {}
    }
    fn in_place<K>(self, _: &K, _: &mut [f32]) {
        match self {}
    }
}

/// Pixels per block: one `[f32; LANES]` array per channel (one AVX or two SSE registers).
pub(crate) const LANES: usize = 8;

/// Pixels per rayon task (64 Ki pixels: 768 KiB of packed RGB f32).
pub const CHUNK_PIXELS: usize = 1 << 16;

type Lanes = [f32; LANES];

/// Errors of the fast path: only frames of the wrong shape (every [`Model`] has a kernel).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum FastError {
    /// Source and destination frames differ in size or layout.
    #[error("source frame is {src_w}×{src_h} {src_layout}, destination {dst_w}×{dst_h} {dst_layout}: they must match")]
    FrameMismatch {
        /// Source width.
        src_w: usize,
        /// Source height.
        src_h: usize,
        /// Source layout.
        src_layout: &'static str,
        /// Destination width.
        dst_w: usize,
        /// Destination height.
        dst_h: usize,
        /// Destination layout.
        dst_layout: &'static str,
    },
    /// A frame whose data length does not match its size and layout.
    #[error("a {width}×{height} {layout} frame needs {expected} floats, its data holds {len}")]
    FrameLength {
        /// Width.
        width: usize,
        /// Height.
        height: usize,
        /// Layout.
        layout: &'static str,
        /// Floats the size and layout need.
        expected: usize,
        /// Floats the data holds.
        len: usize,
    },
    /// Source and destination buffers of different lengths, or not whole pixels.
    #[error("source buffer holds {src} floats, destination {dst}: they must be equal, a whole number of {layout} pixels")]
    SliceLength {
        /// Floats in the source.
        src: usize,
        /// Floats in the destination.
        dst: usize,
        /// The layout.
        layout: &'static str,
    },
}

/// How many threads an apply call uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Threads {
    /// The calling thread only.
    Single,
    /// Every thread of rayon's current pool (the global pool unless called inside `install`).
    All,
}

/// Corrects `frame` in place with every thread of rayon's global pool (alpha untouched).
///
/// Every [`Model`] takes the fast path: a model is valid by construction (its term list derives
/// from its kind and order), and every standard term list has a kernel.
pub(crate) fn apply_frame(model: &Model, frame: &mut Frame) {
    FastModel::new(model).apply(frame, Threads::All)
}

/// [`apply_frame`] on the calling thread only.
#[cfg(test)]
pub(crate) fn apply_frame_single(model: &Model, frame: &mut Frame) {
    FastModel::new(model).apply(frame, Threads::Single)
}

/// Which compiled code the chunk loops run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Code {
    /// The clone for this CPU, detected at run time (AVX2 + FMA where present).
    Detected,
    /// The baseline code: no fused multiply-add, so the same bits on every CPU (the per-pixel
    /// kernels' baseline clone, the SSE2 explicit-vector kernels for NSRM 3 and PRM 3 on packed
    /// RGB); [`FastModel::apply_baseline`].
    Baseline,
    /// [`Detected`](Self::Detected) through the per-pixel kernels only, never the explicit-vector
    /// ones ([`Explicit`]): what the tests hold their bits to.
    #[cfg_attr(not(test), allow(dead_code))]
    PixelLoop,
    /// [`Baseline`](Self::Baseline) through the per-pixel kernels only.
    #[cfg_attr(not(test), allow(dead_code))]
    BaselinePixelLoop,
    /// The AVX2 + FMA explicit-vector kernels wherever the CPU has AVX2 + FMA, AVX-512 included
    /// (where [`Detected`](Self::Detected) does not choose them): so the tests hold their bits to
    /// the per-pixel FMA code's on every such CPU. Else as `Detected`.
    #[cfg_attr(not(test), allow(dead_code))]
    ForcedAvx2,
}

/// Which monomorphised kernel a model runs.
#[derive(Debug, Clone)]
enum Kernel {
    Linear(Linear),
    Prm3(Prm3),
    Rprm3(Rprm3),
    Nsrm3(Nsrm3),
    Plan(Box<Plan>),
}

/// A model prepared for the fast path: f32 matrix and the kernel chosen for its term list.
#[derive(Debug, Clone)]
pub struct FastModel {
    kernel: Kernel,
    /// The model's highlight policy, run on each chunk before the kernel
    /// ([`super::highlights`]).
    highlights: Option<super::highlights::HighlightsF32>,
}

impl FastModel {
    /// Prepares `model`: a hand-written kernel where one declares the model's pixel program
    /// (LRM, PRM 3, RPRM 3, NSRM 3, PRM / RPRM order 1), otherwise a product plan built from it.
    pub fn new(model: &Model) -> FastModel {
        FastModel {
            kernel: Kernel::choose(&model.program(), &model.matrix, model.input_gains),
            highlights: model.highlights.map(|h| h.to_f32()),
        }
    }

    /// The kernel's name: `linear`, `prm3`, `rprm3`, `nsrm3` or `plan` (the generic one).
    pub fn kernel_name(&self) -> &'static str {
        match self.kernel {
            Kernel::Linear(_) => "linear",
            Kernel::Prm3(_) => "prm3",
            Kernel::Rprm3(_) => "rprm3",
            Kernel::Nsrm3(_) => "nsrm3",
            Kernel::Plan(_) => "plan",
        }
    }

    /// Corrects `frame` in place (alpha untouched). Whole pixels only: should the data length not
    /// be a multiple of the channel count, the trailing partial pixel is left as it is.
    pub fn apply(&self, frame: &mut Frame, threads: Threads) {
        self.apply_code(frame, threads, Code::Detected)
    }

    /// [`apply`](Self::apply) with the baseline code on any CPU: no fused multiply-add, so the
    /// output is the same bits on every x86-64 machine (the detected AVX2 + FMA code rounds some
    /// multiply-adds once instead of twice), for a render farm whose hosts must agree bit for
    /// bit. Both stay within the bounds of the f64 reference that `fast_tests.rs` holds them to.
    /// On packed RGB, NSRM 3 and PRM 3 run their SSE2 kernels here; the others their per-pixel
    /// code compiled for baseline x86-64.
    pub fn apply_baseline(&self, frame: &mut Frame, threads: Threads) {
        self.apply_code(frame, threads, Code::Baseline)
    }

    /// [`apply`](Self::apply) through the per-pixel kernels' detected clone only (never the
    /// explicit-vector kernels, which must give the same bits).
    #[cfg(test)]
    pub(crate) fn apply_pixel_loop(&self, frame: &mut Frame, threads: Threads) {
        self.apply_code(frame, threads, Code::PixelLoop)
    }

    /// [`apply_baseline`](Self::apply_baseline) through the per-pixel kernels only.
    #[cfg(test)]
    pub(crate) fn apply_baseline_pixel_loop(&self, frame: &mut Frame, threads: Threads) {
        self.apply_code(frame, threads, Code::BaselinePixelLoop)
    }

    /// [`apply`](Self::apply) through the AVX2 + FMA explicit-vector kernels even where they are
    /// not chosen (an AVX-512 CPU); false (and [`apply`](Self::apply)'s code) where the CPU has
    /// no AVX2 + FMA.
    #[cfg(test)]
    pub(crate) fn apply_forced_avx2(&self, frame: &mut Frame, threads: Threads) -> bool {
        self.apply_code(frame, threads, Code::ForcedAvx2);
        Explicit::avx2().is_some()
    }

    /// The explicit-vector kernel this model runs on packed RGB on this CPU, if any.
    #[cfg(test)]
    pub(crate) fn explicit_vectors(&self) -> Option<&'static str> {
        match &self.kernel {
            Kernel::Nsrm3(Nsrm3 { explicit, .. }) | Kernel::Prm3(Prm3 { explicit, .. }) => {
                explicit.map(Explicit::name)
            }
            _ => None,
        }
    }

    fn apply_code(&self, frame: &mut Frame, threads: Threads, code: Code) {
        let ch = frame.layout.channels();
        let whole = frame.data.len() - frame.data.len() % ch;
        let data = &mut frame.data[..whole];
        match frame.layout {
            Layout::Rgb => self.dispatch_in_place::<3>(data, threads, code),
            Layout::Rgba => self.dispatch_in_place::<4>(data, threads, code),
        }
    }

    /// Corrects `src` into `dst` (same size and layout; alpha copied), leaving `src` unchanged.
    pub fn apply_into(
        &self,
        src: &Frame,
        dst: &mut Frame,
        threads: Threads,
    ) -> Result<(), FastError> {
        if (src.width, src.height, src.layout) != (dst.width, dst.height, dst.layout) {
            return Err(FastError::FrameMismatch {
                src_w: src.width,
                src_h: src.height,
                src_layout: src.layout.name(),
                dst_w: dst.width,
                dst_h: dst.height,
                dst_layout: dst.layout.name(),
            });
        }
        for f in [src, &*dst] {
            let expected = f.pixels() * f.layout.channels();
            if f.data.len() != expected {
                return Err(FastError::FrameLength {
                    width: f.width,
                    height: f.height,
                    layout: f.layout.name(),
                    expected,
                    len: f.data.len(),
                });
            }
        }
        self.apply_slices(&src.data, &mut dst.data, src.layout, threads)
    }

    /// [`apply_into`](Self::apply_into) on bare interleaved buffers of `layout` (the same length,
    /// whole pixels): for a caller whose pixels live in memory it does not own as a [`Frame`]
    /// (the Python bindings correct a numpy array into a new one without copying it first).
    pub fn apply_slices(
        &self,
        src: &[f32],
        dst: &mut [f32],
        layout: Layout,
        threads: Threads,
    ) -> Result<(), FastError> {
        if src.len() != dst.len() || !src.len().is_multiple_of(layout.channels()) {
            return Err(FastError::SliceLength {
                src: src.len(),
                dst: dst.len(),
                layout: layout.name(),
            });
        }
        match layout {
            Layout::Rgb => self.dispatch_into::<3>(src, dst, threads),
            Layout::Rgba => self.dispatch_into::<4>(src, dst, threads),
        }
        Ok(())
    }

    fn dispatch_in_place<const C: usize>(&self, data: &mut [f32], threads: Threads, code: Code) {
        let h = self.highlights.as_ref();
        match &self.kernel {
            Kernel::Linear(k) => in_place::<_, C>(k, h, data, threads, code),
            Kernel::Prm3(k) => in_place_explicit::<_, C>(k, k.explicit, h, data, threads, code),
            Kernel::Rprm3(k) => in_place::<_, C>(k, h, data, threads, code),
            Kernel::Nsrm3(k) => in_place_explicit::<_, C>(k, k.explicit, h, data, threads, code),
            Kernel::Plan(k) => in_place::<_, C>(&Blocks(&**k), h, data, threads, code),
        }
    }

    fn dispatch_into<const C: usize>(&self, src: &[f32], dst: &mut [f32], threads: Threads) {
        if self.highlights.is_some() {
            // The policy changes the input: copied, then corrected in place.
            dst.copy_from_slice(src);
            return self.dispatch_in_place::<C>(dst, threads, Code::Detected);
        }
        match &self.kernel {
            Kernel::Linear(k) => into::<_, C>(k, src, dst, threads),
            Kernel::Prm3(k) => into_explicit::<_, C>(k, k.explicit, src, dst, threads),
            Kernel::Rprm3(k) => into::<_, C>(k, src, dst, threads),
            Kernel::Nsrm3(k) => into_explicit::<_, C>(k, k.explicit, src, dst, threads),
            Kernel::Plan(k) => into::<_, C>(&Blocks(&**k), src, dst, threads),
        }
    }
}

impl Kernel {
    /// The kernel for a pixel program: the first hand-written kernel whose declaration
    /// ([`Declared`]) is the program — the same steps, and the same terms in any order — with its
    /// matrix columns taken through the index map from its term order to the program's; else the
    /// generic plan, built from the program. `matrix` is row-major 3×L over the program's terms.
    fn choose(program: &Program<'_>, matrix: &[f64], gains: [f64; 3]) -> Kernel {
        if let Some(m) = columns::<Linear, 3>(program, matrix) {
            Kernel::Linear(Linear { m })
        } else if let Some(m) = columns::<Prm3, 19>(program, matrix) {
            Kernel::Prm3(Prm3 {
                m,
                explicit: Explicit::detect(),
            })
        } else if let Some(m) = columns::<Rprm3, 13>(program, matrix) {
            Kernel::Rprm3(Rprm3 { m })
        } else if let Some(m) = columns::<Nsrm3, 10>(program, matrix) {
            // Nsrm3 declares the gain step, so the program has it.
            Kernel::Nsrm3(Nsrm3 {
                m,
                gain: gains.map(|v| v as f32),
                explicit: Explicit::detect(),
            })
        } else {
            Kernel::Plan(Box::new(Plan::new(program, matrix, gains)))
        }
    }
}

/// What a hand-written kernel computes, declared beside its arithmetic: the program steps it
/// spells and its terms in the order of its own matrix columns. [`Kernel::choose`] runs it only
/// for a program with these steps and these terms (in any order); the unit test
/// `hand_kernels_compute_what_they_declare` holds the arithmetic to the declaration.
trait Declared {
    const STEPS: &'static [Step];
    const TERMS: &'static [Term];
}

/// A term of a declaration.
const fn term(exps: [u8; 3], root: u8) -> Term {
    Term { exps, root }
}

/// The index map from `K`'s declared term order to the program's, or `None` when `K` does not
/// declare this program (other steps, or another set of terms).
fn index_map<K: Declared>(program: &Program<'_>) -> Option<Vec<usize>> {
    if program.steps != K::STEPS || program.terms.len() != K::TERMS.len() {
        return None;
    }
    let map: Vec<usize> = K::TERMS
        .iter()
        .map(|t| program.terms.iter().position(|p| p == t))
        .collect::<Option<_>>()?;
    // A permutation: every program term is one column of the kernel.
    let mut seen = vec![false; map.len()];
    for &j in &map {
        if std::mem::replace(&mut seen[j], true) {
            return None;
        }
    }
    Some(map)
}

/// `K`'s f32 matrix rows in its declared term order, from the row-major 3×L `matrix` over the
/// program's terms, or `None` when `K` does not declare the program.
fn columns<K: Declared, const L: usize>(
    program: &Program<'_>,
    matrix: &[f64],
) -> Option<[[f32; L]; 3]> {
    let map = index_map::<K>(program)?;
    if map.len() != L || matrix.len() != 3 * L {
        return None;
    }
    let mut m = [[0.0; L]; 3];
    for (k, row) in m.iter_mut().enumerate() {
        for (v, &j) in row.iter_mut().zip(&map) {
            *v = matrix[k * L + j] as f32;
        }
    }
    Some(m)
}

// ---------------------------------------------------------------------------------------------
// Drivers: chunks over threads, blocks within a chunk, (de-)interleaving.
// ---------------------------------------------------------------------------------------------

/// How a kernel runs over one chunk. Every implementation is `#[inline(always)]`, so it is
/// compiled into each multiversioned clone of [`chunk_in_place`] / [`chunk_into`] (and, for the
/// explicit-vector kernels' slow path, into their `vectorize` functions).
trait Chunks: Sync {
    /// Whether the AVX-512 clone runs this kernel where the CPU has it: true for the pixel
    /// kernels; the block kernels' lane arrays of 8 measured 20–30 % slower there than in the
    /// AVX2 clone, so they stop at AVX2.
    const AVX512: bool;
    fn run_in_place<const C: usize>(&self, data: &mut [f32], fma: bool);
    fn run_into<const C: usize>(&self, src: &[f32], dst: &mut [f32], fma: bool);
}

/// A kernel written for one pixel: the chunk loops call it pixel by pixel, reading and writing
/// the interleaved data directly, and the loop vectoriser evaluates 8 (AVX2) or 16 (AVX-512)
/// pixels per vector, de-interleaving them with shuffles in registers.
trait PixelKernel: Sync {
    /// Whether the chunk loop goes in steps of [`PIXEL_BLOCK`] pixels with one cheap test each
    /// ([`step_ok`](Self::step_ok)): a step that passes runs `pixel::<true>`, one that fails (and
    /// the last partial step) [`slow_in_place`](Self::slow_in_place). Otherwise every pixel runs
    /// `pixel::<false>`.
    const STEPPED: bool = false;
    /// The step test, on the interleaved values (alpha included).
    fn step_ok(_blk: &[f32]) -> bool {
        true
    }
    /// One pixel. `STEP_OK`: the pixel is in a step that passed [`step_ok`](Self::step_ok), so
    /// the kernel may skip the handling of values the test excludes (with the same result).
    /// `fma`: whether the code is being compiled for a target with fused multiply-add (a
    /// compile-time constant in each multiversioned clone; see [`madd`]).
    fn pixel<const STEP_OK: bool>(&self, x: [f32; 3], fma: bool) -> [f32; 3];
    /// A step that failed the test, or the last partial step, in place.
    #[inline(always)]
    fn slow_in_place<const C: usize>(&self, blk: &mut [f32], fma: bool)
    where
        Self: Sized,
    {
        map_in_place::<Self, C, false>(self, blk, fma)
    }
    /// The block path of [`guarded_block`] (PRM 3's term sums; unused otherwise).
    fn fallback(&self, x: &[Lanes; 3], fma: bool) -> [Lanes; 3] {
        let mut y = [[0.0; LANES]; 3];
        for i in 0..LANES {
            let p = self.pixel::<false>([x[0][i], x[1][i], x[2][i]], fma);
            for c in 0..3 {
                y[c][i] = p[c];
            }
        }
        y
    }
}

/// A kernel that evaluates one block of `LANES` pixels given as channel arrays (R, G, B): the
/// generic plan, whose per-term loop is not a per-pixel function.
trait BlockKernel: Sync {
    /// Per-task scratch space (allocated once per chunk, never per pixel).
    type Scratch;
    fn scratch(&self) -> Self::Scratch;
    /// `fma` as in [`PixelKernel::pixel`].
    fn block(&self, x: &[Lanes; 3], scratch: &mut Self::Scratch, fma: bool) -> [Lanes; 3];
}

/// Pixels per step of a stepped kernel's loop (two [`LANES`] blocks): one cheap test per step.
const PIXEL_BLOCK: usize = 2 * LANES;

/// Magnitudes below this are finite and so is the sum of three of them.
const SUM_SAFE: f32 = f32::MAX / 4.0;

/// A cheap sufficient test for [`all_finite`] on every block of `blk` (interleaved, alpha
/// included): no shuffles, just one compare per value.
#[inline(always)]
fn quick_finite(blk: &[f32]) -> bool {
    let mut ok = true;
    for v in blk {
        // NaN compares false.
        ok &= v.abs() < SUM_SAFE;
    }
    ok
}

/// De-interleaves one block of `C`-channel pixels.
#[inline(always)]
fn load<const C: usize>(blk: &[f32]) -> [Lanes; C] {
    let blk = &blk[..C * LANES];
    let mut x = [[0.0; LANES]; C];
    for i in 0..LANES {
        for c in 0..C {
            x[c][i] = blk[i * C + c];
        }
    }
    x
}

/// Interleaves one block back: channels 0..3 from `y`, channel 3 (alpha) from `alpha`.
#[inline(always)]
fn store<const C: usize>(y: &[Lanes; 3], alpha: &[Lanes; C], blk: &mut [f32]) {
    let blk = &mut blk[..C * LANES];
    for i in 0..LANES {
        for c in 0..C {
            blk[i * C + c] = if c < 3 { y[c][i] } else { alpha[c][i] };
        }
    }
}

#[inline(always)]
fn rgb_of<const C: usize>(x: &[Lanes; C]) -> [Lanes; 3] {
    [x[0], x[1], x[2]]
}

/// `dst = f(src)` pixel by pixel (alpha copied): the loop the vectoriser turns into interleaved
/// loads, packed arithmetic and interleaved stores.
#[inline(always)]
fn map_into<K: PixelKernel, const C: usize, const STEP_OK: bool>(
    k: &K,
    src: &[f32],
    dst: &mut [f32],
    fma: bool,
) {
    for (s, d) in src.chunks_exact(C).zip(dst.chunks_exact_mut(C)) {
        let y = k.pixel::<STEP_OK>([s[0], s[1], s[2]], fma);
        d[0] = y[0];
        d[1] = y[1];
        d[2] = y[2];
        if C == 4 {
            d[3] = s[3];
        }
    }
}

/// [`map_into`] in place (alpha untouched).
#[inline(always)]
fn map_in_place<K: PixelKernel, const C: usize, const STEP_OK: bool>(
    k: &K,
    data: &mut [f32],
    fma: bool,
) {
    for p in data.chunks_exact_mut(C) {
        let y = k.pixel::<STEP_OK>([p[0], p[1], p[2]], fma);
        p[0] = y[0];
        p[1] = y[1];
        p[2] = y[2];
    }
}

/// One block of at most [`LANES`] pixels, in place: the pixel loop when the block is finite,
/// else the fallback (a partial block through a zero-padded copy). PRM 3's slow path.
#[inline(always)]
fn guarded_block<K: PixelKernel, const C: usize>(k: &K, blk: &mut [f32], fma: bool) {
    let mut buf = [[0.0f32; LANES]; 4];
    let buf = buf.as_flattened_mut();
    let n = blk.len();
    buf[..n].copy_from_slice(blk);
    let x = load::<C>(buf);
    if all_finite(&rgb_of(&x)) {
        map_in_place::<K, C, false>(k, blk, fma);
    } else {
        let y = k.fallback(&rgb_of(&x), fma);
        store::<C>(&y, &x, buf);
        blk.copy_from_slice(&buf[..n]);
    }
}

impl<K: PixelKernel> Chunks for K {
    const AVX512: bool = true;

    #[inline(always)]
    fn run_in_place<const C: usize>(&self, data: &mut [f32], fma: bool) {
        if !K::STEPPED {
            return map_in_place::<K, C, false>(self, data, fma);
        }
        let mut steps = data.chunks_exact_mut(C * PIXEL_BLOCK);
        for s in &mut steps {
            if K::step_ok(s) {
                map_in_place::<K, C, true>(self, s, fma);
            } else {
                self.slow_in_place::<C>(s, fma);
            }
        }
        self.slow_in_place::<C>(steps.into_remainder(), fma);
    }

    #[inline(always)]
    fn run_into<const C: usize>(&self, src: &[f32], dst: &mut [f32], fma: bool) {
        if !K::STEPPED {
            return map_into::<K, C, false>(self, src, dst, fma);
        }
        let n = C * PIXEL_BLOCK;
        let mut s_steps = src.chunks_exact(n);
        let mut d_steps = dst.chunks_exact_mut(n);
        for (s, d) in (&mut s_steps).zip(&mut d_steps) {
            if K::step_ok(s) {
                map_into::<K, C, true>(self, s, d, fma);
            } else {
                d.copy_from_slice(s);
                self.slow_in_place::<C>(d, fma);
            }
        }
        let (s, d) = (s_steps.remainder(), d_steps.into_remainder());
        d.copy_from_slice(s);
        self.slow_in_place::<C>(d, fma);
    }
}

/// A [`BlockKernel`] over a chunk: whole blocks, then the last partial block through a
/// zero-padded copy.
struct Blocks<'a, K>(&'a K);

impl<K: BlockKernel> Chunks for Blocks<'_, K> {
    const AVX512: bool = false;

    #[inline(always)]
    fn run_in_place<const C: usize>(&self, data: &mut [f32], fma: bool) {
        let k = self.0;
        let mut scratch = k.scratch();
        let mut blocks = data.chunks_exact_mut(C * LANES);
        for blk in &mut blocks {
            let x = load::<C>(blk);
            let y = k.block(&rgb_of(&x), &mut scratch, fma);
            store::<C>(&y, &x, blk);
        }
        let rem = blocks.into_remainder();
        if !rem.is_empty() {
            let mut buf = [[0.0f32; LANES]; 4];
            let buf = buf.as_flattened_mut();
            buf[..rem.len()].copy_from_slice(rem);
            let x = load::<C>(buf);
            let y = k.block(&rgb_of(&x), &mut scratch, fma);
            store::<C>(&y, &x, buf);
            rem.copy_from_slice(&buf[..rem.len()]);
        }
    }

    #[inline(always)]
    fn run_into<const C: usize>(&self, src: &[f32], dst: &mut [f32], fma: bool) {
        let k = self.0;
        let mut scratch = k.scratch();
        let mut s_blocks = src.chunks_exact(C * LANES);
        let mut d_blocks = dst.chunks_exact_mut(C * LANES);
        for (s, d) in (&mut s_blocks).zip(&mut d_blocks) {
            let x = load::<C>(s);
            let y = k.block(&rgb_of(&x), &mut scratch, fma);
            store::<C>(&y, &x, d);
        }
        let (s_rem, d_rem) = (s_blocks.remainder(), d_blocks.into_remainder());
        if !s_rem.is_empty() {
            let mut buf = [[0.0f32; LANES]; 4];
            let buf = buf.as_flattened_mut();
            buf[..s_rem.len()].copy_from_slice(s_rem);
            let x = load::<C>(buf);
            let y = k.block(&rgb_of(&x), &mut scratch, fma);
            store::<C>(&y, &x, buf);
            d_rem.copy_from_slice(&buf[..d_rem.len()]);
        }
    }
}

fn in_place<K: Chunks, const C: usize>(
    k: &K,
    highlights: Option<&super::highlights::HighlightsF32>,
    data: &mut [f32],
    threads: Threads,
    code: Code,
) {
    chunked_in_place::<C>(highlights, data, threads, |chunk| match code {
        Code::Detected | Code::PixelLoop | Code::ForcedAvx2 if K::AVX512 => {
            chunk_in_place::<K, C>(k, chunk)
        }
        Code::Detected | Code::PixelLoop | Code::ForcedAvx2 => {
            chunk_in_place_avx2::<K, C>(k, chunk)
        }
        Code::Baseline | Code::BaselinePixelLoop => k.run_in_place::<C>(chunk, false),
    })
}

/// `run` on each [`CHUNK_PIXELS`]-pixel chunk of `data` (after the highlight policy), on the
/// calling thread or rayon's pool.
fn chunked_in_place<const C: usize>(
    highlights: Option<&super::highlights::HighlightsF32>,
    data: &mut [f32],
    threads: Threads,
    run: impl Fn(&mut [f32]) + Sync,
) {
    let n = CHUNK_PIXELS * C;
    let run = |chunk: &mut [f32]| {
        if let Some(h) = highlights {
            h.apply::<C>(chunk);
        }
        run(chunk)
    };
    match threads {
        Threads::All => data.par_chunks_mut(n).for_each(run),
        Threads::Single => data.chunks_mut(n).for_each(run),
    }
}

/// [`in_place`], through an explicit-vector kernel where the data is packed RGB and one stands
/// for the code that runs: `detected` (this CPU's, [`Explicit::detect`]) for the detected code,
/// SSE2 for the baseline.
fn in_place_explicit<K: Chunks + Halves, const C: usize>(
    k: &K,
    detected: Option<Explicit>,
    highlights: Option<&super::highlights::HighlightsF32>,
    data: &mut [f32],
    threads: Threads,
    code: Code,
) {
    let explicit = match code {
        Code::Detected => detected,
        Code::Baseline => Explicit::baseline(),
        Code::ForcedAvx2 => Explicit::avx2().or(detected),
        Code::PixelLoop | Code::BaselinePixelLoop => None,
    };
    match (C, explicit) {
        (3, Some(e)) => chunked_in_place::<C>(highlights, data, threads, |c| e.in_place(k, c)),
        _ => in_place::<_, C>(k, highlights, data, threads, code),
    }
}

/// [`into`], through this CPU's explicit-vector kernel (`detected`) where the data is packed RGB.
fn into_explicit<K: Chunks + Halves, const C: usize>(
    k: &K,
    detected: Option<Explicit>,
    src: &[f32],
    dst: &mut [f32],
    threads: Threads,
) {
    match (C, detected) {
        (3, Some(e)) => chunked_into::<C>(src, dst, threads, |s, d| e.into(k, s, d)),
        _ => into::<_, C>(k, src, dst, threads),
    }
}

fn into<K: Chunks, const C: usize>(k: &K, src: &[f32], dst: &mut [f32], threads: Threads) {
    chunked_into::<C>(src, dst, threads, |s, d| {
        if K::AVX512 {
            chunk_into::<K, C>(k, s, d)
        } else {
            chunk_into_avx2::<K, C>(k, s, d)
        }
    })
}

/// `run` on each pair of [`CHUNK_PIXELS`]-pixel chunks of `src` and `dst`.
fn chunked_into<const C: usize>(
    src: &[f32],
    dst: &mut [f32],
    threads: Threads,
    run: impl Fn(&[f32], &mut [f32]) + Sync,
) {
    let n = CHUNK_PIXELS * C;
    let run = |(s, d): (&[f32], &mut [f32])| run(s, d);
    match threads {
        Threads::All => src.par_chunks(n).zip(dst.par_chunks_mut(n)).for_each(run),
        Threads::Single => src.chunks(n).zip(dst.chunks_mut(n)).for_each(run),
    }
}

// Compiled three times: for the baseline target, for x86-64 with AVX2 + FMA and with AVX-512
// (F + VL, which add two-source permutes and 32 vector registers), chosen at run time (the
// `multiversion` crate detects the CPU once; no `unsafe` here). The baseline body is also called
// directly (`fma = false`, not inlined into a feature-enabled clone): that is what
// [`FastModel::apply_baseline`] runs (but for NSRM 3 and PRM 3 on packed RGB, whose SSE2 kernels
// give the same bits).
#[multiversion::multiversion(targets("x86_64+avx2+fma+avx512f+avx512vl", "x86_64+avx2+fma"))]
fn chunk_in_place<K: Chunks, const C: usize>(k: &K, data: &mut [f32]) {
    const FMA: bool = multiversion::target::selected_target!().supports_feature_str("fma");
    k.run_in_place::<C>(data, FMA)
}

/// [`chunk_in_place`] into a second chunk (the same clones).
#[multiversion::multiversion(targets("x86_64+avx2+fma+avx512f+avx512vl", "x86_64+avx2+fma"))]
fn chunk_into<K: Chunks, const C: usize>(k: &K, src: &[f32], dst: &mut [f32]) {
    const FMA: bool = multiversion::target::selected_target!().supports_feature_str("fma");
    k.run_into::<C>(src, dst, FMA)
}

/// [`chunk_in_place`] without the AVX-512 clone (kernels with `AVX512 = false`).
#[multiversion::multiversion(targets("x86_64+avx2+fma"))]
fn chunk_in_place_avx2<K: Chunks, const C: usize>(k: &K, data: &mut [f32]) {
    const FMA: bool = multiversion::target::selected_target!().supports_feature_str("fma");
    k.run_in_place::<C>(data, FMA)
}

/// [`chunk_into`] without the AVX-512 clone.
#[multiversion::multiversion(targets("x86_64+avx2+fma"))]
fn chunk_into_avx2<K: Chunks, const C: usize>(k: &K, src: &[f32], dst: &mut [f32]) {
    const FMA: bool = multiversion::target::selected_target!().supports_feature_str("fma");
    k.run_into::<C>(src, dst, FMA)
}

// ---------------------------------------------------------------------------------------------
// Scalar building blocks (inlined into the lane loops, so they must stay branch-free).
// ---------------------------------------------------------------------------------------------

/// `a·b + c`: one fused multiply-add where the target has FMA (`fma` is a compile-time constant
/// there), a multiply and an add otherwise (never libm's slow software `fmaf`).
#[inline(always)]
fn madd(a: f32, b: f32, c: f32, fma: bool) -> f32 {
    if fma {
        a.mul_add(b, c)
    } else {
        a * b + c
    }
}

/// The arithmetic the hand-written kernels' formulas are written in, so that one text serves the
/// per-pixel loop (`f32`, which LLVM's loop vectoriser widens) and the explicit-vector kernels
/// (`fast/explicit.rs`: a register of 8 pixels): the same operations in the same order give the same
/// bits.
trait Arith: Copy {
    /// Per-lane truth: `bool` for `f32`, a lane mask for a register.
    type Mask: Copy;
    fn mul(self, b: Self) -> Self;
    fn add(self, b: Self) -> Self;
    fn div(self, b: Self) -> Self;
    /// `self·b + c`: fused where `fma` ([`madd`]); a register is fused or not by its kind (the
    /// AVX2 + FMA one always, the SSE2 one never), as the code it stands for.
    fn madd(self, b: Self, c: Self, fma: bool) -> Self;
    /// `self ≤ 0` (false for NaN).
    fn le_zero(self) -> Self::Mask;
    /// `0` where `mask`, else `self`.
    fn zero_where(self, mask: Self::Mask) -> Self;
}

impl Arith for f32 {
    type Mask = bool;
    #[inline(always)]
    fn mul(self, b: f32) -> f32 {
        self * b
    }
    #[inline(always)]
    fn add(self, b: f32) -> f32 {
        self + b
    }
    #[inline(always)]
    fn div(self, b: f32) -> f32 {
        self / b
    }
    #[inline(always)]
    fn madd(self, b: f32, c: f32, fma: bool) -> f32 {
        madd(self, b, c, fma)
    }
    #[inline(always)]
    fn le_zero(self) -> bool {
        self <= 0.0
    }
    #[inline(always)]
    fn zero_where(self, mask: bool) -> f32 {
        if mask {
            0.0
        } else {
            self
        }
    }
}

/// `y_k = Σ_j m[k][j]·t[j]` for k = 0..3 over lane arrays, summed in term order: the shape the
/// vectoriser turns into packed multiply-adds.
#[inline(always)]
fn combine<const L: usize>(m: &[[f32; L]; 3], t: &[Lanes; L], fma: bool) -> [Lanes; 3] {
    let mut y = [[0.0; LANES]; 3];
    for (yk, mk) in y.iter_mut().zip(m) {
        for i in 0..LANES {
            let mut acc = mk[0] * t[0][i];
            for j in 1..L {
                acc = madd(mk[j], t[j][i], acc, fma);
            }
            yk[i] = acc;
        }
    }
    y
}

/// `Σ_j m[j]·t[j]` in term order (the first product rounded, then one multiply-add per term).
#[inline(always)]
fn dot<const L: usize>(m: &[f32; L], t: &[f32; L], fma: bool) -> f32 {
    let mut acc = m[0] * t[0];
    for j in 1..L {
        acc = madd(m[j], t[j], acc, fma);
    }
    acc
}

/// Sign-preserving square root: `sign(x)·√|x|`.
#[inline(always)]
fn sqrt_s(x: f32) -> f32 {
    x.abs().sqrt().copysign(x)
}

/// Sign-preserving fourth root.
#[inline(always)]
fn root4_s(x: f32) -> f32 {
    x.abs().sqrt().sqrt().copysign(x)
}

/// Bit pattern behind the first guess of `a^(-1/3)` (minimises the guess's worst relative error,
/// 3.4 %, over the normal f32 range).
const RCBRT_MAGIC: u32 = 0x54a2_3400;
/// Magnitudes below this are scaled by 2⁹⁶ first, so subnormals get a good first guess.
const CBRT_TINY: f32 = 1.0e-30;
const TWO_96: f32 = 79_228_162_514_264_337_593_543_950_336.0; // 2^96
const TWO_M32: f32 = 2.328_306_4e-10; // 2^-32 = ∛(2^-96)

/// `x/3` for `x < 2³¹` in shifts and adds only (`x/4·(1+1/4)(1+1/16)(1+1/256)(1+1/65536)`, low by
/// at most 6 units): a float-to-int conversion would not vectorise on baseline x86-64, nor would a
/// 32-bit multiply (SSE4.1).
#[inline(always)]
fn third(x: u32) -> u32 {
    let mut t = x >> 2;
    t += t >> 2;
    t += t >> 4;
    t += t >> 8;
    t += t >> 16;
    t
}

/// About `x/3` for `x < 2³¹` in one 32-bit multiply, `(x >> 16)·⌈2¹⁷/3⌉ / 2`: off by fewer than
/// 2.8·10⁴ units, which moves the first guess it feeds by at most 0.33 % (that guess is 3.4 % off
/// anyway). For targets with a packed 32-bit multiply (every FMA clone has AVX2): three
/// instructions instead of [`third`]'s nine.
#[inline(always)]
fn third_mul(x: u32) -> u32 {
    ((x >> 16) * 0xaaab) >> 1
}

/// Sign-preserving cube root without libm or division, branch-free: `z ≈ a^(-1/3)` from the bit
/// pattern, one third-order step `z ← z·(1 + e/3 + 2e²/9)`, `e = 1 − a·z³` (3.4 % → 2e-4),
/// `y = a·z²`, and one second-order correction of `y` itself, `y ← y·(1 − c/3 + 2c²/9)` with
/// `c = w² − 1`, `w = y·z` (`w² = y³/a`, so it never overflows). Max relative error about 1 ulp
/// over every f32, subnormals included (the unit test below bounds it by 1.3e-7);
/// `±0 → ±0`, `±∞ → ±∞`, NaN → NaN. This is `cbrt_m` without FMA (the baseline's bits).
#[inline(always)]
pub(crate) fn cbrt_s(x: f32) -> f32 {
    cbrt_m::<false>(x, false)
}

/// Whether `x` is 0 or finite of magnitude at least `CBRT_TINY`: the values for which
/// `cbrt_m::<true>` is right (integer compares on the bit pattern, no shuffles).
#[inline(always)]
fn cbrt_plain(x: f32) -> bool {
    let b = x.to_bits() & 0x7fff_ffff;
    let lo = CBRT_TINY.to_bits();
    b == 0 || b.wrapping_sub(lo) <= f32::MAX.to_bits() - lo
}

/// [`cbrt_s`] as the RPRM 3 kernel calls it. With `fma` (a compile-time constant in each clone)
/// the steps are fused multiply-adds, the first guess divides by 3 with a multiply
/// ([`third_mul`]) and the last correction is `y·(1 − d)^(-2/3) ≈ y·(1 + 2d/3 + 5d²/9)` with
/// `d = 1 − y·z` in one fused multiply-add (one multiply fewer; max relative error 9.6e-8).
/// `PLAIN` (a compile-time constant): `x` is 0 or finite of magnitude at least `CBRT_TINY`
/// ([`cbrt_plain`]), so the rescaling of tiny values and the ±∞ select are left out; for such `x`
/// the result is the same bits either way. The unit test checks every form.
#[inline(always)]
fn cbrt_m<const PLAIN: bool>(x: f32, fma: bool) -> f32 {
    let a = x.abs();
    let tiny = !PLAIN && a < CBRT_TINY;
    let s = if tiny { a * TWO_96 } else { a };
    let bits = s.to_bits();
    let t = if fma { third_mul(bits) } else { third(bits) };
    let z = f32::from_bits(RCBRT_MAGIC.wrapping_sub(t));
    // One third-order step: with e = 1 − a·z³, a^(-1/3) = z·(1 − e)^(-1/3) ≈ z·(1 + e/3 + 2e²/9)
    // (3.4 % → 2e-4), in five multiply-adds and multiplies instead of two Newton steps' ten.
    let z2 = z * z;
    let e = madd(-s, z2 * z, 1.0, fma);
    let z = madd(z * e, madd(e, 2.0 / 9.0, 1.0 / 3.0, fma), z, fma);
    let y = s * z * z;
    let y = if fma {
        // y = a·z² and a·z³ = 1 − d, so a^(1/3) = y·(1 − d)^(-2/3), to second order in d.
        let d = madd(-y, z, 1.0, fma);
        madd(y * d, madd(d, 5.0 / 9.0, 2.0 / 3.0, fma), y, fma)
    } else {
        // y·(y³/a)^(-1/3) to second order in c = y³/a − 1 = w² − 1 (w = y·z, so w² = y³/a):
        // y·(1 − c/3 + 2c²/9), which leaves an error of order c³ (≈ 1e-10 from c ≈ 1e-3).
        let w = y * z;
        let c = madd(w, w, -1.0, fma);
        madd(y * c, madd(c, 2.0 / 9.0, -1.0 / 3.0, fma), y, fma)
    };
    if PLAIN {
        return y.copysign(x);
    }
    let y = y * if tiny { TWO_M32 } else { 1.0 };
    // ±∞ → ±∞ and NaN → NaN (the iteration would not keep them); ±0 → ±0 comes out of a·z².
    let y = if a.is_finite() { y } else { a };
    y.copysign(x)
}

/// The pixels of a block multiplied by NSRM's input gains (exact for a gain of 1).
#[inline(always)]
fn gained(x: &[Lanes; 3], gain: &[f32; 3]) -> [Lanes; 3] {
    let mut y = [[0.0; LANES]; 3];
    for c in 0..3 {
        for i in 0..LANES {
            y[c][i] = x[c][i] * gain[c];
        }
    }
    y
}

/// NSRM's `s = R+G+B`, `r = R/s`, `g = G/s`, and whether the pixel takes the `s ≤ 0 → 0` rule.
#[inline(always)]
fn nsrm_signal(r: f32, g: f32, b: f32) -> (f32, f32, f32, bool) {
    let s = r + g + b;
    // NaN is not ≤ 0: it goes through and propagates.
    let black = s <= 0.0;
    (s, r / s, g / s, black)
}

// ---------------------------------------------------------------------------------------------
// Hand-written kernels. Each declares (`Declared`) the steps and the terms, in its own column
// order, that its arithmetic computes; `Kernel::choose` maps the program's columns onto them
// (fast_tests.rs checks every kernel against the f64 reference).
// ---------------------------------------------------------------------------------------------

/// LRM, PRM 1, RPRM 1: `(R, G, B)`.
#[derive(Debug, Clone)]
struct Linear {
    m: [[f32; 3]; 3],
}

impl Declared for Linear {
    const STEPS: &'static [Step] = &[Step::Combine];
    const TERMS: &'static [Term] = &[term([1, 0, 0], 1), term([0, 1, 0], 1), term([0, 0, 1], 1)];
}

impl PixelKernel for Linear {
    #[inline(always)]
    fn pixel<const STEP_OK: bool>(&self, x: [f32; 3], fma: bool) -> [f32; 3] {
        let mut y = [0.0; 3];
        for (yk, m) in y.iter_mut().zip(&self.m) {
            *yk = dot(m, &x, fma);
        }
        y
    }
}

/// PRM 3: `R G B R² G² B² RG GB BR R³ G³ B³ RG² RB² GB² GR² BR² BG² RGB` (eq. (3)).
#[derive(Debug, Clone)]
struct Prm3 {
    m: [[f32; 19]; 3],
    /// This CPU's explicit-vector kernel for packed RGB, if any.
    explicit: Option<Explicit>,
}

impl Declared for Prm3 {
    const STEPS: &'static [Step] = &[Step::Combine];
    const TERMS: &'static [Term] = &[
        term([1, 0, 0], 1),
        term([0, 1, 0], 1),
        term([0, 0, 1], 1),
        term([2, 0, 0], 1),
        term([0, 2, 0], 1),
        term([0, 0, 2], 1),
        term([1, 1, 0], 1),
        term([0, 1, 1], 1),
        term([1, 0, 1], 1),
        term([3, 0, 0], 1),
        term([0, 3, 0], 1),
        term([0, 0, 3], 1),
        term([1, 2, 0], 1),
        term([1, 0, 2], 1),
        term([0, 1, 2], 1),
        term([2, 1, 0], 1),
        term([2, 0, 1], 1),
        term([0, 2, 1], 1),
        term([1, 1, 1], 1),
    ];
}

impl PixelKernel for Prm3 {
    // A block of LANES pixels with a non-finite input (or a sum that overflows) keeps the term
    // sums, which give exactly the f64 reference's NaN/±∞ (a nested form turns ∞·0 terms into
    // ±∞). The step test is a cheap sufficient one; a step that fails it is tested again block by
    // block, exactly.
    const STEPPED: bool = true;

    #[inline(always)]
    fn step_ok(blk: &[f32]) -> bool {
        quick_finite(blk)
    }

    #[inline(always)]
    fn slow_in_place<const C: usize>(&self, blk: &mut [f32], fma: bool) {
        for b in blk.chunks_mut(C * LANES) {
            guarded_block::<Self, C>(self, b, fma);
        }
    }

    #[inline(always)]
    fn pixel<const STEP_OK: bool>(&self, [r, g, b]: [f32; 3], fma: bool) -> [f32; 3] {
        prm3_nested(&self.m, [r, g, b], fma)
    }

    /// The 19 terms, then their sums in term order.
    #[inline(always)]
    fn fallback(&self, x: &[Lanes; 3], fma: bool) -> [Lanes; 3] {
        let mut t = [[0.0; LANES]; 19];
        for i in 0..LANES {
            let (r, g, b) = (x[0][i], x[1][i], x[2][i]);
            let (r2, g2, b2) = (r * r, g * g, b * b);
            let (rg, gb) = (r * g, g * b);
            let v = [
                r,
                g,
                b,
                r2,
                g2,
                b2,
                rg,
                gb,
                r * b,
                r2 * r,
                g2 * g,
                b2 * b,
                r * g2,
                r * b2,
                g * b2,
                r2 * g,
                r2 * b,
                g2 * b,
                rg * b,
            ];
            for (tj, vj) in t.iter_mut().zip(v) {
                tj[i] = vj;
            }
        }
        combine(&self.m, &t, fma)
    }
}

/// Whether every lane of R, G, B is finite and so is their sum.
#[inline(always)]
fn all_finite(x: &[Lanes; 3]) -> bool {
    let mut ok = true;
    for i in 0..LANES {
        // ∞·0 and NaN·0 are NaN, finite·0 is 0.
        ok &= (x[0][i] + x[1][i] + x[2][i]) * 0.0 == 0.0;
    }
    ok
}

/// PRM 3 in the nested (multivariate Horner) form, one multiply-add per coefficient and one
/// multiply per channel:
///   y = R·(m0 + R(m3 + R·m9 + G·m15 + B·m16) + G(m6 + G·m12 + B·m18) + B(m8 + B·m13))
///     + G·(m1 + G(m4 + G·m10 + B·m17) + B(m7 + B·m14)) + B·(m2 + B(m5 + B·m11))
/// (term indices of the eq. (3) order: 15 R²G, 16 R²B, 17 G²B). Right on finite pixels only.
#[inline(always)]
fn prm3_nested<A: Arith>(m: &[[A; 19]; 3], [r, g, b]: [A; 3], fma: bool) -> [A; 3] {
    let mut y = [r; 3];
    for (yk, m) in y.iter_mut().zip(m) {
        let a = b.madd(m[16], g.madd(m[15], r.madd(m[9], m[3], fma), fma), fma);
        let bb = b.madd(m[18], g.madd(m[12], m[6], fma), fma);
        let c = b.madd(m[13], m[8], fma);
        let pr = b.madd(c, g.madd(bb, r.madd(a, m[0], fma), fma), fma);
        let d = b.madd(m[17], g.madd(m[10], m[4], fma), fma);
        let e = b.madd(m[14], m[7], fma);
        let pg = b.madd(e, g.madd(d, m[1], fma), fma);
        let pb = b.madd(b.madd(m[11], m[5], fma), m[2], fma);
        *yk = r.madd(pr, g.madd(pg, b.mul(pb), fma), fma);
    }
    y
}

/// RPRM 3: `R G B √(RG) √(GB) √(RB) ∛(RG²) ∛(RB²) ∛(GB²) ∛(GR²) ∛(BG²) ∛(BR²) ∛(RGB)`, from three
/// square roots and three cube roots.
#[derive(Debug, Clone)]
struct Rprm3 {
    m: [[f32; 13]; 3],
}

impl Declared for Rprm3 {
    const STEPS: &'static [Step] = &[Step::Combine];
    const TERMS: &'static [Term] = &[
        term([1, 0, 0], 1),
        term([0, 1, 0], 1),
        term([0, 0, 1], 1),
        term([1, 1, 0], 2),
        term([0, 1, 1], 2),
        term([1, 0, 1], 2),
        term([1, 2, 0], 3),
        term([1, 0, 2], 3),
        term([0, 1, 2], 3),
        term([2, 1, 0], 3),
        term([0, 2, 1], 3),
        term([2, 0, 1], 3),
        term([1, 1, 1], 3),
    ];
}

impl PixelKernel for Rprm3 {
    // Steps whose values are all 0 or finite magnitudes of at least CBRT_TINY skip the cube
    // root's rescaling of tiny values and its ±∞ select (the same result there).
    const STEPPED: bool = true;

    #[inline(always)]
    fn step_ok(blk: &[f32]) -> bool {
        let mut ok = true;
        for &v in blk {
            ok &= cbrt_plain(v);
        }
        ok
    }

    #[inline(always)]
    fn pixel<const STEP_OK: bool>(&self, [r, g, b]: [f32; 3], fma: bool) -> [f32; 3] {
        // The six roots, the 13 terms (products of roots) and their three sums.
        let (sr, sg, sb) = (sqrt_s(r), sqrt_s(g), sqrt_s(b));
        let (cr, cg, cb) = (
            cbrt_m::<STEP_OK>(r, fma),
            cbrt_m::<STEP_OK>(g, fma),
            cbrt_m::<STEP_OK>(b, fma),
        );
        let (cr2, cg2, cb2) = (cr * cr, cg * cg, cb * cb);
        let t = [
            r,
            g,
            b,
            sr * sg,
            sg * sb,
            sr * sb,
            cr * cg2,
            cr * cb2,
            cg * cb2,
            cr2 * cg,
            cg2 * cb,
            cr2 * cb,
            cr * cg * cb,
        ];
        let mut y = [0.0; 3];
        for (yk, m) in y.iter_mut().zip(&self.m) {
            *yk = dot(m, &t, fma);
        }
        y
    }
}

/// NSRM 3: `s·M·(1 r g r² g² rg r³ g³ rg² r²g)`, `r = R/s`, `g = G/s`, `s = R+G+B`, with
/// R, G, B multiplied by the input gains first (1 unless white-balanced).
#[derive(Debug, Clone)]
struct Nsrm3 {
    m: [[f32; 10]; 3],
    gain: [f32; 3],
    /// This CPU's explicit-vector kernel for packed RGB, if any.
    explicit: Option<Explicit>,
}

impl Declared for Nsrm3 {
    const STEPS: &'static [Step] = &[Step::Gain, Step::Normalise, Step::Combine, Step::Rescale];
    const TERMS: &'static [Term] = &[
        term([0, 0, 0], 1),
        term([1, 0, 0], 1),
        term([0, 1, 0], 1),
        term([2, 0, 0], 1),
        term([0, 2, 0], 1),
        term([1, 1, 0], 1),
        term([3, 0, 0], 1),
        term([0, 3, 0], 1),
        term([1, 2, 0], 1),
        term([2, 1, 0], 1),
    ];
}

impl PixelKernel for Nsrm3 {
    #[inline(always)]
    fn pixel<const STEP_OK: bool>(&self, x: [f32; 3], fma: bool) -> [f32; 3] {
        nsrm3_back(&self.m, nsrm3_front(&self.gain, x), fma)
    }
}

/// What NSRM 3's first half leaves for its second: the input channels times their gains
/// (`R`, `G`), `s`, `r`, `g` and whether the pixel takes the `s ≤ 0 → 0` rule.
#[derive(Clone, Copy)]
struct NsrmSignal<A: Arith> {
    cr: A,
    cg: A,
    s: A,
    r: A,
    g: A,
    black: A::Mask,
}

/// NSRM 3's first half: the input gains (white-balanced NSRM; exact for a gain of 1),
/// `s = R+G+B`, `r = R/s`, `g = G/s` and the `s ≤ 0` rule (NaN is not ≤ 0: it goes through and
/// propagates). The explicit-vector kernel issues the next block's first half before this
/// block's second, so its divisions overlap the multiply-adds.
#[inline(always)]
fn nsrm3_front<A: Arith>(gain: &[A; 3], x: [A; 3]) -> NsrmSignal<A> {
    let (cr, cg, cb) = (x[0].mul(gain[0]), x[1].mul(gain[1]), x[2].mul(gain[2]));
    let s = cr.add(cg).add(cb);
    NsrmSignal {
        cr,
        cg,
        s,
        r: cr.div(s),
        g: cg.div(s),
        black: s.le_zero(),
    }
}

/// NSRM 3's second half: `s·(m0 + r·A + g·B + r·g·C)` with `s·r = R`, `s·g = G`, i.e. the terms
/// 1 r g r² g² rg r³ g³ rg² r²g as `m0·s + R·A + G·B + (R·g)·C`, `A = m1 + r(m3 + r·m6)`,
/// `B = m2 + g(m4 + g·m7)`, `C = m5 + g·m8 + r·m9`: 9 multiply-adds and 1 multiply a channel.
#[inline(always)]
fn nsrm3_back<A: Arith>(m: &[[A; 10]; 3], p: NsrmSignal<A>, fma: bool) -> [A; 3] {
    let NsrmSignal {
        cr,
        cg,
        s,
        r,
        g,
        black,
    } = p;
    let rg = cr.mul(g);
    let mut y = [s; 3];
    for (yk, m) in y.iter_mut().zip(m) {
        let a = r.madd(r.madd(m[6], m[3], fma), m[1], fma);
        let b = g.madd(g.madd(m[7], m[4], fma), m[2], fma);
        let c = r.madd(m[9], g.madd(m[8], m[5], fma), fma);
        let v = cr.madd(a, m[0].mul(s), fma);
        let v = cg.madd(b, v, fma);
        let v = rg.madd(c, v, fma);
        *yk = v.zero_where(black);
    }
    y
}

// ---------------------------------------------------------------------------------------------
// The generic kernel: a product plan over lane arrays.
// ---------------------------------------------------------------------------------------------

/// Slot 0 holds 1.0 in every lane.
const ONE: usize = 0;

/// Every term of any list as products of two earlier values, evaluated a block at a time.
#[derive(Debug, Clone)]
struct Plan {
    /// The program's gain step: the input gains multiplied into R, G, B first.
    gain: Option<[f32; 3]>,
    /// The program's normalise step: `s = R+G+B`, the black rule, the variables `(r, g)`.
    normalise: bool,
    /// The program's rescale step: the output times `s`.
    rescale: bool,
    /// `(channel, root, slot)`: the per-channel roots to compute first.
    bases: Vec<(usize, u8, usize)>,
    /// `(dst, a, b)`: `v[dst] = v[a]·v[b]`, in dependency order.
    steps: Vec<(usize, usize, usize)>,
    /// The slot of each term.
    term_slots: Vec<usize>,
    /// Number of slots used.
    slots: usize,
    /// Row-major 3×L matrix in f32.
    m: Vec<f32>,
}

impl Plan {
    /// The plan of a pixel program (a well-formed one: every root 1..=4, no `x₂` after the
    /// normalise step): its policy flags read from its steps, its products from its terms.
    fn new(program: &Program<'_>, matrix: &[f64], gains: [f64; 3]) -> Plan {
        debug_assert_eq!(program.check(), Ok(()));
        let mut bases = Vec::new();
        let mut steps = Vec::new();
        // (exponents, root) → slot; the empty monomial is the constant 1 whatever the root.
        let mut known: HashMap<([u8; 3], u8), usize> = HashMap::new();
        let mut slots = 1;
        let term_slots = program
            .terms
            .iter()
            .map(|t| {
                plan_monomial(
                    t.exps, t.root, &mut known, &mut bases, &mut steps, &mut slots,
                )
            })
            .collect();
        Plan {
            gain: program.has(Step::Gain).then(|| gains.map(|v| v as f32)),
            normalise: program.has(Step::Normalise),
            rescale: program.has(Step::Rescale),
            bases,
            steps,
            term_slots,
            slots,
            m: matrix.iter().map(|&v| v as f32).collect(),
        }
    }
}

/// The slot holding `Π_c root(x_c)^exps[c]`, adding the steps that compute it (memoised).
fn plan_monomial(
    exps: [u8; 3],
    root: u8,
    known: &mut HashMap<([u8; 3], u8), usize>,
    bases: &mut Vec<(usize, u8, usize)>,
    steps: &mut Vec<(usize, usize, usize)>,
    slots: &mut usize,
) -> usize {
    if exps == [0; 3] {
        return ONE;
    }
    if let Some(&s) = known.get(&(exps, root)) {
        return s;
    }
    let degree: u8 = exps.iter().sum();
    let slot = if degree == 1 {
        let c = exps.iter().position(|&e| e == 1).unwrap_or(0);
        let s = *slots;
        bases.push((c, root, s));
        s
    } else {
        // Split into the larger half and the rest: x^4 = x²·x², R²G = (RG)·R, so the product
        // tree is shallow and shares sub-products between terms.
        let mut half = [0u8; 3];
        let mut left = degree / 2;
        for c in 0..3 {
            let take = exps[c].min(left);
            half[c] = take;
            left -= take;
        }
        let rest = [exps[0] - half[0], exps[1] - half[1], exps[2] - half[2]];
        let a = plan_monomial(half, root, known, bases, steps, slots);
        let b = plan_monomial(rest, root, known, bases, steps, slots);
        let s = *slots;
        steps.push((s, a, b));
        s
    };
    *slots += 1;
    known.insert((exps, root), slot);
    slot
}

impl BlockKernel for Plan {
    type Scratch = Vec<Lanes>;

    fn scratch(&self) -> Vec<Lanes> {
        let mut v = vec![[0.0; LANES]; self.slots.max(1)];
        v[ONE] = [1.0; LANES];
        v
    }

    #[inline(always)]
    fn block(&self, x: &[Lanes; 3], v: &mut Vec<Lanes>, _fma: bool) -> [Lanes; 3] {
        let mut scale = [1.0f32; LANES];
        let mut black = [false; LANES];
        let mut vars = match &self.gain {
            Some(g) => gained(x, g),
            None => *x,
        };
        if self.normalise {
            let x = vars;
            for i in 0..LANES {
                let (s, r, g, k) = nsrm_signal(x[0][i], x[1][i], x[2][i]);
                scale[i] = s;
                vars[0][i] = r;
                vars[1][i] = g;
                black[i] = k;
            }
        }
        for &(c, root, slot) in &self.bases {
            let src = vars[c];
            let dst = &mut v[slot];
            match root {
                1 => *dst = src,
                2 => {
                    for i in 0..LANES {
                        dst[i] = sqrt_s(src[i]);
                    }
                }
                3 => {
                    for i in 0..LANES {
                        // Not `cbrt_m(·, fma)`: in these lane loops LLVM left parts of the
                        // fused form scalar (RPRM 4 ran a third slower).
                        dst[i] = cbrt_s(src[i]);
                    }
                }
                _ => {
                    for i in 0..LANES {
                        dst[i] = root4_s(src[i]);
                    }
                }
            }
        }
        for &(d, a, b) in &self.steps {
            let (va, vb) = (v[a], v[b]);
            let dst = &mut v[d];
            for i in 0..LANES {
                dst[i] = va[i] * vb[i];
            }
        }
        // Three accumulators kept in registers across the term loop; term order as in the list.
        let l = self.term_slots.len();
        let (m0, m1, m2) = (&self.m[..l], &self.m[l..2 * l], &self.m[2 * l..3 * l]);
        let mut y = [[0.0; LANES]; 3];
        for (j, &slot) in self.term_slots.iter().enumerate() {
            let t = &v[slot];
            let (c0, c1, c2) = (m0[j], m1[j], m2[j]);
            for i in 0..LANES {
                y[0][i] += c0 * t[i];
                y[1][i] += c1 * t[i];
                y[2][i] += c2 * t[i];
            }
        }
        if self.normalise {
            let rescale = self.rescale;
            for yk in &mut y {
                for i in 0..LANES {
                    let v = if rescale { scale[i] * yk[i] } else { yk[i] };
                    yk[i] = if black[i] { 0.0 } else { v };
                }
            }
        }
        y
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::terms::terms;
    use crate::model::{Kind, MAX_ORDER};

    #[test]
    fn cbrt_is_accurate_and_keeps_special_values() {
        // Both forms: the baseline's (`cbrt_s`) and the FMA clones' (here with libm's `fmaf`,
        // which rounds exactly as the FMA instructions do).
        for fma in [false, true] {
            let cbrt = |v: f32| cbrt_m::<false>(v, fma);
            let mut worst = 0.0f64;
            let mut x = f32::MIN_POSITIVE / 1024.0;
            while x < f32::MAX / 1.01 {
                for v in [x, -x] {
                    let got = cbrt(v) as f64;
                    let want = (v as f64).cbrt();
                    worst = worst.max((got / want - 1.0).abs());
                }
                x *= 1.000_37;
            }
            assert!(
                worst < 1.3e-7,
                "cbrt (fma {fma}) worst relative error {worst:e}"
            );
            // The plain form where it applies: the same bits (0 included).
            let mut x = CBRT_TINY;
            while x < f32::MAX / 1.01 {
                for v in [x, -x] {
                    assert!(cbrt_plain(v));
                    assert_eq!(cbrt_m::<true>(v, fma).to_bits(), cbrt(v).to_bits(), "{v:e}");
                }
                x *= 1.000_37;
            }
            for v in [0.0f32, -0.0, f32::MAX, -f32::MAX] {
                assert!(cbrt_plain(v));
                assert_eq!(cbrt_m::<true>(v, fma).to_bits(), cbrt(v).to_bits(), "{v:e}");
            }
            for v in [
                CBRT_TINY / 1.001,
                1e-40,
                f32::INFINITY,
                f32::NEG_INFINITY,
                f32::NAN,
            ] {
                assert!(!cbrt_plain(v), "{v:e}");
            }
            assert_eq!(cbrt(0.0).to_bits(), 0.0f32.to_bits());
            assert_eq!(cbrt(-0.0).to_bits(), (-0.0f32).to_bits());
            assert_eq!(cbrt(f32::INFINITY), f32::INFINITY);
            assert_eq!(cbrt(f32::NEG_INFINITY), f32::NEG_INFINITY);
            assert!(cbrt(f32::NAN).is_nan());
            assert_eq!(cbrt(-8.0), -2.0);
            assert_eq!(cbrt(27.0), 3.0);
        }
    }

    #[test]
    fn every_standard_model_gets_a_kernel_and_plans_fit() {
        for kind in Kind::ALL {
            for order in 1..=MAX_ORDER {
                let order = kind.effective_order(order);
                let t = terms(kind, order);
                let m = Model::from_matrix(kind, order, vec![0.5; 3 * t.len()]).unwrap();
                let f = FastModel::new(&m);
                let expect = match (kind, order) {
                    (Kind::Lrm, _) | (Kind::Prm, 1) | (Kind::Rprm, 1) => "linear",
                    (Kind::Prm, 3) => "prm3",
                    (Kind::Rprm, 3) => "rprm3",
                    (Kind::Nsrm, 3) => "nsrm3",
                    _ => "plan",
                };
                assert_eq!(f.kernel_name(), expect, "{kind} {order}");
                // The generic plan can also take every standard list (used by the tests).
                let plan = Plan::new(&m.program(), &m.matrix, m.input_gains);
                assert!(
                    plan.slots <= 2 * t.len() + 8,
                    "{kind} {order}: {}",
                    plan.slots
                );
                // One multiplication per non-linear monomial, at most.
                assert!(
                    plan.steps.len() <= t.len() + 8,
                    "{kind} {order}: {}",
                    plan.steps.len()
                );
            }
        }
    }

    /// Pixels for the declaration tests: ordinary, negative channels, s ≤ 0, tiny, NaN, ±∞.
    const PIXELS: [[f32; 3]; 9] = [
        [0.2, 0.3, 0.25],
        [0.7, 0.05, 0.4],
        [0.4, -0.05, 0.3],
        [-0.1, -0.05, 0.6],
        [0.1, -0.2, 0.05],
        [1e-30, 2e-30, 3e-30],
        [2e3, 3e3, 2.5e3],
        [f32::NAN, 0.2, 0.3],
        [f32::INFINITY, 0.2, 0.3],
    ];

    /// `got` against the f64 evaluation of `program` (rounded once): NaN for NaN, the same ±∞,
    /// else within 1e-5 relative to the summands' size.
    fn assert_follows(
        program: &Program<'_>,
        matrix: &[f64],
        gains: [f64; 3],
        x: [f32; 3],
        got: [f32; 3],
        what: &str,
    ) {
        let x64 = x.map(|v| v as f64);
        let mut p = vec![0.0; program.terms.len()];
        let want = program.eval(matrix, gains, x64, &mut p);
        let scale = program.features(gains, x64, &mut p).unwrap_or(0.0).abs();
        let l = p.len();
        for k in 0..3 {
            let (g, w) = (got[k] as f64, want[k]);
            let size: f64 = (0..l)
                .map(|j| (matrix[k * l + j] * p[j]).abs())
                .sum::<f64>()
                * scale;
            let ok = if w.is_nan() {
                g.is_nan()
            } else if w.is_infinite() {
                !g.is_finite()
            } else {
                (g - w).abs() <= 1e-5 * w.abs().max(size) + 1e-30
            };
            assert!(ok, "{what}: pixel {x:?} channel {k}: got {g}, program {w}");
        }
    }

    /// Each hand-written kernel's arithmetic is what it declares: with a matrix that picks one
    /// column per output, its output is that declared term under the declared steps, as the f64
    /// evaluator computes the declaration. (The kernels are chosen by their declaration, so this
    /// and the index map tie them to the one description.)
    #[test]
    fn hand_kernels_compute_what_they_declare() {
        fn check<K: Declared + PixelKernel, const L: usize>(make: impl Fn([[f32; L]; 3]) -> K) {
            let kind = if K::STEPS.contains(&Step::Normalise) {
                Kind::Nsrm
            } else {
                Kind::Rprm
            };
            let program = Program::custom(kind, K::STEPS, K::TERMS).unwrap();
            assert_eq!(K::TERMS.len(), L);
            for j in 0..L {
                // Output k picks column (j + k) mod L, weighted 1, 2, 3.
                let mut m = [[0.0f32; L]; 3];
                let mut matrix = vec![0.0f64; 3 * L];
                for k in 0..3 {
                    let c = (j + k) % L;
                    m[k][c] = (k + 1) as f32;
                    matrix[k * L + c] = (k + 1) as f64;
                }
                let kernel = make(m);
                // Finite pixels: a per-pixel kernel may leave non-finite ones to its chunk loop's
                // fallback (PRM 3), which `kernels_follow_the_program_not_the_kind` runs.
                for x in PIXELS
                    .into_iter()
                    .filter(|x| x.iter().all(|v| v.is_finite()))
                {
                    for fma in [false, true] {
                        let got = kernel.pixel::<false>(x, fma);
                        let what = format!("{} column {j} fma {fma}", std::any::type_name::<K>());
                        assert_follows(&program, &matrix, [1.0; 3], x, got, &what);
                    }
                }
            }
        }
        check::<Linear, 3>(|m| Linear { m });
        check::<Prm3, 19>(|m| Prm3 { m, explicit: None });
        check::<Rprm3, 13>(|m| Rprm3 { m });
        check::<Nsrm3, 10>(|m| Nsrm3 {
            m,
            gain: [1.0; 3],
            explicit: None,
        });
    }

    /// Runs `kernel` (baseline and detected code) on [`PIXELS`] and holds it to `program`.
    fn run_against(program: &Program<'_>, matrix: &[f64], gains: [f64; 3], name: &str) {
        let kernel = Kernel::choose(program, matrix, gains);
        let fast = FastModel {
            kernel,
            highlights: None,
        };
        assert_eq!(fast.kernel_name(), name, "{program:?}");
        let data: Vec<f32> = PIXELS.iter().flatten().copied().collect();
        for baseline in [false, true] {
            let mut f = Frame::from_data(PIXELS.len(), 1, Layout::Rgb, data.clone()).unwrap();
            if baseline {
                fast.apply_baseline(&mut f, Threads::Single);
            } else {
                fast.apply(&mut f, Threads::Single);
            }
            for (x, got) in PIXELS.iter().zip(f.data.chunks_exact(3)) {
                let what = format!("{name} (baseline {baseline}) on {program:?}");
                assert_follows(program, matrix, gains, *x, [got[0], got[1], got[2]], &what);
            }
        }
    }

    /// The fast path follows the program it is given, not the kind: programs that are no kind's
    /// (another policy over a kind's terms, a kind's terms in another order) run the generic plan
    /// with the program's flags, or a hand-written kernel through the index map, and agree with
    /// the f64 evaluator.
    #[test]
    fn kernels_follow_the_program_not_the_kind() {
        let matrix = |l: usize| -> Vec<f64> {
            (0..3 * l)
                .map(|i| 0.3 + ((i * 7) % 11) as f64 * 0.1 - 0.4)
                .collect()
        };
        let gains = [1.5, 1.0, 0.75];
        // A kind's terms in reverse order: the hand-written kernels through their index maps.
        for (kind, order, name) in [
            (Kind::Prm, 3, "prm3"),
            (Kind::Rprm, 3, "rprm3"),
            (Kind::Nsrm, 3, "nsrm3"),
            (Kind::Prm, 1, "linear"),
        ] {
            let mut t = terms(kind, order);
            t.reverse();
            let p = Program::custom(kind, Program::steps_of(kind), &t).unwrap();
            let g = if kind == Kind::Nsrm { gains } else { [1.0; 3] };
            run_against(&p, &matrix(t.len()), g, name);
        }
        // Another policy: the plan, with the program's flags.
        let nsrm3 = terms(Kind::Nsrm, 3);
        let nsrm2 = terms(Kind::Nsrm, 2);
        let rprm2 = terms(Kind::Rprm, 2);
        for p in [
            Program::custom(
                Kind::Nsrm,
                &[Step::Normalise, Step::Combine, Step::Rescale],
                &nsrm3,
            ),
            Program::custom(
                Kind::Nsrm,
                &[Step::Gain, Step::Normalise, Step::Combine],
                &nsrm2,
            ),
            Program::custom(Kind::Nsrm, &[Step::Combine], &nsrm2),
            Program::custom(Kind::Rprm, &[Step::Gain, Step::Combine], &rprm2),
        ] {
            let p = p.unwrap();
            run_against(&p, &matrix(p.terms.len()), gains, "plan");
        }
    }

    #[test]
    fn apply_into_checks_shapes() {
        let m = Model::from_matrix(
            Kind::Lrm,
            1,
            vec![1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        )
        .unwrap();
        let f = FastModel::new(&m);
        let src = Frame::new(4, 3, Layout::Rgb);
        let mut dst = Frame::new(3, 4, Layout::Rgb);
        assert!(matches!(
            f.apply_into(&src, &mut dst, Threads::All),
            Err(FastError::FrameMismatch { .. })
        ));
        let mut dst = Frame::new(4, 3, Layout::Rgb);
        dst.data.pop();
        assert!(matches!(
            f.apply_into(&src, &mut dst, Threads::Single),
            Err(FastError::FrameLength {
                expected: 36,
                len: 35,
                ..
            })
        ));
    }
}
