//! Explicit-vector kernels for NSRM 3 and PRM 3 on packed RGB (x86-64): AVX2 + FMA on CPUs
//! without AVX-512, SSE2 where the CPU has no AVX2 + FMA (and for the baseline code).
//!
//! The per-pixel kernels leave the de-interleave to LLVM's loop vectoriser, which reads a
//! stride-3 block of 8 pixels as three 256-bit loads put apart by lane-crossing permutes and
//! blends (28 shuffles a block, in and out), and evaluates one block at a time, so NSRM's
//! multiply-adds wait on its two divisions (about 11 cycles each on AMD Zen 3) while the
//! out-of-order window holds little else. Here:
//! * a block of 8 pixels is de-interleaved with in-lane shuffles only: AVX2 loads it as six
//!   128-bit quarters paired into three registers (pixels 0–3 in the low lanes, 4–7 in the high
//!   lanes) and needs five `vshufps` (six and three `vperm2f128` on the way back); SSE2 takes it
//!   as two halves of 4 pixels, five `shufps` each (six on the way back);
//! * the loop is software-pipelined by one block: the next block's load and first half (NSRM's
//!   sum and divisions) are issued before this block's second half, so the divider works while
//!   the multiply pipes do;
//! * each iteration asks for the block [`PREFETCH_BLOCKS`] ahead (`prefetcht0`, a hint), so
//!   that on a frame larger than the caches the loads meet lines already on their way while the
//!   arithmetic runs;
//! * PRM 3 tests each block once on its registers (every value below `f32::MAX / 4`); a block
//!   that fails takes the per-pixel kernel's exact path (`guarded_block`: the term sums where a
//!   value is not finite), as the per-pixel loop does.
//!
//! The arithmetic is the per-pixel kernels' own text: [`nsrm3_front`], [`nsrm3_back`] and
//! [`prm3_nested`] are generic over [`Arith`], here over a register of 8 pixels, so every
//! operation is the per-pixel code's, in the same order — fused multiply-adds where the
//! per-pixel code would run its AVX2 + FMA clone, a multiply and an add where it would run its
//! baseline code — and the output is the same bits (`fast_tests.rs` checks both on frames of
//! awkward pixels; NaN payloads aside: where two different NaNs meet, which one comes out is the
//! compiler's choice on either path). A chunk's last partial block goes through the per-pixel
//! code.
//!
//! The intrinsics are [`pulp`]'s safe wrappers: `V3::try_new` / `V1::try_new` check the CPU
//! once, and `vectorize` runs the loop inside a function compiled for that instruction set, so
//! this crate keeps `forbid(unsafe_code)`. The loop is a [`NullaryFnOnce`] operation and
//! everything it calls is `#[inline(always)]`, with no closures: a closure that LLVM does not
//! inline is a function of its own, compiled without the instruction set, and every intrinsic in
//! it stays a call (20–60× slower). On a CPU with AVX-512 F + VL the per-pixel kernels' own
//! clone runs instead (the AVX-512 one, 16 pixels a register and 32 registers, where the CPU has
//! everything that clone needs): these kernels were measured only where AVX-512 is absent.

use super::{
    chunk_in_place_avx2, chunk_into_avx2, guarded_block, map_in_place, nsrm3_back, nsrm3_front,
    prm3_nested, Arith, Chunks, Nsrm3, NsrmSignal, Prm3, SUM_SAFE,
};
use pulp::x86::{V1, V3};
use pulp::NullaryFnOnce;
use std::arch::x86_64::{__m128, __m256, _CMP_LE_OQ, _CMP_LT_OQ, _MM_HINT_T0};

/// Floats per block: 8 RGB pixels, one register (or two SSE registers) per channel.
const FLOATS: usize = 24;

