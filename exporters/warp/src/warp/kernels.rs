//! Bilinear colour filtering of one run of pixels (seed 001, Eq. 8) whose taps all lie inside the
//! image: a portable scalar kernel and, on x86_64, SSE2 (part of the baseline target, always
//! there) and AVX2+FMA (chosen at run time when the CPU has it) kernels.
//!
//! Every kernel computes exactly the same bytes as the scalar formula
//! `out = (((p00 gx + p10 fx) gy + (p01 gx + p11 fx) fy) + 2^15) >> 16` with 8-bit fractions
//! `fx, fy` and `gx = 256 - fx`, `gy = 256 - fy`. The SIMD kernels filter vertically first with
//! `pmaddwd` (`p00 gy + p01 fy <= 65280`, exact in i32) and horizontally in f32 with weights
//! `gx / 2^16`, `fx / 2^16`: every product and partial sum is an integer below 2^24 times a power of
//! two, so f32 holds it exactly and truncation gives the same rounding as the integer shift.

use super::Warper;

/// A run of pixels whose source points `(sx + k dsx, sy + k dsy)` (1/65536 pixel) round to points
/// in `[0, w - 1) x [0, h - 1)` (1/256 pixel), so no tap needs clamping.
#[derive(Debug, Clone, Copy)]
pub(super) struct Interior {
    pub sx: i32,
    pub sy: i32,
    pub dsx: i32,
    pub dsy: i32,
}

/// Which implementation of the inner loop [`super::Warper::remap_with`] uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RemapKernel {
    /// Portable Rust, any CPU.
    Scalar,
    /// SSE2 intrinsics (every x86_64 CPU).
    Sse2,
    /// AVX2 + FMA intrinsics, selected at run time.
    Avx2,
}

impl RemapKernel {
    /// The fastest kernel this CPU runs.
    pub fn best() -> RemapKernel {
        [RemapKernel::Avx2, RemapKernel::Sse2]
            .into_iter()
            .find(|k| k.is_available())
            .unwrap_or(RemapKernel::Scalar)
    }

    /// Every kernel this CPU runs.
    pub fn available() -> Vec<RemapKernel> {
        [RemapKernel::Scalar, RemapKernel::Sse2, RemapKernel::Avx2]
            .into_iter()
            .filter(|k| k.is_available())
            .collect()
    }

    /// Whether this CPU runs the kernel.
    pub fn is_available(self) -> bool {
        match self {
            RemapKernel::Scalar => true,
            #[cfg(target_arch = "x86_64")]
            RemapKernel::Sse2 => true,
            #[cfg(target_arch = "x86_64")]
            RemapKernel::Avx2 => is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma"),
            #[cfg(not(target_arch = "x86_64"))]
            RemapKernel::Sse2 | RemapKernel::Avx2 => false,
        }
    }

    /// Short name for reports.
    pub fn name(self) -> &'static str {
        match self {
            RemapKernel::Scalar => "scalar",
            RemapKernel::Sse2 => "sse2",
            RemapKernel::Avx2 => "avx2+fma",
        }
    }
}

/// The reference formula for one pixel from its taps `[p00, p10, p01, p11]` and 8-bit fractions.
#[inline(always)]
pub(super) fn bilinear(p: [[u8; 4]; 4], fx: u32, fy: u32) -> [u8; 4] {
    let (gx, gy) = (256 - fx, 256 - fy);
    let mut out = [0u8; 4];
    for c in 0..4 {
        let top = p[0][c] as u32 * gx + p[1][c] as u32 * fx;
        let bot = p[2][c] as u32 * gx + p[3][c] as u32 * fx;
        out[c] = ((top * gy + bot * fy + (1 << 15)) >> 16) as u8;
    }
    out
}

/// Filters one interior run into `out` (4 bytes per pixel) from `src` (`w` pixels per row).
pub(super) trait Kernel {
    fn interior(src: &[u8], w: usize, out: &mut [u8], run: Interior);
}

/// [`RemapKernel::Scalar`].
pub(super) struct Scalar;

