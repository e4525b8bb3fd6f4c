//! Behaviour of the warper as the issue states it: zero wind reproduces the picture byte for
//! byte, pixels outside every mask never change, and a constant velocity moves content by the
//! number of pixels computed by hand from seed 001, Eq. 5-8.

use frond_warp::Animator;
use frond_warp::layers::{LayerInput, Rgba, Scene};
use frond_warp::params::{Horizon, LayerParams, SceneParams, WindSource};
use frond_warp::warp::Warper;

const W: usize = 64;
const H: usize = 48;

/// A picture with detail everywhere (so any displacement shows).
fn picture() -> Rgba {
    let mut img = Rgba::filled(W, H, [0, 0, 0, 255]);
    for y in 0..H {
        for x in 0..W {
            let p = (y * W + x) * 4;
            let v = ((x * 37 + y * 91) % 256) as u8;
            img.data[p..p + 3].copy_from_slice(&[v, (x * 4) as u8, (y * 5) as u8]);
        }
    }
    img
}

/// Lower half is grass with a soft (anti-aliased) top edge; a bush-like blob in the top right.
fn masks() -> (Vec<u8>, Vec<u8>) {
    let grass = (0..W * H)
        .map(|p| match p / W {
            y if y >= 26 => 255,
            25 => 170,
            24 => 60,
            _ => 0,
        })
        .collect();
    let bush = (0..W * H)
        .map(|p| {
            let (x, y) = ((p % W) as f32, (p / W) as f32);
            let d = ((x - 48.0).powi(2) + (y - 10.0).powi(2)).sqrt();
            ((8.0 - d).clamp(0.0, 1.0) * 255.0) as u8
        })
        .collect();
    (grass, bush)
}

fn animator(strength: f32, layers: &[Vec<u8>]) -> Animator {
    let inputs =
        layers.iter().enumerate().map(|(i, m)| (format!("mask{i}"), LayerInput::Mask(m.clone()))).collect();
    let scene = Scene::build(picture(), inputs, None, None).unwrap();
    let mut p = SceneParams::default();
    p.wind.strength = strength;
    p.wind.interval_s = 0.0;
    p.wind.direction_deg = 20.0;
    p.fluid.grid = 16;
    p.layers =
        vec![
            LayerParams { horizon: Horizon::None, lambda_x: 40.0, lambda_y: 40.0, ..Default::default() };
            layers.len()
        ];
    Animator::new(scene, p).unwrap()
}

#[test]
fn zero_wind_gives_the_input_byte_for_byte() {
    let (grass, bush) = masks();
    let mut a = animator(0.0, &[grass, bush]);
    let input = picture().data;
    assert_eq!(a.frame(), &input[..], "first frame");
    for k in 0..30 {
        let f = a.step(1.0 / 30.0);
        assert_eq!(f, &input[..], "frame {k} differs from the input");
    }
}

#[test]
fn pixels_outside_every_mask_never_change() {
    let (grass, bush) = masks();
    let mut a = animator(1.0, &[grass.clone(), bush.clone()]);
    let input = picture().data;
    let mut moved_inside = 0usize;
    for _ in 0..40 {
        let f = a.step(1.0 / 30.0).to_vec();
        for p in 0..W * H {
            if grass[p] == 0 && bush[p] == 0 {
                assert_eq!(
                    &f[p * 4..p * 4 + 4],
                    &input[p * 4..p * 4 + 4],
                    "pixel ({}, {}) changed",
                    p % W,
                    p / W
                );
            } else if f[p * 4..p * 4 + 3] != input[p * 4..p * 4 + 3] {
                moved_inside += 1;
            }
        }
    }
    // The test must be able to fail: the layers really moved.
    assert!(moved_inside > 1000, "only {moved_inside} changed pixels inside the masks");
    assert!(a.max_displacement() > 1.0, "{}", a.max_displacement());
}

#[test]
fn point_source_wind_only_touches_the_layers_too() {
    let (grass, _) = masks();
    let scene =
        Scene::build(picture(), vec![("g".into(), LayerInput::Mask(grass.clone()))], None, None).unwrap();
    let mut p = SceneParams::default();
    p.wind.strength = 1.0;
    p.wind.source = WindSource::Point { x: 0.5, y: 0.7 };
    p.wind.radius = 0.2;
    p.fluid.grid = 16;
    let mut a = Animator::new(scene, p).unwrap();
    let input = picture().data;
    for _ in 0..20 {
        let f = a.step(1.0 / 30.0).to_vec();
        for p in (0..W * H).filter(|&p| grass[p] == 0) {
            assert_eq!(&f[p * 4..p * 4 + 4], &input[p * 4..p * 4 + 4]);
        }
    }
}