/// A register of 8 pixels' values of one channel on one instruction set, with the CPU token that
/// lets it compute.
pub(super) trait Reg: Arith {
    /// The instruction set's token.
    type Cpu: Copy;
    /// Whether multiply-adds are fused (the per-pixel code these registers stand for).
    const FMA: bool;
    fn splat(cpu: Self::Cpu, v: f32) -> Self;
    /// One block de-interleaved into R, G, B registers (pixel order in each).
    fn load(cpu: Self::Cpu, b: &[f32; FLOATS]) -> [Self; 3];
    /// [`load`](Self::load)'s inverse.
    fn store(cpu: Self::Cpu, y: [Self; 3], out: &mut [f32; FLOATS]);
    /// Whether every value of `x` is below `limit` in magnitude (NaN is not).
    fn all_below(cpu: Self::Cpu, x: &[Self; 3], limit: f32) -> bool;
    /// The per-pixel code, as the chunk loop would run it, on a chunk's last partial block.
    fn tail_into<K: Chunks>(k: &K, src: &[f32], dst: &mut [f32]);
    /// [`tail_into`](Self::tail_into) in place.
    fn tail_in_place<K: Chunks>(k: &K, data: &mut [f32]);
    /// Asks for the cache line holding `b`'s first float (a hint: no fault, no result).
    fn prefetch(cpu: Self::Cpu, b: &[f32]);
}

/// How far ahead the loops ask for their input, in blocks: 24 blocks are 2,304 bytes (36 cache
/// lines). On a frame larger than the caches, with the kernel's arithmetic between its loads,
/// the hardware's stream prefetcher alone left NSRM 3 at 0.89 × memcpy on one thread of a Zen 3
/// host (median of 20 runs) and 1.02 with this; 16 and 32 measured alike (BENCHMARKS.md).
const PREFETCH_BLOCKS: usize = 24;

/// Both cache lines a block may start or end in (a block is 1.5 lines, so its first floats
/// alone would skip every third line).
#[inline(always)]
fn prefetch_block<R: Reg>(cpu: R::Cpu, b: &[f32; FLOATS]) {
    R::prefetch(cpu, &b[..]);
    R::prefetch(cpu, &b[FLOATS - 1..]);
}

/// One AVX register: 8 pixels.
#[derive(Clone, Copy)]
pub(super) struct Y(V3, __m256);

impl Arith for Y {
    type Mask = __m256;
    #[inline(always)]
    fn mul(self, b: Y) -> Y {
        Y(self.0, self.0.avx._mm256_mul_ps(self.1, b.1))
    }
    #[inline(always)]
    fn add(self, b: Y) -> Y {
        Y(self.0, self.0.avx._mm256_add_ps(self.1, b.1))
    }
    #[inline(always)]
    fn div(self, b: Y) -> Y {
        Y(self.0, self.0.avx._mm256_div_ps(self.1, b.1))
    }
    /// Always fused: these registers stand for the per-pixel code's AVX2 + FMA clone.
    #[inline(always)]
    fn madd(self, b: Y, c: Y, _fma: bool) -> Y {
        Y(self.0, self.0.fma._mm256_fmadd_ps(self.1, b.1, c.1))
    }
    #[inline(always)]
    fn le_zero(self) -> __m256 {
        let avx = self.0.avx;
        avx._mm256_cmp_ps::<_CMP_LE_OQ>(self.1, avx._mm256_setzero_ps())
    }
    #[inline(always)]
    fn zero_where(self, mask: __m256) -> Y {
        Y(self.0, self.0.avx._mm256_andnot_ps(mask, self.1))
    }
}