impl Kernel for Scalar {
    #[inline(always)]
    fn interior(src: &[u8], w: usize, out: &mut [u8], run: Interior) {
        interior_scalar(src, w, out, run);
    }
}

/// Runs `warper`'s frame loop with `kernel`, which the caller checked is available.
pub(super) fn remap(kernel: RemapKernel, warper: &Warper, src: &[u8], dst: &mut [u8]) {
    match kernel {
        #[cfg(target_arch = "x86_64")]
        RemapKernel::Sse2 => {
            // SAFETY: SSE2 is part of the x86_64 baseline: every x86_64 CPU has it.
            unsafe { x86::remap_sse2(warper, src, dst) }
        }
        #[cfg(target_arch = "x86_64")]
        RemapKernel::Avx2 => {
            // SAFETY: `remap_with` only passes Avx2 when `is_available` detected AVX2 and FMA.
            unsafe { x86::remap_avx2(warper, src, dst) }
        }
        _ => warper.remap_runs::<Scalar>(src, dst),
    }
}

/// Runs `warper`'s compositing loop ([`Warper::warp_over_opaque`]) with `kernel` for the opaque
/// runs, which the caller checked is available; returns how many runs the kernel wrote.
pub(super) fn warp_over(
    kernel: RemapKernel,
    warper: &Warper,
    layer: &[u8],
    opaque: &super::OpaqueTiles,
    region: &[u8],
    frame: &mut [u8],
) -> usize {
    match kernel {
        #[cfg(target_arch = "x86_64")]
        RemapKernel::Sse2 => {
            // SAFETY: SSE2 is part of the x86_64 baseline: every x86_64 CPU has it.
            unsafe { x86::warp_over_sse2(warper, layer, opaque, region, frame) }
        }
        #[cfg(target_arch = "x86_64")]
        RemapKernel::Avx2 => {
            // SAFETY: `warp_over_opaque_with` only passes Avx2 when `is_available` detected AVX2
            // and FMA.
            unsafe { x86::warp_over_avx2(warper, layer, opaque, region, frame) }
        }
        _ => warper.warp_over_runs::<Scalar>(layer, Some(opaque), region, frame),
    }
}

/// Portable kernel (also the tail of the SIMD ones).
fn interior_scalar(src: &[u8], w: usize, out: &mut [u8], run: Interior) {
    let stride = w * 4;
    let (mut sx, mut sy) = (run.sx, run.sy);
    for o in out.chunks_exact_mut(4) {
        let (sxf, syf) = ((sx + 128) >> 8, (sy + 128) >> 8);
        let i = ((syf >> 8) as usize * w + (sxf >> 8) as usize) * 4;
        let top: &[u8; 8] = src[i..i + 8].try_into().expect("8 bytes");
        let bot: &[u8; 8] = src[i + stride..i + stride + 8].try_into().expect("8 bytes");
        let p = [
            [top[0], top[1], top[2], top[3]],
            [top[4], top[5], top[6], top[7]],
            [bot[0], bot[1], bot[2], bot[3]],
            [bot[4], bot[5], bot[6], bot[7]],
        ];
        let o: &mut [u8; 4] = o.try_into().expect("4 bytes");
        *o = bilinear(p, (sxf & 255) as u32, (syf & 255) as u32);
        // The step after the last pixel may leave the run's range: wrap instead of overflowing.
        sx = sx.wrapping_add(run.dsx);
        sy = sy.wrapping_add(run.dsy);
    }
}

#[cfg(target_arch = "x86_64")]
mod x86 {
    use std::arch::x86_64::*;

    use super::super::OpaqueTiles;
    use super::{Interior, Kernel, Warper, interior_scalar};

    /// Widest row (bytes) whose offsets the SIMD kernels form with 16-bit multiplies.
    const MAX_STRIDE: usize = i16::MAX as usize;

    struct Sse2;

