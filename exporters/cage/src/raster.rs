//! Polygons to pixels: the pixels whose centres lie inside a closed polygon (even-odd rule).

use crate::Point;

/// Sets `mask[y * width + x] = 255` for each pixel whose centre `(x + 0.5, y + 0.5)` lies inside
/// `poly`; other pixels are left as they are.
pub fn fill_polygon(poly: &[Point], width: usize, height: usize, mask: &mut [u8]) {
    let n = poly.len();
    if n < 3 {
        return;
    }
    let [_, lo, _, hi] = crate::outline::bounds(poly);
    let y0 = (lo - 0.5).ceil().max(0.0) as usize;
    let y1 = ((hi - 0.5).floor().min(height as f64 - 1.0)).max(-1.0);
    if y1 < 0.0 {
        return;
    }
    let mut xs: Vec<f64> = Vec::new();
    for y in y0..=(y1 as usize) {
        let yc = y as f64 + 0.5;
        xs.clear();
        for i in 0..n {
            let (a, b) = (poly[i], poly[(i + 1) % n]);
            if (a[1] > yc) != (b[1] > yc) {
                xs.push(a[0] + (yc - a[1]) / (b[1] - a[1]) * (b[0] - a[0]));
            }
        }
        xs.sort_by(f64::total_cmp);
        for pair in xs.chunks_exact(2) {
            // Pixels with x + 0.5 in [pair[0], pair[1]).
            let from = (pair[0] - 0.5).ceil().max(0.0) as usize;
            let to = ((pair[1] - 0.5).ceil().min(width as f64)).max(0.0) as usize;
            for x in from..to {
                mask[y * width + x] = 255;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tree::contains;

    #[test]
    fn filled_pixels_are_those_whose_centres_are_inside() {
        let poly = [[1.2, 0.7], [9.6, 2.1], [7.3, 8.8], [4.0, 5.0], [0.4, 7.9]];
        let (w, h) = (12, 10);
        let mut mask = vec![0u8; w * h];
        fill_polygon(&poly, w, h, &mut mask);
        for y in 0..h {
            for x in 0..w {
                let inside = contains(&poly, [x as f64 + 0.5, y as f64 + 0.5]);
                assert_eq!(mask[y * w + x] == 255, inside, "pixel {x},{y}");
            }
        }
    }
}