impl Reg for Y {
    type Cpu = V3;
    const FMA: bool = true;
    #[inline(always)]
    fn splat(cpu: V3, v: f32) -> Y {
        Y(cpu, cpu.avx._mm256_set1_ps(v))
    }
    #[inline(always)]
    fn load(cpu: V3, b: &[f32; FLOATS]) -> [Y; 3] {
        let avx = cpu.avx;
        // Per 128-bit lane (pixels 0–3, and 4–7 alike): a = R0 G0 B0 R1, b = G1 B1 R2 G2,
        // c = B2 R3 G3 B3.
        let a = avx._mm256_insertf128_ps::<1>(avx._mm256_castps128_ps256(quad(b, 0)), quad(b, 12));
        let c = avx._mm256_insertf128_ps::<1>(avx._mm256_castps128_ps256(quad(b, 8)), quad(b, 20));
        let b = avx._mm256_insertf128_ps::<1>(avx._mm256_castps128_ps256(quad(b, 4)), quad(b, 16));
        let rg23 = avx._mm256_shuffle_ps::<0b10_01_11_10>(b, c); // R2 G2 R3 G3
        let gb01 = avx._mm256_shuffle_ps::<0b01_00_10_01>(a, b); // G0 B0 G1 B1
        [
            Y(cpu, avx._mm256_shuffle_ps::<0b10_00_11_00>(a, rg23)), // R0 R1 R2 R3
            Y(cpu, avx._mm256_shuffle_ps::<0b11_01_10_00>(gb01, rg23)), // G0 G1 G2 G3
            Y(cpu, avx._mm256_shuffle_ps::<0b11_00_11_01>(gb01, c)), // B0 B1 B2 B3
        ]
    }
    #[inline(always)]
    fn store(cpu: V3, [r, g, b]: [Y; 3], out: &mut [f32; FLOATS]) {
        let avx = cpu.avx;
        let (r, g, b) = (r.1, g.1, b.1);
        let rg = avx._mm256_shuffle_ps::<0b10_00_10_00>(r, g); // R0 R2 G0 G2
        let gb = avx._mm256_shuffle_ps::<0b11_01_11_01>(g, b); // G1 G3 B1 B3
        let br = avx._mm256_shuffle_ps::<0b11_01_10_00>(b, r); // B0 B2 R1 R3
        let a = avx._mm256_shuffle_ps::<0b10_00_10_00>(rg, br); // R0 G0 B0 R1
        let b = avx._mm256_shuffle_ps::<0b11_01_10_00>(gb, rg); // G1 B1 R2 G2
        let c = avx._mm256_shuffle_ps::<0b11_01_11_01>(br, gb); // B2 R3 G3 B3
        let halves: [[f32; 8]; 3] = [
            pulp::cast(avx._mm256_permute2f128_ps::<0x20>(a, b)),
            pulp::cast(avx._mm256_permute2f128_ps::<0x30>(c, a)),
            pulp::cast(avx._mm256_permute2f128_ps::<0x31>(b, c)),
        ];
        *out = pulp::cast(halves);
    }
    #[inline(always)]
    fn all_below(cpu: V3, x: &[Y; 3], limit: f32) -> bool {
        let avx = cpu.avx;
        let (limit, sign) = (avx._mm256_set1_ps(limit), avx._mm256_set1_ps(-0.0));
        let mut ok = avx._mm256_castsi256_ps(avx._mm256_set1_epi32(-1));
        for v in x {
            let b = avx._mm256_cmp_ps::<_CMP_LT_OQ>(avx._mm256_andnot_ps(sign, v.1), limit);
            ok = avx._mm256_and_ps(ok, b);
        }
        avx._mm256_movemask_ps(ok) == 0xff
    }
    #[inline(always)]
    fn tail_into<K: Chunks>(k: &K, src: &[f32], dst: &mut [f32]) {
        chunk_into_avx2::<K, 3>(k, src, dst)
    }
    #[inline(always)]
    fn tail_in_place<K: Chunks>(k: &K, data: &mut [f32]) {
        chunk_in_place_avx2::<K, 3>(k, data)
    }
    #[inline(always)]
    fn prefetch(cpu: V3, b: &[f32]) {
        cpu.sse._mm_prefetch::<_MM_HINT_T0>(b.as_ptr().cast());
    }
}

/// Two SSE registers: 8 pixels, 4 in each.
#[derive(Clone, Copy)]
pub(super) struct X(V1, [__m128; 2]);

