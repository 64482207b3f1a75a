//! Explicit AVX2 + FMA kernels for NSRM 3 and PRM 3 on packed RGB (x86-64 CPUs without AVX-512).
//!
//! The per-pixel kernels leave the de-interleave to LLVM's loop vectoriser, which reads a
//! stride-3 block of 8 pixels as three 256-bit loads put apart by lane-crossing permutes and
//! blends (28 shuffles a block, in and out), and evaluates one block at a time, so NSRM's
//! multiply-adds wait on its two divisions (about 11 cycles each on AMD Zen 3) while the
//! out-of-order window holds little else. Here:
//! * a block is loaded as six 128-bit quarters paired into three registers (pixels 0–3 in the low
//!   lanes, 4–7 in the high lanes), so the de-interleave is five in-lane `vshufps`; the way back
//!   is six `vshufps` and three `vperm2f128`;
//! * the loop is software-pipelined by one block: the next block's load and first half (NSRM's
//!   sum and divisions) are issued before this block's second half, so the divider works while
//!   the FMA pipes do;
//! * PRM 3 tests each block once on its registers (every value below `f32::MAX / 4`); a block
//!   that fails takes the per-pixel kernel's exact path (`guarded_block`: the term sums where a
//!   value is not finite), as the per-pixel loop does.
//!
//! The arithmetic is the per-pixel kernels' own text: [`nsrm3_front`], [`nsrm3_back`] and
//! [`prm3_nested`] are generic over [`Arith`], here over a register of 8 pixels, so every
//! operation is the FMA clone's, in the same order, and the output is the same bits
//! (`fast_tests.rs` checks that on frames of awkward pixels). A chunk's last partial block goes
//! through the per-pixel clone.
//!
//! The intrinsics are [`pulp`]'s safe wrappers: [`V3::try_new`] checks the CPU once, and
//! [`V3::vectorize`] runs the loop inside a function compiled for AVX2 + FMA, so this crate keeps
//! `forbid(unsafe_code)`. The loop is a [`NullaryFnOnce`] operation and everything it calls is
//! `#[inline(always)]`, with no closures: a closure that LLVM does not inline is a function of its
//! own, compiled without AVX2, and every intrinsic in it stays a call (20–60× slower). On a CPU with AVX-512
//! the per-pixel kernels' AVX-512 clone (16 pixels a register, 32 registers) runs instead: these
//! kernels were measured only where AVX-512 is absent.

use super::{
    chunk_in_place_avx2, chunk_into_avx2, guarded_block, nsrm3_back, nsrm3_front, prm3_nested,
    Arith, Chunks, Nsrm3, NsrmSignal, Prm3, SUM_SAFE,
};
use pulp::{x86::V3, NullaryFnOnce};
use std::arch::x86_64::{__m128, __m256, _CMP_LE_OQ, _CMP_LT_OQ};

/// Floats per block: 8 RGB pixels, one register per channel.
const FLOATS: usize = 24;

/// One register of 8 pixels' values of one channel, with the CPU token that lets it compute.
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
    /// Always fused: these kernels stand for the per-pixel kernels' FMA clone.
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
        let avx = self.0.avx;
        Y(
            self.0,
            avx._mm256_blendv_ps(self.1, avx._mm256_setzero_ps(), mask),
        )
    }
}

/// A hand-written kernel in two halves over registers: the first issued one block ahead of the
/// second.
pub(super) trait Halves: Chunks {
    /// The coefficients, each broadcast to a register.
    type Splat;
    /// What the first half leaves for the second.
    type Front: Copy;
    fn splat(&self, simd: V3) -> Self::Splat;
    /// Whether a block takes the register path (else the per-pixel kernel's exact one).
    #[inline(always)]
    fn block_ok(_simd: V3, _x: &[Y; 3]) -> bool {
        true
    }
    fn front(k: &Self::Splat, x: [Y; 3]) -> Self::Front;
    fn back(k: &Self::Splat, f: Self::Front) -> [Y; 3];
    /// A block that failed [`block_ok`](Self::block_ok), in place.
    #[inline(always)]
    fn slow(&self, _blk: &mut [f32; FLOATS]) {}
}

