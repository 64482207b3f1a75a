//! NSRM 3 on packed RGB with explicit AVX2 + FMA vectors, for x86-64 CPUs without AVX-512.
//!
//! The per-pixel kernel ([`Nsrm3`]'s `pixel`) leaves the de-interleave to LLVM's loop vectoriser,
//! which reads a stride-3 block of 8 pixels as three 256-bit loads put apart by lane-crossing
//! permutes and blends (28 shuffles a block, in and out), and evaluates one block at a time, so
//! the multiply-adds of a block wait on its two divisions (about 11 cycles each on AMD Zen 3)
//! while the out-of-order window holds little else. Here:
//! * a block is loaded as six 128-bit halves paired into three registers (pixels 0–3 in the low
//!   lanes, 4–7 in the high lanes), so the de-interleave is five in-lane `vshufps`; the way back
//!   is six `vshufps` and three `vperm2f128`;
//! * the loop is software-pipelined by one block: the next block's load, sum and divisions are
//!   issued before this block's multiply-adds, so the divider works while the FMA pipes do.
//!
//! The arithmetic is the per-pixel kernel's FMA clone, operation for operation and in the same
//! order (the input gains, `s = (R+G)+B`, `r = R/s`, `g = G/s`, the nested multiply-adds, the
//! `s ≤ 0 → 0` select), so the output is the same bits (`fast_tests.rs` checks that on frames of
//! awkward pixels); a chunk's last partial block goes through the per-pixel clone.
//!
//! The intrinsics are [`pulp`]'s safe wrappers: [`V3::try_new`] checks the CPU once, and
//! [`V3::vectorize`] runs the loop inside a function compiled for AVX2 + FMA, so this crate keeps
//! `forbid(unsafe_code)`. On a CPU with AVX-512 the per-pixel kernel's AVX-512 clone (16 pixels
//! a register, 32 registers) runs instead: this kernel was measured only where AVX-512 is absent.

use super::{chunk_in_place_avx2, chunk_into_avx2, Nsrm3};
use pulp::x86::V3;
use std::arch::x86_64::{__m128, __m256, _CMP_LE_OQ};

/// Floats per block: 8 RGB pixels, one register per channel.
const FLOATS: usize = 24;

/// NSRM 3's matrix and input gains, each coefficient broadcast to a register.
struct Splat {
    m: [[__m256; 10]; 3],
    gain: [__m256; 3],
}

/// What the front half of a block leaves for the back half: `R·gain`, `G·gain`, `s`, `r`, `g`
/// and the `s ≤ 0` mask.
type Front = [__m256; 6];

/// The NSRM 3 kernel over whole blocks of packed RGB, where the CPU has AVX2 + FMA (and not
/// AVX-512).
#[derive(Debug, Clone, Copy)]
pub(in crate::model) struct Avx2(V3);

impl Avx2 {
    /// The kernel, where this CPU should run it.
    pub(super) fn detect() -> Option<Avx2> {
        if std::arch::is_x86_feature_detected!("avx512f")
            && std::arch::is_x86_feature_detected!("avx512vl")
        {
            return None;
        }
        V3::try_new().map(Avx2)
    }

    /// `dst = NSRM 3(src)`, packed RGB of the same length.
    pub(super) fn into(self, k: &Nsrm3, src: &[f32], dst: &mut [f32]) {
        let simd = self.0;
        simd.vectorize(
            #[inline(always)]
            || {
                let splat = splat(simd, k);
                let (s_blocks, s_rest) = src.as_chunks::<FLOATS>();
                let (d_blocks, d_rest) = dst.as_chunks_mut::<FLOATS>();
                let n = s_blocks.len().min(d_blocks.len());
                if n > 0 {
                    let mut f = front(simd, &splat, load(simd, &s_blocks[0]));
                    for i in 0..n {
                        // The next block's divisions go out before this block's multiply-adds.
                        let next = if i + 1 < n {
                            front(simd, &splat, load(simd, &s_blocks[i + 1]))
                        } else {
                            f
                        };
                        store(simd, back(simd, &splat, f), &mut d_blocks[i]);
                        f = next;
                    }
                }
                chunk_into_avx2::<Nsrm3, 3>(k, s_rest, d_rest);
            },
        )
    }

    /// NSRM 3 of packed RGB `data`, in place.
    pub(super) fn in_place(self, k: &Nsrm3, data: &mut [f32]) {
        let simd = self.0;
        simd.vectorize(
            #[inline(always)]
            || {
                let splat = splat(simd, k);
                let (blocks, rest) = data.as_chunks_mut::<FLOATS>();
                let n = blocks.len();
                if n > 0 {
                    let mut f = front(simd, &splat, load(simd, &blocks[0]));
                    for i in 0..n {
                        let next = if i + 1 < n {
                            front(simd, &splat, load(simd, &blocks[i + 1]))
                        } else {
                            f
                        };
                        store(simd, back(simd, &splat, f), &mut blocks[i]);
                        f = next;
                    }
                }
                chunk_in_place_avx2::<Nsrm3, 3>(k, rest);
            },
        )
    }
}