impl Arith for X {
    type Mask = [__m128; 2];
    #[inline(always)]
    fn mul(self, b: X) -> X {
        let s = self.0.sse;
        X(
            self.0,
            [
                s._mm_mul_ps(self.1[0], b.1[0]),
                s._mm_mul_ps(self.1[1], b.1[1]),
            ],
        )
    }
    #[inline(always)]
    fn add(self, b: X) -> X {
        let s = self.0.sse;
        X(
            self.0,
            [
                s._mm_add_ps(self.1[0], b.1[0]),
                s._mm_add_ps(self.1[1], b.1[1]),
            ],
        )
    }
    #[inline(always)]
    fn div(self, b: X) -> X {
        let s = self.0.sse;
        X(
            self.0,
            [
                s._mm_div_ps(self.1[0], b.1[0]),
                s._mm_div_ps(self.1[1], b.1[1]),
            ],
        )
    }
    /// Never fused: these registers stand for the per-pixel code's baseline (`madd` without FMA:
    /// a multiply, then an add).
    #[inline(always)]
    fn madd(self, b: X, c: X, _fma: bool) -> X {
        self.mul(b).add(c)
    }
    #[inline(always)]
    fn le_zero(self) -> [__m128; 2] {
        let s = self.0.sse;
        // CMPLEPS is an ordered compare: false for NaN.
        [
            s._mm_cmple_ps(self.1[0], s._mm_setzero_ps()),
            s._mm_cmple_ps(self.1[1], s._mm_setzero_ps()),
        ]
    }
    #[inline(always)]
    fn zero_where(self, mask: [__m128; 2]) -> X {
        let s = self.0.sse;
        X(
            self.0,
            [
                s._mm_andnot_ps(mask[0], self.1[0]),
                s._mm_andnot_ps(mask[1], self.1[1]),
            ],
        )
    }
}

impl Reg for X {
    type Cpu = V1;
    const FMA: bool = false;
    #[inline(always)]
    fn splat(cpu: V1, v: f32) -> X {
        X(cpu, [cpu.sse._mm_set1_ps(v); 2])
    }
    #[inline(always)]
    fn load(cpu: V1, b: &[f32; FLOATS]) -> [X; 3] {
        let [r0, g0, b0] = load4(cpu, quad(b, 0), quad(b, 4), quad(b, 8));
        let [r1, g1, b1] = load4(cpu, quad(b, 12), quad(b, 16), quad(b, 20));
        [X(cpu, [r0, r1]), X(cpu, [g0, g1]), X(cpu, [b0, b1])]
    }
    #[inline(always)]
    fn store(cpu: V1, [r, g, b]: [X; 3], out: &mut [f32; FLOATS]) {
        let lo = store4(cpu, r.1[0], g.1[0], b.1[0]);
        let hi = store4(cpu, r.1[1], g.1[1], b.1[1]);
        let all: [[__m128; 3]; 2] = [lo, hi];
        *out = pulp::cast(all);
    }
    #[inline(always)]
    fn all_below(cpu: V1, x: &[X; 3], limit: f32) -> bool {
        let s = cpu.sse;
        let (limit, sign) = (s._mm_set1_ps(limit), s._mm_set1_ps(-0.0));
        let mut ok = s._mm_cmpeq_ps(limit, limit);
        for v in x {
            for h in v.1 {
                // CMPLTPS is ordered: false for NaN.
                ok = s._mm_and_ps(ok, s._mm_cmplt_ps(s._mm_andnot_ps(sign, h), limit));
            }
        }
        s._mm_movemask_ps(ok) == 0xf
    }
    #[inline(always)]
    fn tail_into<K: Chunks>(k: &K, src: &[f32], dst: &mut [f32]) {
        k.run_into::<3>(src, dst, false)
    }
    #[inline(always)]
    fn tail_in_place<K: Chunks>(k: &K, data: &mut [f32]) {
        k.run_in_place::<3>(data, false)
    }
    #[inline(always)]
    fn prefetch(cpu: V1, b: &[f32]) {
        cpu.sse._mm_prefetch::<_MM_HINT_T0>(b.as_ptr().cast());
    }
}

