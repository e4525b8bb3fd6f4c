//! `frond-warp morph` (seed 004, section 5): a textured RGBA layer over a plain background,
//! morphed towards sketches; expected pictures are worked out independently (a translation moves
//! every pixel by the same whole offset; the target outline is a polygon tested pixel by pixel).

use std::path::{Path, PathBuf};

use crate::common;
use common::{run, s, stderr, write_take_on, write_take_with};

const W: usize = 160;
const H: usize = 120;
const BG: [u8; 3] = [40, 60, 200];

fn in_blob(x: f64, y: f64) -> bool {
    [(60.0, 60.0, 30.0), (85.0, 45.0, 24.0), (80.0, 80.0, 20.0)]
        .iter()
        .any(|&(cx, cy, r): &(f64, f64, f64)| (x - cx).hypot(y - cy) < r)
}

/// Layer colour at pixel (x, y): stripes in red and green, blue 0 (the background's is 200).
fn texture(x: usize, y: usize) -> [u8; 3] {
    [((x * 7 + y * 3) % 256) as u8, (120 + (x * 5 + y * 11) % 120) as u8, 0]
}

struct Inputs {
    _dir: tempfile::TempDir,
    bg: PathBuf,
    layer: PathBuf,
    cage: PathBuf,
    crown: Vec<[f64; 2]>,
    dir: PathBuf,
}

