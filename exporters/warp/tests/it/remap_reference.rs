//! The fast remap against the first implementation, kept here as the reference: every kernel this
//! CPU runs (scalar, SSE2, AVX2) must give the same bytes on random fields, including fields that
//! push sources past the border, odd sizes and cell sizes, and still cells.

use frond_warp::warp::{RemapKernel, Warper};

/// The original per-pixel implementation of seed 001 Eq. 8 with bilinear filtering, unchanged:
/// source point interpolated per cell row in 1/65536 pixel, rounded to 1/256 pixel, clamped.
fn reference_remap(warper: &Warper, src: &[u8], dst: &mut [u8]) {
    const ONE: i32 = 256;
    let (w, h) = warper.size();
    let (cell_x, cell_y) = warper.cells();
    let (cols, _) = warper.corners();
    let max_x = (w as i32 - 1) * ONE;
    let max_y = (h as i32 - 1) * ONE;
    let inv_sx = 1.0 / cell_x as f32;
    let inv_sy = 1.0 / cell_y as f32;
    let lerp2 = |a: [f32; 2], b: [f32; 2], t: f32| [a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t];
    for y in 0..h {
        let cy = y / cell_y;
        let v = (y - cy * cell_y) as f32 * inv_sy;
        let mut x = 0;
        for cx in 0..cols - 1 {
            if x >= w {
                break;
            }
            let l = lerp2(warper.corner(cx, cy), warper.corner(cx, cy + 1), v);
            let r = lerp2(warper.corner(cx + 1, cy), warper.corner(cx + 1, cy + 1), v);
            let end = ((cx + 1) * cell_x).min(w);
            let x_start = cx * cell_x;
            const SUB: f32 = 65536.0;
            let sx0 = ((x_start as f32 + l[0]) * SUB).round() as i64;
            let sy0 = ((y as f32 + l[1]) * SUB).round() as i64;
            let dsx = ((1.0 + (r[0] - l[0]) * inv_sx) * SUB).round() as i64;
            let dsy = ((r[1] - l[1]) * inv_sx * SUB).round() as i64;
            let (mut sxa, mut sya) = (sx0 + (x - x_start) as i64 * dsx, sy0 + (x - x_start) as i64 * dsy);
            while x < end {
                let sxf = (((sxa + 128) >> 8) as i32).clamp(0, max_x);
                let syf = (((sya + 128) >> 8) as i32).clamp(0, max_y);
                let x0 = (sxf >> 8) as usize;
                let y0 = (syf >> 8) as usize;
                let (fx, fy) = ((sxf & 255) as u32, (syf & 255) as u32);
                let x1 = (x0 + 1).min(w - 1);
                let y1 = (y0 + 1).min(h - 1);
                let tap = |xx: usize, yy: usize, c: usize| src[(yy * w + xx) * 4 + c] as u32;
                let (gx, gy) = (256 - fx, 256 - fy);
                for c in 0..4 {
                    let top = tap(x0, y0, c) * gx + tap(x1, y0, c) * fx;
                    let bot = tap(x0, y1, c) * gx + tap(x1, y1, c) * fx;
                    dst[(y * w + x) * 4 + c] = ((top * gy + bot * fy + (1 << 15)) >> 16) as u8;
                }
                sxa += dsx;
                sya += dsy;
                x += 1;
            }
        }
    }
}

/// xorshift64*: a small deterministic generator (no dependency).
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    /// Uniform in [-a, a].
    fn sym(&mut self, a: f32) -> f32 {
        ((self.next() >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0) * a
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

fn check_all_kernels(warper: &Warper, src: &[u8], what: &str) {
    let (w, h) = warper.size();
    let mut expected = vec![0u8; w * h * 4];
    reference_remap(warper, src, &mut expected);
    for kernel in RemapKernel::available() {
        let mut got = vec![0xA5u8; w * h * 4];
        warper.remap_with(kernel, src, &mut got);
        if let Some(p) = (0..w * h).find(|&p| got[p * 4..p * 4 + 4] != expected[p * 4..p * 4 + 4]) {
            panic!(
                "{what}, kernel {}: pixel ({}, {}) is {:?}, reference {:?}",
                kernel.name(),
                p % w,
                p / w,
                &got[p * 4..p * 4 + 4],
                &expected[p * 4..p * 4 + 4]
            );
        }
    }
    let mut got = vec![0u8; w * h * 4];
    warper.remap(src, &mut got);
    assert!(got == expected, "{what}: default kernel differs from the reference");
}

#[test]
fn every_kernel_matches_the_reference_on_random_fields() {
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    // The test must exercise the SIMD kernels where the CPU has them.
    #[cfg(target_arch = "x86_64")]
    assert!(RemapKernel::available().contains(&RemapKernel::Sse2));
    for case in 0..60 {
        let w = 1 + rng.below(90);
        let h = 1 + rng.below(60);
        let (cell_x, cell_y) = (1 + rng.below(24), 1 + rng.below(24));
        let src: Vec<u8> = (0..w * h * 4).map(|_| rng.next() as u8).collect();
        let mut warper = Warper::new(w, h, cell_x, cell_y);
        let (cols, rows) = warper.corners();
        // Small, medium and border-crossing displacements; some corners still.
        let amp = [0.3, 2.5, 12.0, 60.0][case % 4];
        for cy in 0..rows {
            for cx in 0..cols {
                if rng.below(5) > 0 {
                    warper.set_corner(cx, cy, [rng.sym(amp), rng.sym(amp)]);
                }
            }
        }
        check_all_kernels(
            &warper,
            &src,
            &format!("case {case}: {w}x{h}, cells {cell_x}x{cell_y}, amp {amp}"),
        );
    }
}

#[test]
fn every_kernel_matches_the_reference_on_a_smooth_hd_field() {
    // The benchmark's kind of field at a size whose runs fill whole SIMD groups and leave tails.
    let (w, h) = (333, 211);
    let mut rng = Rng(7);
    let src: Vec<u8> = (0..w * h * 4).map(|_| rng.next() as u8).collect();
    for (cell_x, cell_y) in [(16, 16), (13, 7), (8, 32)] {
        let mut warper = Warper::new(w, h, cell_x, cell_y);
        let (cols, rows) = warper.corners();
        for cy in 0..rows {
            for cx in 0..cols {
                let (x, y) = (cx as f32 * 0.21, cy as f32 * 0.17);
                warper.set_corner(cx, cy, [5.0 * (x + 0.5 * y).sin(), 3.0 * (0.7 * x - y).cos()]);
            }
        }
        check_all_kernels(&warper, &src, &format!("smooth field, cells {cell_x}x{cell_y}"));
    }
}

#[test]
fn whole_pixel_shifts_and_still_cells_match_the_reference() {
    // Still corners (copied rows), whole-pixel shifts (copied from elsewhere), and shifts that
    // would read past the border (clamped path).
    let (w, h) = (70, 40);
    let mut rng = Rng(99);
    let src: Vec<u8> = (0..w * h * 4).map(|_| rng.next() as u8).collect();
    for d in [[0.0, 0.0], [3.0, 0.0], [-2.0, 5.0], [0.0, -1.0], [40.0, 0.0], [-80.0, 3.0], [0.5, 0.0]] {
        let mut warper = Warper::new(w, h, 16, 16);
        let (cols, rows) = warper.corners();
        for cy in 0..rows {
            for cx in 0..cols {
                warper.set_corner(cx, cy, d);
            }
        }
        check_all_kernels(&warper, &src, &format!("uniform shift {d:?}"));
    }
}