    impl Kernel for Sse2 {
        #[inline(always)]
        fn interior(src: &[u8], w: usize, out: &mut [u8], run: Interior) {
            if w * 4 <= MAX_STRIDE {
                // SAFETY: SSE2 is part of the x86_64 baseline.
                unsafe { interior_sse2(src, w, out, run) }
            } else {
                interior_scalar(src, w, out, run)
            }
        }
    }

    struct Avx2;

    impl Kernel for Avx2 {
        #[inline(always)]
        fn interior(src: &[u8], w: usize, out: &mut [u8], run: Interior) {
            if w * 4 > MAX_STRIDE {
                interior_scalar(src, w, out, run)
            } else if out.len() < 32 {
                // Under one 8-pixel step (runs of small cells): the AVX2 kernel would only set
                // up its constants and hand the run to its SSE2 tail.
                // SAFETY: AVX2 implies SSE2, which every x86_64 CPU has anyway.
                unsafe { interior_sse2(src, w, out, run) }
            } else {
                // SAFETY: only reached from `remap_avx2` and `warp_over_avx2`, whose callers
                // checked AVX2 and FMA.
                unsafe { interior_avx2(src, w, out, run) }
            }
        }
    }

    /// The frame loop compiled for SSE2, the SSE2 kernel inlined into it.
    #[target_feature(enable = "sse2")]
    pub(super) fn remap_sse2(warper: &Warper, src: &[u8], dst: &mut [u8]) {
        warper.remap_runs::<Sse2>(src, dst);
    }

    /// The frame loop compiled for AVX2 and FMA, the AVX2 kernel inlined into it.
    #[target_feature(enable = "avx2,fma")]
    pub(super) fn remap_avx2(warper: &Warper, src: &[u8], dst: &mut [u8]) {
        warper.remap_runs::<Avx2>(src, dst);
    }

    /// The compositing loop compiled for SSE2, the SSE2 kernel inlined into it.
    #[target_feature(enable = "sse2")]
    pub(super) fn warp_over_sse2(
        warper: &Warper,
        layer: &[u8],
        opaque: &OpaqueTiles,
        region: &[u8],
        frame: &mut [u8],
    ) -> usize {
        warper.warp_over_runs::<Sse2>(layer, Some(opaque), region, frame)
    }

    /// The compositing loop compiled for AVX2 and FMA, the AVX2 kernel inlined into it.
    #[target_feature(enable = "avx2,fma")]
    pub(super) fn warp_over_avx2(
        warper: &Warper,
        layer: &[u8],
        opaque: &OpaqueTiles,
        region: &[u8],
        frame: &mut [u8],
    ) -> usize {
        warper.warp_over_runs::<Avx2>(layer, Some(opaque), region, frame)
    }

    /// `2^-16`: the horizontal weights as f32 fractions of the full weight `2^16`.
    const SCALE: f32 = 1.0 / 65536.0;

    /// Largest byte offset at which both rows' taps (8 bytes at it and 8 bytes one row down)
    /// lie inside the image.
    #[inline(always)]
    fn tap_limit(src: &[u8], w: usize) -> usize {
        // Interior runs exist only when the image has two rows and two columns. Capped below 2^31
        // so that a negative i32 offset (2^31 or more as u32) never passes the check.
        src.len().saturating_sub(w * 4 + 8).min(i32::MAX as usize)
    }

    /// Panics unless every lane of `offs`, read as unsigned, is at most `limit` (< 2^31): the
    /// check that makes the unchecked tap loads sound whatever the run arithmetic computed.
    #[inline]
    #[target_feature(enable = "sse2")]
    fn check_offsets_sse2(offs: __m128i, limit: usize) {
        let bias = _mm_set1_epi32(i32::MIN);
        let over =
            _mm_cmpgt_epi32(_mm_xor_si128(offs, bias), _mm_set1_epi32((limit as u32 ^ 1 << 31) as i32));
        assert!(_mm_movemask_epi8(over) == 0, "warp tap offset out of bounds");
    }