fn inputs() -> Inputs {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().to_path_buf();
    let bg: Vec<u8> = (0..W * H).flat_map(|_| BG).collect();
    let mut layer = vec![0u8; W * H * 4];
    for y in 0..H {
        for x in 0..W {
            if in_blob(x as f64 + 0.5, y as f64 + 0.5) {
                let c = texture(x, y);
                layer[(y * W + x) * 4..][..4].copy_from_slice(&[c[0], c[1], c[2], 255]);
            }
        }
    }
    let (bgp, lp, cage) = (d.join("bg.png"), d.join("layer.png"), d.join("cage.json"));
    image::save_buffer(&bgp, &bg, W as u32, H as u32, image::ColorType::Rgb8).unwrap();
    image::save_buffer(&lp, &layer, W as u32, H as u32, image::ColorType::Rgba8).unwrap();
    let o = run(&["cage", "build", "--layer", s(&lp), "-o", s(&cage)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let tree: serde_json::Value = serde_json::from_slice(&std::fs::read(&cage).unwrap()).unwrap();
    let crown = tree["cages"][0]["vertices"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| [v[0].as_f64().unwrap(), v[1].as_f64().unwrap()])
        .collect();
    Inputs { _dir: dir, bg: bgp, layer: lp, cage, crown, dir: d }
}

fn sketch(dir: &Path, name: &str, closed: bool, points: &[[f64; 2]]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, serde_json::json!({"version": 1, "closed": closed, "points": points}).to_string())
        .unwrap();
    p
}

/// Runs a morph of `frames` frames into a directory; returns the frames and the report.
fn morph(inp: &Inputs, sketch: &Path, frames: usize, extra: &[&str]) -> (Vec<Vec<u8>>, serde_json::Value) {
    let out = inp.dir.join(format!("out-{}/", sketch.file_stem().unwrap().to_str().unwrap()));
    let report = inp.dir.join("report.json");
    let n = frames.to_string();
    let mut args = vec!["morph", "--image", s(&inp.bg), "--layer", s(&inp.layer), "--sketch", s(sketch)];
    args.extend(["--cage", s(&inp.cage), "--frames", &n, "-o", s(&out), "--report", s(&report), "--quiet"]);
    args.extend(extra);
    let o = run(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    let mut names: Vec<_> = std::fs::read_dir(&out).unwrap().map(|e| e.unwrap().path()).collect();
    names.sort();
    let frames = names.iter().map(|p| image::open(p).unwrap().to_rgb8().into_raw()).collect();
    (frames, serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap())
}

fn px(frame: &[u8], x: usize, y: usize) -> [u8; 3] {
    frame[(y * W + x) * 3..][..3].try_into().unwrap()
}

/// The still picture: the layer over the background, computed here.
fn still(x: usize, y: usize) -> [u8; 3] {
    if in_blob(x as f64 + 0.5, y as f64 + 0.5) { texture(x, y) } else { BG }
}

#[test]
fn a_sketch_equal_to_the_outline_changes_nothing() {
    let inp = inputs();
    let sk = sketch(&inp.dir, "same", true, &inp.crown);
    let (frames, report) = morph(&inp, &sk, 3, &[]);
    for (k, f) in frames.iter().enumerate() {
        for y in 0..H {
            for x in 0..W {
                assert_eq!(px(f, x, y), still(x, y), "frame {k} pixel {x},{y}");
            }
        }
    }
    assert_eq!(report["pruned"], serde_json::json!([]));
}

/// Mean value coordinates reproduce affine maps and Eq. 1 is translation invariant: a sketch that
/// is the outline moved by (10, 5) moves every pixel by (10, 5), texture and all.
#[test]
fn a_translated_sketch_carries_the_texture_unsmeared() {
    let inp = inputs();
    let moved: Vec<[f64; 2]> = inp.crown.iter().map(|v| [v[0] + 10.0, v[1] + 5.0]).collect();
    let sk = sketch(&inp.dir, "moved", true, &moved);
    // No pruning: the lobes the moved outline leaves behind would wilt (section 5.4.2).
    let (frames, report) = morph(&inp, &sk, 5, &["--no-prune"]);
    let last = frames.last().unwrap();
    let (mut inside, mut outside) = (0, 0);
    let mut bad = Vec::new();
    for y in 0..H {
        for x in 0..W {
            let (sx, sy) = (x as f64 - 10.0 + 0.5, y as f64 - 5.0 + 0.5);
            // Well inside the moved blob: the source pixel's colour exactly.
            let deep = (0..16).all(|k| {
                let a = std::f64::consts::TAU * k as f64 / 16.0;
                in_blob(sx + 2.5 * a.cos(), sy + 2.5 * a.sin())
            });
            if deep {
                if px(last, x, y) != texture(x - 10, y - 5) {
                    bad.push((x, y, px(last, x, y), texture(x - 10, y - 5)));
                }
                inside += 1;
            }
            // Well outside it: background.
            let far = (0..16).all(|k| {
                let a = std::f64::consts::TAU * k as f64 / 16.0;
                !in_blob(sx + 4.0 * a.cos(), sy + 4.0 * a.sin())
            }) && !in_blob(sx, sy);
            if far {
                assert_eq!(px(last, x, y), BG, "pixel {x},{y} should be background");
                outside += 1;
            }
        }
    }
    assert!(bad.is_empty(), "{} of {inside} pixels differ: {:?}", bad.len(), &bad[..bad.len().min(12)]);
    assert!(inside > 3000 && outside > 10_000, "{inside} {outside}");
    let frechet: Vec<f64> =
        report["frechet_px"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
    assert_eq!(report["t"], serde_json::json!([0.0, 0.25, 0.5, 0.75, 1.0]));
    assert!(frechet.iter().all(|&d| d < 3.0), "outline far from the reference: {frechet:?}");
}

/// Point in polygon (even-odd), written here.
fn inside(poly: &[[f64; 2]], x: f64, y: f64) -> bool {
    let mut c = false;
    for i in 0..poly.len() {
        let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
        if (a[1] > y) != (b[1] > y) && x < a[0] + (y - a[1]) / (b[1] - a[1]) * (b[0] - a[0]) {
            c = !c;
        }
    }
    c
}

fn near_outline(poly: &[[f64; 2]], x: f64, y: f64, d: f64) -> bool {
    (0..64).any(|k| {
        let a = std::f64::consts::TAU * k as f64 / 64.0;
        inside(poly, x + d * a.cos(), y + d * a.sin()) != inside(poly, x, y)
    })
}

fn ellipse(c: [f64; 2], r: [f64; 2]) -> Vec<[f64; 2]> {
    (0..120)
        .map(|k| {
            let a = std::f64::consts::TAU * k as f64 / 120.0;
            [c[0] + r[0] * a.cos(), c[1] + r[1] * a.sin()]
        })
        .collect()
}

#[test]
fn a_closed_sketch_ends_with_the_layer_on_its_outline_texture_carried() {
    let inp = inputs();
    // A flat ellipse: the blob (x 30-104, y 21-100) is squashed and widened.
    let target = ellipse([70.0, 60.0], [45.0, 30.0]);
    let sk = sketch(&inp.dir, "ellipse", true, &target);
    let (frames, report) = morph(&inp, &sk, 6, &[]);
    let last = frames.last().unwrap();
    let (mut agree, mut total) = (0, 0);
    for y in 0..H {
        for x in 0..W {
            let (cx, cy) = (x as f64 + 0.5, y as f64 + 0.5);
            let is_layer = px(last, x, y)[2] != BG[2];
            let want = inside(&target, cx, cy);
            total += 1;
            if is_layer == want {
                agree += 1;
            } else {
                assert!(
                    near_outline(&target, cx, cy, 3.0),
                    "pixel {x},{y} (layer {is_layer}) is far from the outline"
                );
            }
        }
    }
    assert!(agree as f64 / total as f64 > 0.99, "{agree} of {total}");
    let frechet: Vec<f64> =
        report["frechet_px"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
    assert!(frechet.iter().all(|&d| d < 5.0), "{frechet:?}");
    // Texture carried, not smeared: the stripes keep their contrast inside.
    let grad = |f: &[u8], own: bool| {
        let (mut sum, mut n) = (0.0, 0);
        for y in 1..H - 1 {
            for x in 1..W - 1 {
                let (cx, cy) = (x as f64 + 0.5, y as f64 + 0.5);
                let take = if own { in_blob(cx, cy) } else { inside(&target, cx, cy) };
                if take && px(f, x + 1, y)[2] == 0 && px(f, x, y)[2] == 0 {
                    sum += (px(f, x + 1, y)[0] as f64 - px(f, x, y)[0] as f64).abs();
                    n += 1;
                }
            }
        }
        sum / n.max(1) as f64
    };
    let (g0, g1) = (grad(&frames[0], true), grad(last, false));
    assert!(g1 > 0.5 * g0, "stripes smeared: mean gradient {g1:.1} against {g0:.1}");
}

#[test]
fn lobes_mostly_outside_a_closed_sketch_are_pruned_and_fade() {
    let inp = inputs();
    // An upright ellipse over the blob's left part: lobes on the right fall mostly outside.
    let target = ellipse([58.0, 62.0], [26.0, 40.0]);
    let sk = sketch(&inp.dir, "narrow", true, &target);
    let (frames, report) = morph(&inp, &sk, 3, &[]);
    assert!(!report["pruned"].as_array().unwrap().is_empty(), "{report}");
    let (kept_frames, kept) = morph(&inp, &sk, 3, &["--no-prune"]);
    assert_eq!(kept["pruned"], serde_json::json!([]));
    // Halfway, pruned lobes are half faded: fewer pixels are pure layer colour than without.
    let pure = |f: &[u8]| (0..W * H).filter(|&i| f[i * 3 + 2] == 0).count();
    assert!(pure(&frames[1]) < pure(&kept_frames[1]), "{} vs {}", pure(&frames[1]), pure(&kept_frames[1]));
    // At the end nothing is drawn outside the sketch (beyond the layer's 1-2 px slack).
    for y in 0..H {
        for x in 0..W {
            let (cx, cy) = (x as f64 + 0.5, y as f64 + 0.5);
            if !inside(&target, cx, cy) && !near_outline(&target, cx, cy, 3.0) {
                assert_eq!(px(frames.last().unwrap(), x, y), BG, "pixel {x},{y}");
            }
        }
    }
}

#[test]
fn an_open_stroke_reshapes_only_the_side_it_follows() {
    let inp = inputs();
    // A stroke left of the blob, from above to below its leftmost point (30, 60).
    let stroke: Vec<[f64; 2]> = (0..=30).map(|k| [22.0, 42.0 + k as f64 * 1.2]).collect();
    let sk = sketch(&inp.dir, "stroke", false, &stroke);
    let (frames, _) = morph(&inp, &sk, 3, &[]);
    let last = frames.last().unwrap();
    let leftmost = (0..W).find(|&x| (0..H).any(|y| px(last, x, y)[2] != BG[2])).unwrap();
    assert!(
        (19..=25).contains(&leftmost),
        "the left side reaches the stroke at x 22 (within 3 px): {leftmost}"
    );
    // The far side barely moves (mean value coordinates are global, so not exactly nothing):
    // on the right third the picture is the still one within a fraction of a level on average.
    let (mut diff, mut n) = (0.0, 0);
    for y in 0..H {
        for x in 100..W {
            let (a, b) = (px(last, x, y), still(x, y));
            diff += (0..3).map(|c| (a[c] as f64 - b[c] as f64).abs()).sum::<f64>() / 3.0;
            n += 1;
        }
    }
    assert!(diff / (n as f64) < 0.5, "the far side changed by {:.2} levels on average", diff / n as f64);
}

#[test]
fn bad_sketches_frames_and_cages_are_refused_by_name() {
    let inp = inputs();
    let bad = sketch(&inp.dir, "bad", true, &[[1.0, 1.0], [500.0, 1.0], [5.0, 5.0]]);
    let args = |sk: &Path, extra: &[&str]| {
        let mut a: Vec<String> =
            ["morph", "--image", s(&inp.bg), "--layer", s(&inp.layer), "--sketch", s(sk)]
                .iter()
                .map(|x| x.to_string())
                .collect();
        a.extend(extra.iter().map(|x| x.to_string()));
        a
    };
    let go = |a: Vec<String>| {
        let a: Vec<&str> = a.iter().map(String::as_str).collect();
        run(&a)
    };
    let o = go(args(&bad, &["-o", "x.gif"]));
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("point 1: [500, 1] is not a point of the 160x120 picture"), "{}", stderr(&o));
    let o = go(args(&bad, &["--frames", "0", "--fps", "0", "-o", "x.bmp"]));
    let e = stderr(&o);
    assert!(e.contains("--frames") && e.contains("--fps") && e.contains("--output"), "{e}");
    let small = inp.dir.join("small.json");
    std::fs::write(&small, r#"{"version":1,"size":[10,10],"cages":[{"id":0,"parent":null,"kind":"leaf","vertices":[[1,1],[9,1],[5,9]]}]}"#).unwrap();
    let ok = sketch(&inp.dir, "ok", true, &inp.crown);
    let o = go(args(&ok, &["--cage", s(&small), "-o", "x.gif"]));
    assert!(stderr(&o).contains("is for a 10x10 picture"), "{}", stderr(&o));
}

/// Seed 000, Eq. 1 with only the root joint turned is a rigid turn of the whole plant about the
/// root joint; mean value coordinates reproduce it, so the picture turns rigidly: worked out here
/// from the rig's joint heights and the crown's box, and sampled bilinearly by this test.
#[test]
fn the_skeleton_driven_cage_mode_turns_the_plant_with_the_take() {
    let inp = inputs();
    let take = inp.dir.join("lean.take");
    let yaw = 12.0f64;
    write_take_with(&take, 100, |_| yaw as f32); // one pose held for 1 s
    let out = inp.dir.join("lean/");
    let o = run(&[
        "render",
        "--mode",
        "cage",
        "--image",
        s(&inp.bg),
        "--layer",
        s(&inp.layer),
        "--cage",
        s(&inp.cage),
        "--take",
        s(&take),
        "--frames",
        "2",
        "-o",
        s(&out),
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let last = image::open(out.join("frame_00001.png")).unwrap().to_rgb8().into_raw();
    // The skeleton stands at the crown's bottom centre; the crown's top is the top joint.
    let (x0, x1) = inp.crown.iter().fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p[0]), b.max(p[0])));
    let (y0, y1) = inp.crown.iter().fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p[1]), b.max(p[1])));
    let rig = frond_formats::rig_files::load_rig("grass").unwrap().rig;
    let (h0, h3) = (rig.joints[0].height_m as f64, rig.joints[3].height_m as f64);
    let scale = (y1 - y0) / h3;
    let c = [(x0 + x1) / 2.0, y1 - scale * h0];
    let (sn, cs) = yaw.to_radians().sin_cos();
    // The source of picture point q: the inverse turn (counter-clockwise on screen).
    let source = |q: [f64; 2]| {
        let (dx, dy) = (q[0] - c[0], q[1] - c[1]);
        [c[0] + cs * dx - sn * dy, c[1] + sn * dx + cs * dy]
    };
    let (mut checked, mut worst) = (0, 0.0f64);
    let (mut agree, mut total) = (0, 0);
    for y in 0..H {
        for x in 0..W {
            let q = [x as f64 + 0.5, y as f64 + 0.5];
            let src = source(q);
            let want_layer = in_blob(src[0], src[1]);
            let is_layer = px(&last, x, y)[2] != BG[2];
            total += 1;
            if is_layer == want_layer {
                agree += 1;
            } else {
                let edge = (0..16).any(|k| {
                    let a = std::f64::consts::TAU * k as f64 / 16.0;
                    in_blob(src[0] + 2.0 * a.cos(), src[1] + 2.0 * a.sin()) != want_layer
                });
                assert!(edge, "pixel {x},{y} (layer {is_layer}) is far from the turned outline");
            }
            // Bilinear sample of the texture at the source pixel position, where all four taps
            // are well inside the blob and the stripes do not wrap between them.
            let (sx, sy) = (src[0] - 0.5, src[1] - 0.5);
            let (ix, iy) = (sx.floor() as i64, sy.floor() as i64);
            let taps = [(ix, iy), (ix + 1, iy), (ix, iy + 1), (ix + 1, iy + 1)];
            let deep = taps.iter().all(|&(tx, ty)| {
                tx >= 0
                    && ty >= 0
                    && (0..8).all(|k| {
                        let a = std::f64::consts::TAU * k as f64 / 8.0;
                        in_blob(tx as f64 + 0.5 + 2.0 * a.cos(), ty as f64 + 0.5 + 2.0 * a.sin())
                    })
            });
            if !deep {
                continue;
            }
            let tex: Vec<[u8; 3]> = taps.iter().map(|&(tx, ty)| texture(tx as usize, ty as usize)).collect();
            if (0..2).any(|ch| {
                tex.iter().map(|t| t[ch] as i32).max().unwrap()
                    - tex.iter().map(|t| t[ch] as i32).min().unwrap()
                    > 40
            }) {
                continue; // a stripe wraps between the taps
            }
            let (fx, fy) = (sx - ix as f64, sy - iy as f64);
            let got = px(&last, x, y);
            for ch in 0..2 {
                let v = |i: usize| tex[i][ch] as f64;
                let want =
                    (v(0) * (1.0 - fx) + v(1) * fx) * (1.0 - fy) + (v(2) * (1.0 - fx) + v(3) * fx) * fy;
                worst = worst.max((got[ch] as f64 - want).abs());
            }
            checked += 1;
        }
    }
    assert!(checked > 2000, "{checked}");
    assert!(worst <= 2.5, "the turned texture is {worst} levels from the rigid turn");
    assert!(agree as f64 / total as f64 > 0.99, "{agree} of {total} pixels agree on the silhouette");
    let first = image::open(out.join("frame_00000.png")).unwrap().to_rgb8().into_raw();
    assert_eq!(first, last, "one pose, one picture");
    // Wrong combinations are refused by name.
    let o = run(&[
        "render",
        "--mode",
        "cage",
        "--image",
        s(&inp.bg),
        "--layer",
        s(&inp.layer),
        "--frames",
        "2",
        "-o",
        "x.gif",
        "--anchor",
        "a,b",
    ]);
    let e = stderr(&o);
    assert!(e.contains("--take") && e.contains("--anchor"), "{e}");
}