/// Vertical stripes: the colour encodes x, so a horizontal shift is visible as a colour change.
fn stripes() -> Vec<u8> {
    let mut v = vec![0u8; W * H * 4];
    for y in 0..H {
        for x in 0..W {
            let p = (y * W + x) * 4;
            v[p..p + 4].copy_from_slice(&[(x * 4) as u8, (y * 5) as u8, 7, 255]);
        }
    }
    v
}

#[test]
fn constant_velocity_moves_content_by_the_hand_computed_pixels() {
    // Eq. 5: n_x = lambda_x * R * V_px * dt = 2 * 1 * 0.5 * 0.5 = 0.5 cells;
    //        n_y = lambda_y * R * V_py * dt = 1 * 1 * 0.625 * 0.5 = 0.3125 cells.
    // Eq. 7: corners move by (-n_x s_x, -n_y s_y) = (-0.5 * 8, -0.3125 * 8) = (-4, -2.5) pixels.
    // Eq. 8: every pixel of every cell interpolates equal corner displacements, so the source of
    // output pixel (x, y) is (x - 4, y - 2.5): the content moves 4 px right and 2.5 px down.
    let mut w = Warper::new(W, H, 8, 8);
    w.set_displacements(0.5, [2.0, 1.0], |_| 1.0, |_, _| 1.0, |_, _| [0.5, 0.625]);
    let src = stripes();
    let mut dst = vec![0u8; src.len()];
    w.remap(&src, &mut dst);
    for y in 3..H {
        for x in 4..W {
            let o = (y * W + x) * 4;
            let s = ((y - 3) * W + (x - 4)) * 4; // row y - 3 and y - 2 average to y - 2.5
            let s2 = ((y - 2) * W + (x - 4)) * 4;
            assert_eq!(dst[o], src[s], "red (x) at ({x}, {y})");
            let green_expected = (src[s + 1] as f32 + src[s2 + 1] as f32) / 2.0;
            assert!((dst[o + 1] as f32 - green_expected).abs() <= 0.5, "green (y) at ({x}, {y})");
        }
    }
    // With a rigidity factor, Eq. 6 scales the shift: R = (l/h)^r with the bottom as horizon.
    // Rows 0..=40 of a layer spanning 0..=40, r = 1: at corner row y = 32, R = (40 - 32) / 40 = 0.2,
    // so the corner moves 0.2 * 4 = 0.8 px.
    let mut w = Warper::new(W, H, 8, 8);
    w.set_displacements(
        0.5,
        [2.0, 1.0],
        |y| frond_warp::warp::rigidity_factor(Horizon::Bottom, y, 0.0, 40.0, 1.0),
        |_, _| 1.0,
        |_, _| [0.5, 0.0],
    );
    assert!((w.corner(3, 4)[0] + 0.8).abs() < 1e-6, "{:?}", w.corner(3, 4));
}

#[test]
fn warp_over_composites_moved_layer_inside_its_region_only() {
    // A layer whose colours are the stripes, opaque in columns 20..40, over a flat background.
    let mut layer = stripes();
    let mut region = vec![0u8; W * H];
    for y in 0..H {
        for x in 0..W {
            let p = y * W + x;
            let inside = (20..40).contains(&x);
            layer[p * 4 + 3] = if inside { 255 } else { 0 };
            region[p] = inside as u8;
        }
    }
    let bg = Rgba::filled(W, H, [1, 2, 3, 255]).data;
    let mut frame = bg.clone();
    let mut w = Warper::new(W, H, 8, 8);
    // 3 px to the right.
    w.set_displacements(1.0, [1.0, 1.0], |_| 1.0, |_, _| 1.0, |_, _| [0.375, 0.0]);
    w.warp_over(&layer, &region, &mut frame);
    for y in 0..H {
        for x in 0..W {
            let o = (y * W + x) * 4;
            if !(20..40).contains(&x) {
                assert_eq!(&frame[o..o + 4], &bg[o..o + 4], "outside region at ({x}, {y})");
            } else if x < 23 {
                // Source x - 3 is left of the layer's alpha: background shows.
                assert_eq!(&frame[o..o + 3], &bg[o..o + 3], "uncovered at ({x}, {y})");
            } else {
                assert_eq!(frame[o], ((x - 3) * 4) as u8, "moved content at ({x}, {y})");
            }
        }
    }
}