/// 4 pixels (`a = R0 G0 B0 R1`, `b = G1 B1 R2 G2`, `c = B2 R3 G3 B3`) into R, G, B.
#[inline(always)]
fn load4(cpu: V1, a: __m128, b: __m128, c: __m128) -> [__m128; 3] {
    let s = cpu.sse;
    let rg23 = s._mm_shuffle_ps::<0b10_01_11_10>(b, c); // R2 G2 R3 G3
    let gb01 = s._mm_shuffle_ps::<0b01_00_10_01>(a, b); // G0 B0 G1 B1
    [
        s._mm_shuffle_ps::<0b10_00_11_00>(a, rg23), // R0 R1 R2 R3
        s._mm_shuffle_ps::<0b11_01_10_00>(gb01, rg23), // G0 G1 G2 G3
        s._mm_shuffle_ps::<0b11_00_11_01>(gb01, c), // B0 B1 B2 B3
    ]
}

/// [`load4`]'s inverse.
#[inline(always)]
fn store4(cpu: V1, r: __m128, g: __m128, b: __m128) -> [__m128; 3] {
    let s = cpu.sse;
    let rg = s._mm_shuffle_ps::<0b10_00_10_00>(r, g); // R0 R2 G0 G2
    let gb = s._mm_shuffle_ps::<0b11_01_11_01>(g, b); // G1 G3 B1 B3
    let br = s._mm_shuffle_ps::<0b11_01_10_00>(b, r); // B0 B2 R1 R3
    [
        s._mm_shuffle_ps::<0b10_00_10_00>(rg, br), // R0 G0 B0 R1
        s._mm_shuffle_ps::<0b11_01_10_00>(gb, rg), // G1 B1 R2 G2
        s._mm_shuffle_ps::<0b11_01_11_01>(br, gb), // B2 R3 G3 B3
    ]
}

/// Four floats of a block from `i`.
#[inline(always)]
fn quad(b: &[f32; FLOATS], i: usize) -> __m128 {
    pulp::cast([b[i], b[i + 1], b[i + 2], b[i + 3]])
}

/// A hand-written kernel in two halves over registers: the first issued one block ahead of the
/// second.
pub(super) trait Halves: Chunks {
    /// The coefficients, each broadcast to a register.
    type Splat<R: Reg>;
    /// What the first half leaves for the second.
    type Front<R: Reg>: Copy;
    fn splat<R: Reg>(&self, cpu: R::Cpu) -> Self::Splat<R>;
    /// Whether a block takes the register path (else the per-pixel kernel's exact one).
    #[inline(always)]
    fn block_ok<R: Reg>(_cpu: R::Cpu, _x: &[R; 3]) -> bool {
        true
    }
    fn front<R: Reg>(k: &Self::Splat<R>, x: [R; 3]) -> Self::Front<R>;
    fn back<R: Reg>(k: &Self::Splat<R>, f: Self::Front<R>) -> [R; 3];
    /// A block that failed [`block_ok`](Self::block_ok), in place, as the per-pixel code does it
    /// (`fma` as the registers').
    fn slow(&self, blk: &mut [f32; FLOATS], fma: bool);
}

/// Broadcasts each of `m`'s values to a register.
#[inline(always)]
fn splat_all<R: Reg, const N: usize, const L: usize>(
    cpu: R::Cpu,
    m: &[[f32; L]; N],
) -> [[R; L]; N] {
    let mut out = [[R::splat(cpu, 0.0); L]; N];
    for (row, m) in out.iter_mut().zip(m) {
        for (v, &c) in row.iter_mut().zip(m) {
            *v = R::splat(cpu, c);
        }
    }
    out
}