/// Broadcasts each of `m`'s values to a register.
#[inline(always)]
fn splat_all<const N: usize, const L: usize>(simd: V3, m: &[[f32; L]; N]) -> [[Y; L]; N] {
    let zero = Y(simd, simd.avx._mm256_setzero_ps());
    let mut out = [[zero; L]; N];
    for (row, m) in out.iter_mut().zip(m) {
        for (v, &c) in row.iter_mut().zip(m) {
            *v = Y(simd, simd.avx._mm256_set1_ps(c));
        }
    }
    out
}

impl Halves for Nsrm3 {
    type Splat = ([[Y; 10]; 3], [Y; 3]);
    type Front = NsrmSignal<Y>;
    #[inline(always)]
    fn splat(&self, simd: V3) -> Self::Splat {
        let [gain] = splat_all(simd, &[self.gain]);
        (splat_all(simd, &self.m), gain)
    }
    #[inline(always)]
    fn front((_, gain): &Self::Splat, x: [Y; 3]) -> NsrmSignal<Y> {
        nsrm3_front(gain, x)
    }
    #[inline(always)]
    fn back((m, _): &Self::Splat, f: NsrmSignal<Y>) -> [Y; 3] {
        nsrm3_back(m, f, true)
    }
}

impl Halves for Prm3 {
    type Splat = [[Y; 19]; 3];
    type Front = [Y; 3];
    #[inline(always)]
    fn splat(&self, simd: V3) -> Self::Splat {
        splat_all(simd, &self.m)
    }
    /// The per-pixel loop's step test (`quick_finite`) on one block: every `|value| < MAX/4`
    /// (NaN compares false), so the values and their sums are finite.
    #[inline(always)]
    fn block_ok(simd: V3, x: &[Y; 3]) -> bool {
        let avx = simd.avx;
        let limit = avx._mm256_set1_ps(SUM_SAFE);
        let sign = avx._mm256_set1_ps(-0.0);
        let mut ok = avx._mm256_castsi256_ps(avx._mm256_set1_epi32(-1));
        for v in x {
            let below = avx._mm256_cmp_ps::<_CMP_LT_OQ>(avx._mm256_andnot_ps(sign, v.1), limit);
            ok = avx._mm256_and_ps(ok, below);
        }
        avx._mm256_movemask_ps(ok) == 0xff
    }
    #[inline(always)]
    fn front(_: &Self::Splat, x: [Y; 3]) -> [Y; 3] {
        x
    }
    #[inline(always)]
    fn back(m: &Self::Splat, x: [Y; 3]) -> [Y; 3] {
        prm3_nested(m, x, true)
    }
    #[inline(always)]
    fn slow(&self, blk: &mut [f32; FLOATS]) {
        guarded_block::<Prm3, 3>(self, blk, true)
    }
}

/// A CPU that runs these kernels: AVX2 + FMA, and not AVX-512.
#[derive(Debug, Clone, Copy)]
pub(in crate::model) struct Avx2(V3);

impl Avx2 {
    /// The token, where this CPU should run these kernels.
    pub(super) fn detect() -> Option<Avx2> {
        if std::arch::is_x86_feature_detected!("avx512f")
            && std::arch::is_x86_feature_detected!("avx512vl")
        {
            return None;
        }
        V3::try_new().map(Avx2)
    }

    /// `dst = k(src)`, packed RGB of the same length.
    pub(super) fn into<K: Halves>(self, k: &K, src: &[f32], dst: &mut [f32]) {
        self.0.vectorize(Into {
            simd: self.0,
            k,
            src,
            dst,
        })
    }

    /// `k` on packed RGB `data`, in place.
    pub(super) fn in_place<K: Halves>(self, k: &K, data: &mut [f32]) {
        self.0.vectorize(InPlace {
            simd: self.0,
            k,
            data,
        })
    }
}

/// [`Avx2::into`]'s loop: a [`NullaryFnOnce`] operation (not a closure), so that its body is compiled
/// into [`V3::vectorize`]'s AVX2 + FMA function.
struct Into<'a, K> {
    simd: V3,
    k: &'a K,
    src: &'a [f32],
    dst: &'a mut [f32],
}