    /// The 8 bytes at `src[i..i + 8]` in the low half of a vector.
    ///
    /// # Safety
    /// `i + 8 <= src.len()`.
    #[inline]
    #[target_feature(enable = "sse2")]
    unsafe fn load8(src: &[u8], i: usize) -> __m128i {
        debug_assert!(i + 8 <= src.len());
        // SAFETY: the caller guarantees 8 readable bytes at `i`; the load has no alignment need.
        unsafe { _mm_loadl_epi64(src.as_ptr().add(i).cast()) }
    }

    /// Source points of lanes `0..N` of a group: `s + k ds`, wrapping (lanes past the run's end
    /// are computed but never used).
    #[inline(always)]
    fn lanes<const N: usize>(s: i32, ds: i32) -> [i32; N] {
        std::array::from_fn(|k| s.wrapping_add(ds.wrapping_mul(k as i32)))
    }

    /// SSE2 kernel: 4 pixels per iteration, one pixel per vector in the filter.
    #[inline]
    #[target_feature(enable = "sse2")]
    fn interior_sse2(src: &[u8], w: usize, out: &mut [u8], run: Interior) {
        let stride = w * 4;
        let limit = tap_limit(src, w);
        let groups = out.len() / 16;
        let (head, tail) = out.split_at_mut(groups * 16);
        let [a, b, c, d] = lanes::<4>(run.sx, run.dsx);
        let mut sx = _mm_setr_epi32(a, b, c, d);
        let [a, b, c, d] = lanes::<4>(run.sy, run.dsy);
        let mut sy = _mm_setr_epi32(a, b, c, d);
        let step_x = _mm_set1_epi32(run.dsx.wrapping_mul(4));
        let step_y = _mm_set1_epi32(run.dsy.wrapping_mul(4));
        let c128 = _mm_set1_epi32(128);
        let c256 = _mm_set1_epi32(256);
        let m255 = _mm_set1_epi32(255);
        // (x0, y0) as i16 pairs times (4, stride): the byte offset x0 * 4 + y0 * stride.
        let offset_mul = _mm_set1_epi32(4 | (stride as i32) << 16);
        let scale = _mm_set1_ps(SCALE);
        let half = _mm_set1_ps(0.5);
        let zero = _mm_setzero_si128();
        for chunk in head.chunks_exact_mut(16) {
            let sxf = _mm_srai_epi32::<8>(_mm_add_epi32(sx, c128));
            let syf = _mm_srai_epi32::<8>(_mm_add_epi32(sy, c128));
            let fx = _mm_and_si128(sxf, m255);
            let fy = _mm_and_si128(syf, m255);
            let gyfy = _mm_or_si128(_mm_sub_epi32(c256, fy), _mm_slli_epi32::<16>(fy));
            let gxf = _mm_mul_ps(_mm_cvtepi32_ps(_mm_sub_epi32(c256, fx)), scale);
            let fxf = _mm_mul_ps(_mm_cvtepi32_ps(fx), scale);
            let xy = _mm_or_si128(_mm_srli_epi32::<8>(sxf), _mm_slli_epi32::<8>(_mm_andnot_si128(m255, syf)));
            // SAFETY: __m128i and [i32; 4] have the same size and every bit pattern is valid.
            let offs = _mm_madd_epi16(xy, offset_mul);
            check_offsets_sse2(offs, limit);
            // SAFETY: __m128i and [i32; 4] have the same size and every bit pattern is valid.
            let offs: [i32; 4] = unsafe { std::mem::transmute(offs) };
            macro_rules! pixel {
                ($k:literal) => {{
                    let i = offs[$k] as usize;
                    // SAFETY: checked above: `i <= limit`, so `i + stride + 8 <= src.len()`.
                    let (top, bot) = unsafe { (load8(src, i), load8(src, i + stride)) };
                    let inter = _mm_unpacklo_epi8(top, bot);
                    let wy = _mm_shuffle_epi32::<{ $k * 0x55 }>(gyfy);
                    let left = _mm_cvtepi32_ps(_mm_madd_epi16(_mm_unpacklo_epi8(inter, zero), wy));
                    let right = _mm_cvtepi32_ps(_mm_madd_epi16(_mm_unpackhi_epi8(inter, zero), wy));
                    let acc = _mm_add_ps(_mm_mul_ps(left, _mm_shuffle_ps::<{ $k * 0x55 }>(gxf, gxf)), half);
                    _mm_cvttps_epi32(_mm_add_ps(
                        acc,
                        _mm_mul_ps(right, _mm_shuffle_ps::<{ $k * 0x55 }>(fxf, fxf)),
                    ))
                }};
            }
            let (p0, p1, p2, p3) = (pixel!(0), pixel!(1), pixel!(2), pixel!(3));
            let bytes = _mm_packus_epi16(_mm_packs_epi32(p0, p1), _mm_packs_epi32(p2, p3));
            let chunk: &mut [u8; 16] = chunk.try_into().expect("16 bytes");
            // SAFETY: `chunk` is 16 writable bytes; the unaligned store has no alignment need.
            unsafe { _mm_storeu_si128(chunk.as_mut_ptr().cast(), bytes) };
            sx = _mm_add_epi32(sx, step_x);
            sy = _mm_add_epi32(sy, step_y);
        }
        if !tail.is_empty() {
            let k = (groups * 4) as i32;
            let rest = Interior { sx: run.sx + k * run.dsx, sy: run.sy + k * run.dsy, ..run };
            interior_scalar(src, w, tail, rest);
        }
    }