impl Halves for Nsrm3 {
    type Splat<R: Reg> = ([[R; 10]; 3], [R; 3]);
    type Front<R: Reg> = NsrmSignal<R>;
    #[inline(always)]
    fn splat<R: Reg>(&self, cpu: R::Cpu) -> Self::Splat<R> {
        let [gain] = splat_all::<R, 1, 3>(cpu, &[self.gain]);
        (splat_all(cpu, &self.m), gain)
    }
    #[inline(always)]
    fn front<R: Reg>((_, gain): &Self::Splat<R>, x: [R; 3]) -> NsrmSignal<R> {
        nsrm3_front(gain, x)
    }
    #[inline(always)]
    fn back<R: Reg>((m, _): &Self::Splat<R>, f: NsrmSignal<R>) -> [R; 3] {
        nsrm3_back(m, f, R::FMA)
    }
    /// Never called (every block takes the register path); the per-pixel code all the same.
    #[inline(always)]
    fn slow(&self, blk: &mut [f32; FLOATS], fma: bool) {
        map_in_place::<Nsrm3, 3, false>(self, blk, fma)
    }
}

impl Halves for Prm3 {
    type Splat<R: Reg> = [[R; 19]; 3];
    type Front<R: Reg> = [R; 3];
    #[inline(always)]
    fn splat<R: Reg>(&self, cpu: R::Cpu) -> Self::Splat<R> {
        splat_all(cpu, &self.m)
    }
    /// The per-pixel loop's step test (`quick_finite`) on one block: every `|value| < MAX/4`
    /// (NaN compares false), so the values and their sums are finite.
    #[inline(always)]
    fn block_ok<R: Reg>(cpu: R::Cpu, x: &[R; 3]) -> bool {
        R::all_below(cpu, x, SUM_SAFE)
    }
    #[inline(always)]
    fn front<R: Reg>(_: &Self::Splat<R>, x: [R; 3]) -> [R; 3] {
        x
    }
    #[inline(always)]
    fn back<R: Reg>(m: &Self::Splat<R>, x: [R; 3]) -> [R; 3] {
        prm3_nested(m, x, R::FMA)
    }
    #[inline(always)]
    fn slow(&self, blk: &mut [f32; FLOATS], fma: bool) {
        guarded_block::<Prm3, 3>(self, blk, fma)
    }
}

/// An instruction set these kernels run on.
#[derive(Debug, Clone, Copy)]
pub(in crate::model) enum Explicit {
    /// AVX2 + FMA (the per-pixel code's AVX2 + FMA clone's bits).
    Avx2(V3),
    /// SSE2 (the per-pixel code's baseline bits).
    Sse2(V1),
}

impl Explicit {
    /// The kernels for the code this CPU runs ([`Code::Detected`](super::Code)): AVX2 + FMA
    /// where the CPU has it and not AVX-512, SSE2 where it has no AVX2 + FMA (so the per-pixel
    /// code would run its baseline), none on an AVX-512 CPU (its per-pixel clone runs: on an AMD
    /// Zen 5 host the two ran NSRM 3 and PRM 3 alike, in L2 and on a frame; BENCHMARKS.md).
    pub(super) fn detect() -> Option<Explicit> {
        use std::arch::is_x86_feature_detected as has;
        if !(has!("avx2") && has!("fma")) {
            return Self::baseline();
        }
        if has!("avx512f") && has!("avx512vl") {
            return None;
        }
        V3::try_new().map(Explicit::Avx2)
    }