impl<K: Halves> NullaryFnOnce for Into<'_, K> {
    type Output = ();

    #[inline(always)]
    fn call(self) {
        let Into { simd, k, src, dst } = self;
        let splat = k.splat(simd);
        let (s_blocks, s_rest) = src.as_chunks::<FLOATS>();
        let (d_blocks, d_rest) = dst.as_chunks_mut::<FLOATS>();
        let n = s_blocks.len().min(d_blocks.len());
        if n > 0 {
            let mut x = load(simd, &s_blocks[0]);
            let mut f = K::front(&splat, x);
            for i in 0..n {
                // The next block's first half goes out before this block's second.
                let (nx, nf) = if i + 1 < n {
                    let nx = load(simd, &s_blocks[i + 1]);
                    (nx, K::front(&splat, nx))
                } else {
                    (x, f)
                };
                if K::block_ok(simd, &x) {
                    store(simd, K::back(&splat, f), &mut d_blocks[i]);
                } else {
                    d_blocks[i] = s_blocks[i];
                    k.slow(&mut d_blocks[i]);
                }
                (x, f) = (nx, nf);
            }
        }
        chunk_into_avx2::<K, 3>(k, s_rest, d_rest);
    }
}

/// [`Avx2::in_place`]'s loop (as [`Into`]).
struct InPlace<'a, K> {
    simd: V3,
    k: &'a K,
    data: &'a mut [f32],
}

impl<K: Halves> NullaryFnOnce for InPlace<'_, K> {
    type Output = ();

    #[inline(always)]
    fn call(self) {
        let InPlace { simd, k, data } = self;
        let splat = k.splat(simd);
        let (blocks, rest) = data.as_chunks_mut::<FLOATS>();
        let n = blocks.len();
        if n > 0 {
            let mut x = load(simd, &blocks[0]);
            let mut f = K::front(&splat, x);
            for i in 0..n {
                let (nx, nf) = if i + 1 < n {
                    let nx = load(simd, &blocks[i + 1]);
                    (nx, K::front(&splat, nx))
                } else {
                    (x, f)
                };
                if K::block_ok(simd, &x) {
                    store(simd, K::back(&splat, f), &mut blocks[i]);
                } else {
                    k.slow(&mut blocks[i]);
                }
                (x, f) = (nx, nf);
            }
        }
        chunk_in_place_avx2::<K, 3>(k, rest);
    }
}

/// Four floats of a block from `i`.
#[inline(always)]
fn quad(b: &[f32; FLOATS], i: usize) -> __m128 {
    pulp::cast([b[i], b[i + 1], b[i + 2], b[i + 3]])
}

/// One block of 8 pixels de-interleaved into R, G, B registers (pixel order in each).
#[inline(always)]
fn load(simd: V3, b: &[f32; FLOATS]) -> [Y; 3] {
    let avx = simd.avx;
    // Per 128-bit lane (pixels 0–3, and 4–7 alike): a = R0 G0 B0 R1, b = G1 B1 R2 G2,
    // c = B2 R3 G3 B3.
    let a = avx._mm256_insertf128_ps::<1>(avx._mm256_castps128_ps256(quad(b, 0)), quad(b, 12));
    let c = avx._mm256_insertf128_ps::<1>(avx._mm256_castps128_ps256(quad(b, 8)), quad(b, 20));
    let b = avx._mm256_insertf128_ps::<1>(avx._mm256_castps128_ps256(quad(b, 4)), quad(b, 16));
    let rg23 = avx._mm256_shuffle_ps::<0b10_01_11_10>(b, c); // R2 G2 R3 G3
    let gb01 = avx._mm256_shuffle_ps::<0b01_00_10_01>(a, b); // G0 B0 G1 B1
    [
        Y(simd, avx._mm256_shuffle_ps::<0b10_00_11_00>(a, rg23)), // R0 R1 R2 R3
        Y(simd, avx._mm256_shuffle_ps::<0b11_01_10_00>(gb01, rg23)), // G0 G1 G2 G3
        Y(simd, avx._mm256_shuffle_ps::<0b11_00_11_01>(gb01, c)), // B0 B1 B2 B3
    ]
}

/// [`load`]'s inverse: R, G, B registers interleaved into one block.
#[inline(always)]
fn store(simd: V3, [r, g, b]: [Y; 3], out: &mut [f32; FLOATS]) {
    let avx = simd.avx;
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