#[inline(always)]
fn splat(simd: V3, k: &Nsrm3) -> Splat {
    let zero = simd.avx._mm256_setzero_ps();
    let mut out = Splat {
        m: [[zero; 10]; 3],
        gain: [zero; 3],
    };
    for (row, m) in out.m.iter_mut().zip(&k.m) {
        for (v, &c) in row.iter_mut().zip(m) {
            *v = simd.avx._mm256_set1_ps(c);
        }
    }
    for (v, &c) in out.gain.iter_mut().zip(&k.gain) {
        *v = simd.avx._mm256_set1_ps(c);
    }
    out
}

/// Four floats of a block from `i`.
#[inline(always)]
fn quad(b: &[f32; FLOATS], i: usize) -> __m128 {
    pulp::cast([b[i], b[i + 1], b[i + 2], b[i + 3]])
}

/// One block of 8 pixels de-interleaved into R, G, B registers (pixel order in each).
#[inline(always)]
fn load(simd: V3, b: &[f32; FLOATS]) -> [__m256; 3] {
    let avx = simd.avx;
    // Per 128-bit lane (pixels 0–3, and 4–7 alike): a = R0 G0 B0 R1, b = G1 B1 R2 G2,
    // c = B2 R3 G3 B3.
    let a = avx._mm256_insertf128_ps::<1>(avx._mm256_castps128_ps256(quad(b, 0)), quad(b, 12));
    let c = avx._mm256_insertf128_ps::<1>(avx._mm256_castps128_ps256(quad(b, 8)), quad(b, 20));
    let b = avx._mm256_insertf128_ps::<1>(avx._mm256_castps128_ps256(quad(b, 4)), quad(b, 16));
    let rg23 = avx._mm256_shuffle_ps::<0b10_01_11_10>(b, c); // R2 G2 R3 G3
    let gb01 = avx._mm256_shuffle_ps::<0b01_00_10_01>(a, b); // G0 B0 G1 B1
    [
        avx._mm256_shuffle_ps::<0b10_00_11_00>(a, rg23), // R0 R1 R2 R3
        avx._mm256_shuffle_ps::<0b11_01_10_00>(gb01, rg23), // G0 G1 G2 G3
        avx._mm256_shuffle_ps::<0b11_00_11_01>(gb01, c), // B0 B1 B2 B3
    ]
}

/// [`load`]'s inverse: R, G, B registers interleaved into one block.
#[inline(always)]
fn store(simd: V3, [r, g, b]: [__m256; 3], out: &mut [f32; FLOATS]) {
    let avx = simd.avx;
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

/// The input gains, `s`, the black mask and the two divisions.
#[inline(always)]
fn front(simd: V3, k: &Splat, [x, y, z]: [__m256; 3]) -> Front {
    let avx = simd.avx;
    let cr = avx._mm256_mul_ps(x, k.gain[0]);
    let cg = avx._mm256_mul_ps(y, k.gain[1]);
    let cb = avx._mm256_mul_ps(z, k.gain[2]);
    let s = avx._mm256_add_ps(avx._mm256_add_ps(cr, cg), cb);
    // NaN is not ≤ 0 (an ordered compare): it goes through and propagates.
    let black = avx._mm256_cmp_ps::<_CMP_LE_OQ>(s, avx._mm256_setzero_ps());
    [
        cr,
        cg,
        s,
        avx._mm256_div_ps(cr, s),
        avx._mm256_div_ps(cg, s),
        black,
    ]
}

/// The terms and the matrix: `s·m0 + R·A + G·B + (R·g)·C` as in [`Nsrm3`]'s `pixel`.
#[inline(always)]
fn back(simd: V3, k: &Splat, [cr, cg, s, r, g, black]: Front) -> [__m256; 3] {
    let (avx, f) = (simd.avx, simd.fma);
    let rg = avx._mm256_mul_ps(cr, g);
    let mut out = [black; 3];
    for (o, m) in out.iter_mut().zip(&k.m) {
        let a = f._mm256_fmadd_ps(r, f._mm256_fmadd_ps(r, m[6], m[3]), m[1]);
        let b = f._mm256_fmadd_ps(g, f._mm256_fmadd_ps(g, m[7], m[4]), m[2]);
        let c = f._mm256_fmadd_ps(r, m[9], f._mm256_fmadd_ps(g, m[8], m[5]));
        let v = f._mm256_fmadd_ps(cr, a, avx._mm256_mul_ps(m[0], s));
        let v = f._mm256_fmadd_ps(cg, b, v);
        let v = f._mm256_fmadd_ps(rg, c, v);
        *o = avx._mm256_blendv_ps(v, avx._mm256_setzero_ps(), black);
    }
    out
}