    /// The instruction set's name.
    #[cfg(test)]
    pub(super) fn name(self) -> &'static str {
        match self {
            Explicit::Avx2(_) => "AVX2 + FMA",
            Explicit::Sse2(_) => "SSE2",
        }
    }

    /// The AVX2 + FMA kernels wherever the CPU has what they need, AVX-512 or not (what the
    /// tests run on an AVX-512 CPU).
    pub(super) fn avx2() -> Option<Explicit> {
        V3::try_new().map(Explicit::Avx2)
    }

    /// The kernels of the baseline code (no FMA: the same bits on every CPU).
    pub(super) fn baseline() -> Option<Explicit> {
        V1::try_new().map(Explicit::Sse2)
    }

    /// `dst = k(src)`, packed RGB of the same length.
    pub(super) fn into<K: Halves>(self, k: &K, src: &[f32], dst: &mut [f32]) {
        match self {
            Explicit::Avx2(cpu) => cpu.vectorize(Into::<K, Y> { cpu, k, src, dst }),
            Explicit::Sse2(cpu) => cpu.vectorize(Into::<K, X> { cpu, k, src, dst }),
        }
    }

    /// `k` on packed RGB `data`, in place.
    pub(super) fn in_place<K: Halves>(self, k: &K, data: &mut [f32]) {
        match self {
            Explicit::Avx2(cpu) => cpu.vectorize(InPlace::<K, Y> { cpu, k, data }),
            Explicit::Sse2(cpu) => cpu.vectorize(InPlace::<K, X> { cpu, k, data }),
        }
    }
}

/// [`Explicit::into`]'s loop: a [`NullaryFnOnce`] operation (not a closure), so that its body
/// is compiled into `vectorize`'s function for the instruction set.
struct Into<'a, K, R: Reg> {
    cpu: R::Cpu,
    k: &'a K,
    src: &'a [f32],
    dst: &'a mut [f32],
}

impl<K: Halves, R: Reg> NullaryFnOnce for Into<'_, K, R> {
    type Output = ();

    #[inline(always)]
    fn call(self) {
        let Into { cpu, k, src, dst } = self;
        let splat = k.splat::<R>(cpu);
        let (s_blocks, s_rest) = src.as_chunks::<FLOATS>();
        let (d_blocks, d_rest) = dst.as_chunks_mut::<FLOATS>();
        let n = s_blocks.len().min(d_blocks.len());
        if n > 0 {
            let mut x = R::load(cpu, &s_blocks[0]);
            let mut f = K::front(&splat, x);
            for i in 0..n {
                if let Some(ahead) = s_blocks.get(i + PREFETCH_BLOCKS) {
                    prefetch_block::<R>(cpu, ahead);
                }
                // The next block's first half goes out before this block's second.
                let (nx, nf) = if i + 1 < n {
                    let nx = R::load(cpu, &s_blocks[i + 1]);
                    (nx, K::front(&splat, nx))
                } else {
                    (x, f)
                };
                if K::block_ok::<R>(cpu, &x) {
                    R::store(cpu, K::back(&splat, f), &mut d_blocks[i]);
                } else {
                    d_blocks[i] = s_blocks[i];
                    k.slow(&mut d_blocks[i], R::FMA);
                }
                (x, f) = (nx, nf);
            }
        }
        R::tail_into(k, s_rest, d_rest);
    }
}

/// [`Explicit::in_place`]'s loop (as [`Into`]).
struct InPlace<'a, K, R: Reg> {
    cpu: R::Cpu,
    k: &'a K,
    data: &'a mut [f32],
}

impl<K: Halves, R: Reg> NullaryFnOnce for InPlace<'_, K, R> {
    type Output = ();

    #[inline(always)]
    fn call(self) {
        let InPlace { cpu, k, data } = self;
        let splat = k.splat::<R>(cpu);
        let (blocks, rest) = data.as_chunks_mut::<FLOATS>();
        let n = blocks.len();
        if n > 0 {
            let mut x = R::load(cpu, &blocks[0]);
            let mut f = K::front(&splat, x);
            for i in 0..n {
                if let Some(ahead) = blocks.get(i + PREFETCH_BLOCKS) {
                    prefetch_block::<R>(cpu, ahead);
                }
                let (nx, nf) = if i + 1 < n {
                    let nx = R::load(cpu, &blocks[i + 1]);
                    (nx, K::front(&splat, nx))
                } else {
                    (x, f)
                };
                if K::block_ok::<R>(cpu, &x) {
                    R::store(cpu, K::back(&splat, f), &mut blocks[i]);
                } else {
                    k.slow(&mut blocks[i], R::FMA);
                }
                (x, f) = (nx, nf);
            }
        }
        R::tail_in_place(k, rest);
    }
}