#[test]
fn a_takes_rig_name_is_never_opened_as_a_path() {
    // A take keeps the name of its rig; one naming a path there must not make `render --mode
    // cage` read that file (the old frond-warp loaded it and rendered). Its own rig is an
    // embedded one; a rig file is given with --rig FILE.
    let inp = inputs();
    let rig_file = inp.dir.join("mine.toml");
    let grass = frond_formats::rig_files::EMBEDDED_RIGS[0].1;
    std::fs::write(&rig_file, grass.replacen("\nname = \"grass\"\n", "\nname = \"mine\"\n", 1)).unwrap();
    let render = |take: &Path, out: &Path, extra: &[&str]| {
        let mut args = vec!["render", "--mode", "cage", "--image", s(&inp.bg), "--layer", s(&inp.layer)];
        args.extend(["--cage", s(&inp.cage), "--take", s(take), "--frames", "2", "-o", s(out), "--quiet"]);
        args.extend(extra);
        run(&args)
    };
    for (name, rig) in [("by_path", s(&rig_file)), ("by_name", "mine"), ("device", "/dev/zero")] {
        let take = inp.dir.join(format!("{name}.take"));
        write_take_on(&take, rig, 100, |_| 10.0);
        let out = inp.dir.join(format!("{name}.gif"));
        let o = render(&take, &out, &[]);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{name}: {e}");
        assert!(e.contains(&format!("rig {rig:?} is not an embedded rig (grass, flower, shrub)")), "{e}");
        assert!(e.contains("give that file with --rig FILE"), "{e}");
        assert!(!out.exists(), "{name}: nothing is written");
        // Given with --rig, the file is the operator's word, and is read.
        if name == "by_name" {
            let o = render(&take, &out, &["--rig", s(&rig_file)]);
            assert!(o.status.success(), "{}", stderr(&o));
            assert!(out.is_file());
        }
    }
}