    /// AVX2 + FMA kernel: 8 pixels per iteration, two pixels per vector in the filter.
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    fn interior_avx2(src: &[u8], w: usize, out: &mut [u8], run: Interior) {
        let stride = w * 4;
        let limit = tap_limit(src, w);
        let groups = out.len() / 32;
        let (head, tail) = out.split_at_mut(groups * 32);
        let [a, b, c, d, e, f, g, h] = lanes::<8>(run.sx, run.dsx);
        let mut sx = _mm256_setr_epi32(a, b, c, d, e, f, g, h);
        let [a, b, c, d, e, f, g, h] = lanes::<8>(run.sy, run.dsy);
        let mut sy = _mm256_setr_epi32(a, b, c, d, e, f, g, h);
        let step_x = _mm256_set1_epi32(run.dsx.wrapping_mul(8));
        let step_y = _mm256_set1_epi32(run.dsy.wrapping_mul(8));
        let c128 = _mm256_set1_epi32(128);
        let c256 = _mm256_set1_epi32(256);
        let m255 = _mm256_set1_epi32(255);
        let offset_mul = _mm256_set1_epi32(4 | (stride as i32) << 16);
        let scale = _mm256_set1_ps(SCALE);
        let half = _mm256_set1_ps(0.5);
        // Lane picks for pixel pair k: pixel 2k in the low half, 2k + 1 in the high half.
        let pick = [
            _mm256_setr_epi32(0, 0, 0, 0, 1, 1, 1, 1),
            _mm256_setr_epi32(2, 2, 2, 2, 3, 3, 3, 3),
            _mm256_setr_epi32(4, 4, 4, 4, 5, 5, 5, 5),
            _mm256_setr_epi32(6, 6, 6, 6, 7, 7, 7, 7),
        ];
        let order = _mm256_setr_epi32(0, 4, 1, 5, 2, 6, 3, 7);
        // Unsigned `offset > limit` as a signed compare of both biased by 2^31.
        let bias = _mm256_set1_epi32(i32::MIN);
        let biased_limit = _mm256_set1_epi32((limit as u32 ^ 1 << 31) as i32);
        for chunk in head.chunks_exact_mut(32) {
            let sxf = _mm256_srai_epi32::<8>(_mm256_add_epi32(sx, c128));
            let syf = _mm256_srai_epi32::<8>(_mm256_add_epi32(sy, c128));
            let fx = _mm256_and_si256(sxf, m255);
            let fy = _mm256_and_si256(syf, m255);
            let gyfy = _mm256_or_si256(_mm256_sub_epi32(c256, fy), _mm256_slli_epi32::<16>(fy));
            let gxf = _mm256_mul_ps(_mm256_cvtepi32_ps(_mm256_sub_epi32(c256, fx)), scale);
            let fxf = _mm256_mul_ps(_mm256_cvtepi32_ps(fx), scale);
            let xy = _mm256_or_si256(
                _mm256_srli_epi32::<8>(sxf),
                _mm256_slli_epi32::<8>(_mm256_andnot_si256(m255, syf)),
            );
            // SAFETY: __m256i and [i32; 8] have the same size and every bit pattern is valid.
            let offs = _mm256_madd_epi16(xy, offset_mul);
            let over = _mm256_cmpgt_epi32(_mm256_xor_si256(offs, bias), biased_limit);
            assert!(_mm256_movemask_epi8(over) == 0, "warp tap offset out of bounds");
            // SAFETY: __m256i and [i32; 8] have the same size and every bit pattern is valid.
            let offs: [i32; 8] = unsafe { std::mem::transmute(offs) };
            // A macro, not a closure: closures do not inherit `target_feature`, so the intrinsics
            // in one would become calls.
            macro_rules! pair {
                ($k:literal) => {{
                    let k: usize = $k;
                    let (a, b) = (offs[2 * k] as usize, offs[2 * k + 1] as usize);
                    // SAFETY: checked above: both offsets are at most `limit`, so the 8 bytes at
                    // them and one row (`stride` bytes) below lie inside `src`.
                    let (a0, b0, a1, b1) = unsafe {
                        (load8(src, a), load8(src, b), load8(src, a + stride), load8(src, b + stride))
                    };
                    // Rows y0 and y0 + 1 of both pixels: [A.p00, A.p10, B.p00, B.p10] -> [A.p00, B.p00,
                    // A.p10, B.p10] so that the byte interleave gives each column's vertical pairs.
                    let top = _mm_shuffle_epi32::<0b11_01_10_00>(_mm_unpacklo_epi64(a0, b0));
                    let bot = _mm_shuffle_epi32::<0b11_01_10_00>(_mm_unpacklo_epi64(a1, b1));
                    let wy = _mm256_permutevar8x32_epi32(gyfy, pick[k]);
                    let left = _mm256_madd_epi16(_mm256_cvtepu8_epi16(_mm_unpacklo_epi8(top, bot)), wy);
                    let right = _mm256_madd_epi16(_mm256_cvtepu8_epi16(_mm_unpackhi_epi8(top, bot)), wy);
                    let acc = _mm256_fmadd_ps(
                        _mm256_cvtepi32_ps(left),
                        _mm256_permutevar8x32_ps(gxf, pick[k]),
                        half,
                    );
                    let acc = _mm256_fmadd_ps(
                        _mm256_cvtepi32_ps(right),
                        _mm256_permutevar8x32_ps(fxf, pick[k]),
                        acc,
                    );
                    _mm256_cvttps_epi32(acc)
                }};
            }
            let (p01, p23, p45, p67) = (pair!(0), pair!(1), pair!(2), pair!(3));
            let bytes = _mm256_packus_epi16(_mm256_packs_epi32(p01, p23), _mm256_packs_epi32(p45, p67));
            let bytes = _mm256_permutevar8x32_epi32(bytes, order);
            let chunk: &mut [u8; 32] = chunk.try_into().expect("32 bytes");
            // SAFETY: `chunk` is 32 writable bytes; the unaligned store has no alignment need.
            unsafe { _mm256_storeu_si256(chunk.as_mut_ptr().cast(), bytes) };
            sx = _mm256_add_epi32(sx, step_x);
            sy = _mm256_add_epi32(sy, step_y);
        }
        if !tail.is_empty() {
            let k = (groups * 8) as i32;
            let rest = Interior { sx: run.sx + k * run.dsx, sy: run.sy + k * run.dsy, ..run };
            // A tail of 4 or more pixels still gets SIMD.
            interior_sse2(src, w, tail, rest);
        }
    }
}
