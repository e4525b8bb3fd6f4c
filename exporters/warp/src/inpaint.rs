//! A simple inpainting of the background under the vegetation (seed 001, section III-B, where the
//! paper uses texture synthesis): the hole is filled from its border inwards, each ring taking the
//! mean of its already known 8-neighbours, then smoothed by a few diffusion passes restricted to
//! the hole. Deterministic; cost proportional to the image size times a small constant.

use std::collections::VecDeque;

const SMOOTH_PASSES: usize = 8;

/// Fills the pixels of the opaque RGBA image `rgba` (`width x height`) where `hole` is true.
/// Pixels outside the hole are never changed. With no known pixel at all the hole becomes the
/// image's mean grey (black for an empty image).
pub fn inpaint(rgba: &mut [u8], width: usize, height: usize, hole: &[bool]) {
    let n = width * height;
    assert!(rgba.len() >= n * 4 && hole.len() >= n, "buffer size");
    if !hole.iter().take(n).any(|&h| h) {
        return;
    }
    // Ring index: 0 for known pixels, k for the k-th ring into the hole.
    let mut ring = vec![u32::MAX; n];
    let mut queue = VecDeque::new();
    for p in 0..n {
        if !hole[p] {
            ring[p] = 0;
        }
    }
    for p in 0..n {
        if hole[p] && neighbours(p, width, height).any(|q| ring[q] == 0) {
            ring[p] = 1;
            queue.push_back(p);
        }
    }
    if queue.is_empty() {
        // Nothing known: a flat grey.
        for p in 0..n {
            if hole[p] {
                rgba[p * 4..p * 4 + 4].copy_from_slice(&[128, 128, 128, 255]);
            }
        }
        return;
    }
    let mut order = Vec::new();
    while let Some(p) = queue.pop_front() {
        order.push(p);
        let r = ring[p];
        for q in neighbours(p, width, height) {
            if ring[q] == u32::MAX {
                ring[q] = r + 1;
                queue.push_back(q);
            }
        }
    }
    // Rings in order; each pixel averages neighbours of earlier rings only, so the result does not
    // depend on the order inside a ring.
    for &p in &order {
        let mut sum = [0u32; 3];
        let mut count = 0u32;
        for q in neighbours(p, width, height) {
            if ring[q] < ring[p] {
                for c in 0..3 {
                    sum[c] += rgba[q * 4 + c] as u32;
                }
                count += 1;
            }
        }
        for c in 0..3 {
            rgba[p * 4 + c] = ((sum[c] + count / 2) / count.max(1)) as u8;
        }
        rgba[p * 4 + 3] = 255;
    }
    // Smooth the fill (Jacobi, hole pixels only).
    let mut scratch = vec![[0u8; 3]; order.len()];
    for _ in 0..SMOOTH_PASSES {
        for (k, &p) in order.iter().enumerate() {
            let mut sum = [0u32; 3];
            let mut count = 0u32;
            for q in neighbours(p, width, height).chain(std::iter::once(p)) {
                for c in 0..3 {
                    sum[c] += rgba[q * 4 + c] as u32;
                }
                count += 1;
            }
            for c in 0..3 {
                scratch[k][c] = ((sum[c] + count / 2) / count) as u8;
            }
        }
        for (k, &p) in order.iter().enumerate() {
            rgba[p * 4..p * 4 + 3].copy_from_slice(&scratch[k]);
        }
    }
}

fn neighbours(p: usize, w: usize, h: usize) -> impl Iterator<Item = usize> {
    let (x, y) = ((p % w) as isize, (p / w) as isize);
    (-1isize..=1).flat_map(move |dy| (-1isize..=1).map(move |dx| (dx, dy))).filter_map(move |(dx, dy)| {
        let (nx, ny) = (x + dx, y + dy);
        if (dx, dy) != (0, 0) && nx >= 0 && ny >= 0 && nx < w as isize && ny < h as isize {
            Some(ny as usize * w + nx as usize)
        } else {
            None
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fills_a_hole_from_its_surroundings_and_leaves_the_rest() {
        let (w, h) = (12, 10);
        let mut img = vec![0u8; w * h * 4];
        for y in 0..h {
            for x in 0..w {
                let p = (y * w + x) * 4;
                img[p..p + 4].copy_from_slice(&[200, 50, (x * 20) as u8, 255]);
            }
        }
        let orig = img.clone();
        let hole: Vec<bool> =
            (0..w * h).map(|p| (3..8).contains(&(p % w)) && (2..7).contains(&(p / w))).collect();
        for (p, &is_hole) in hole.iter().enumerate() {
            if is_hole {
                img[p * 4..p * 4 + 3].copy_from_slice(&[0, 255, 0]);
            }
        }
        inpaint(&mut img, w, h, &hole);
        for (p, &is_hole) in hole.iter().enumerate() {
            if is_hole {
                // Constant channels are reproduced; the horizontal ramp stays within its range.
                assert_eq!(&img[p * 4..p * 4 + 2], &[200, 50]);
                let b = img[p * 4 + 2];
                assert!((40..=160).contains(&b), "pixel {p}: blue {b}");
            } else {
                assert_eq!(&img[p * 4..p * 4 + 4], &orig[p * 4..p * 4 + 4]);
            }
        }
    }
}
