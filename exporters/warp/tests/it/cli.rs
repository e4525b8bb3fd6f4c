//! The `frond-warp` binary: offline rendering (deterministic, byte-exact at zero wind, driven by
//! a take), sample generation, and clear errors for bad input.

use std::path::{Path, PathBuf};

use crate::common;
use common::{bin, run, s, stderr, write_take_with};
use frond_formats::rig_toml::RigText;

const W: u32 = 64;
const H: u32 = 48;

/// Writes a 64x48 picture, a grass mask (lower half, soft top row) and returns their paths.
fn inputs(dir: &Path) -> (PathBuf, PathBuf) {
    let mut pic = Vec::new();
    for y in 0..H {
        for x in 0..W {
            pic.extend_from_slice(&[((x * 37 + y * 11) % 256) as u8, (x * 4) as u8, (y * 5) as u8]);
        }
    }
    let mask: Vec<u8> = (0..W * H)
        .map(|p| {
            if p / W > 24 {
                255
            } else if p / W == 24 {
                128
            } else {
                0
            }
        })
        .collect();
    let (ip, mp) = (dir.join("pic.png"), dir.join("mask.png"));
    image::save_buffer(&ip, &pic, W, H, image::ColorType::Rgb8).unwrap();
    image::save_buffer(&mp, &mask, W, H, image::ColorType::L8).unwrap();
    (ip, mp)
}

fn frames(dir: &Path) -> Vec<Vec<u8>> {
    let mut names: Vec<_> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().path()).collect();
    names.sort();
    names.iter().map(|p| image::open(p).unwrap().to_rgba8().into_raw()).collect()
}

#[test]
fn zero_wind_render_equals_the_input_png() {
    let t = tempfile::tempdir().unwrap();
    let (pic, mask) = inputs(t.path());
    let out = t.path().join("frames/");
    let o = run(&[
        "render",
        "--image",
        s(&pic),
        "--layer",
        s(&mask),
        "--strength",
        "0",
        "--frames",
        "5",
        "--fps",
        "30",
        "-o",
        s(&out),
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let input = image::open(&pic).unwrap().to_rgba8().into_raw();
    let fs = frames(&out);
    assert_eq!(fs.len(), 5);
    for (k, f) in fs.iter().enumerate() {
        assert!(f == &input, "frame {k} differs from the input");
    }
}

#[test]
fn render_is_deterministic_for_a_seed_and_gif_and_webp_are_written() {
    let t = tempfile::tempdir().unwrap();
    let (pic, mask) = inputs(t.path());
    let render = |seed: &str, out: &Path| {
        let o = run(&[
            "render",
            "--image",
            s(&pic),
            "--layer",
            s(&mask),
            "--strength",
            "1",
            "--interval",
            "0.3",
            "--fluid-grid",
            "16",
            "--seed",
            seed,
            "--frames",
            "12",
            "-o",
            s(out),
            "--quiet",
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
    };
    let (a, b, c) = (t.path().join("a/"), t.path().join("b/"), t.path().join("c/"));
    render("5", &a);
    render("5", &b);
    render("6", &c);
    let (fa, fb, fc) = (frames(&a), frames(&b), frames(&c));
    assert_eq!(fa, fb, "same seed, different frames");
    assert_ne!(fa, fc, "the seed has no effect");
    assert_ne!(fa[11], fa[0], "nothing moves");

    let gif = t.path().join("out.gif");
    render("5", &gif);
    let dec =
        image::codecs::gif::GifDecoder::new(std::io::BufReader::new(std::fs::File::open(&gif).unwrap()))
            .unwrap();
    use image::AnimationDecoder;
    assert_eq!(dec.into_frames().count(), 12);
    let webp = t.path().join("out.webp");
    render("5", &webp);
    let dec =
        image::codecs::webp::WebPDecoder::new(std::io::BufReader::new(std::fs::File::open(&webp).unwrap()))
            .unwrap();
    let wf: Vec<_> = dec.into_frames().collect::<Result<_, _>>().unwrap();
    assert_eq!(wf.len(), 12);
    assert_eq!(wf[7].buffer().as_raw(), &fa[7], "webp frames are lossless");
}

/// A take whose root joint sways +-30 degrees of yaw at 1 Hz for 2 s at 100 Hz.
fn write_take(path: &Path) {
    write_take_with(path, 200, |t| 30.0 * (std::f64::consts::TAU * t).sin() as f32)
}

/// Renders 20 frames of `pic` with `mask` as its layer on a 16-cell wind grid, with `extra`
/// arguments, into the directory `out`; returns the frames.
fn render_20(pic: &Path, mask: &Path, extra: &[&str], out: &Path) -> Vec<Vec<u8>> {
    let mut args = vec!["render", "--image", s(pic), "--layer", s(mask), "--fluid-grid", "16"];
    args.extend_from_slice(&["--frames", "20", "-o", s(out), "--quiet"]);
    args.extend_from_slice(extra);
    let o = run(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    frames(out)
}

#[test]
fn a_take_drives_the_wind_deterministically() {
    let t = tempfile::tempdir().unwrap();
    let (pic, mask) = inputs(t.path());
    let take = t.path().join("sway.take");
    write_take(&take);
    let render = |extra: &[&str], out: &Path| render_20(&pic, &mask, extra, out);
    let (a, b, still) = (t.path().join("a/"), t.path().join("b/"), t.path().join("still/"));
    let fa = render(&["--take", s(&take)], &a);
    let fb = render(&["--take", s(&take), "--seed", "99"], &b);
    let fs = render(&["--strength", "0"], &still);
    assert_eq!(fa, fb, "a take must not depend on the procedural seed");
    assert_ne!(fa[19], fs[19], "the take's sway did not move the picture");

    // A file that is not a take is a clear error.
    std::fs::write(t.path().join("bad.take"), b"not a take at all").unwrap();
    let o = run(&[
        "render",
        "--image",
        s(&pic),
        "--layer",
        s(&mask),
        "--take",
        s(&t.path().join("bad.take")),
        "--frames",
        "2",
        "-o",
        s(&a),
        "--quiet",
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("cannot read take") && stderr(&o).contains("bad.take"), "{}", stderr(&o));
}

#[test]
fn the_simulation_wind_blows_the_picture() {
    let t = tempfile::tempdir().unwrap();
    let (pic, mask) = inputs(t.path());
    let render = |extra: &[&str], out: &Path| render_20(&pic, &mask, extra, out);
    // A steady 6 m/s towards +X is strength 6/10 = 0.6 towards the right; so is a hand held
    // with the root yawed -9.045 degrees (tip towards +X, 0.6 of the full bend, 15.075 degrees):
    // two mappings worked out by hand must blow the picture alike.
    let take = t.path().join("held.take");
    write_take_with(&take, 200, |_| -0.6 * 15.075);
    let sim = render(&["--wind-sim", "speed=6,dir=0,gust=0,seed=1"], &t.path().join("sim/"));
    let held = render(&["--take", s(&take)], &t.path().join("held/"));
    let still = render(&["--strength", "0"], &t.path().join("still/"));
    let mean_diff = |a: &[u8], b: &[u8]| {
        a.iter().zip(b).map(|(x, y)| (*x as f64 - *y as f64).abs()).sum::<f64>() / a.len() as f64
    };
    let moved = mean_diff(&sim[19], &still[19]);
    assert!(moved > 1.0, "the simulation's wind did not move the picture ({moved})");
    assert!(mean_diff(&sim[19], &held[19]) < 0.05 * moved, "sim and hand mappings disagree");
    // Another direction blows differently; the same spec renders the same bytes; released, calm.
    let west = render(&["--wind-sim", "speed=6,dir=180,gust=0,seed=1"], &t.path().join("west/"));
    assert!(mean_diff(&west[19], &sim[19]) > 0.5 * moved);
    assert_eq!(sim, render(&["--wind-sim", "speed=6,dir=0,gust=0,seed=1"], &t.path().join("again/")));
    let calm = render(&["--wind-sim", "speed=6,dir=0,gust=0,seed=1,until=0"], &t.path().join("calm/"));
    assert_eq!(calm, still);
    // Bad specs are named; a take and a simulation wind do not mix.
    let o = run(&[
        "render",
        "--image",
        s(&pic),
        "--layer",
        s(&mask),
        "--frames",
        "2",
        "-o",
        "x/",
        "--wind-sim",
        "speed=-3",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("--wind-sim") && stderr(&o).contains("speed"), "{}", stderr(&o));
    let o = run(&[
        "render",
        "--image",
        s(&pic),
        "--frames",
        "2",
        "-o",
        "x/",
        "--wind-sim",
        "speed=1",
        "--take",
        s(&take),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("cannot be used with"), "{}", stderr(&o));
}

#[test]
fn a_simulated_take_blows_the_picture_as_its_wind_does() {
    // Seed 003's plant (frondd's default rig, grass, and its default [sim]) simulated from rest
    // in a steady 10 m/s wind towards +X for 8 s at 100 FPS; its last 2 s (the plant at rest,
    // bent by that wind) are the take. A plant bent by the full wind blows the picture as that
    // wind does (`--wind-sim` at 10 m/s is full strength): the same frames within 5 % of the
    // motion. (A root bend of 40 degrees was full strength: the take blew at 0.38 of it.)
    let t = tempfile::tempdir().unwrap();
    let (pic, mask) = inputs(t.path());
    let rig = frond_motion::rig::Rig::from_toml_str(include_str!("../../../../rig-files/plants/grass.toml"))
        .unwrap();
    let spec = "speed=10,dir=0,gust=0,seed=0";
    let poses = frond_motion::sim::simulate(&rig, &rig.sim, spec.parse().unwrap(), 8.0, 100.0).unwrap();
    let take = t.path().join("gale.take");
    let at_rest = poses[600..].iter().enumerate().map(|(k, p)| {
        let t = k as f64 / 100.0;
        (frond_motion::PoseFrame { t, ..*p }, frond_motion::HandSample { t, ..Default::default() })
    });
    common::write_poses(&take, "grass", at_rest);
    let render = |extra: &[&str], out: &Path| render_20(&pic, &mask, extra, out);
    let simulated = render(&["--take", s(&take)], &t.path().join("take/"));
    let wind = render(&["--wind-sim", spec], &t.path().join("sim/"));
    let still = render(&["--strength", "0"], &t.path().join("still/"));
    let mean_diff = |a: &[u8], b: &[u8]| {
        a.iter().zip(b).map(|(x, y)| (*x as f64 - *y as f64).abs()).sum::<f64>() / a.len() as f64
    };
    let moved = mean_diff(&wind[19], &still[19]);
    assert!(moved > 1.0, "the simulation's wind did not move the picture ({moved})");
    let apart = mean_diff(&simulated[19], &wind[19]);
    assert!(apart < 0.05 * moved, "the simulated take and its wind disagree: {apart} of {moved}");
}

#[test]
fn the_log_level_is_checked_as_frondd_checks_it() {
    let t = tempfile::tempdir().unwrap();
    let (pic, mask) = inputs(t.path());
    let out = t.path().join("out/");
    let render =
        ["render", "--image", s(&pic), "--layer", s(&mask), "--frames", "2", "-o", s(&out), "--quiet"];
    // A level that does not parse is a usage error naming the option and the value, before or
    // after the subcommand, and nothing is rendered.
    for args in [
        [&render[..], &["--log-level", "frond=loud"]].concat(),
        [&["--log-level", "frond=loud"][..], &render[..]].concat(),
    ] {
        let o = run(&args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).starts_with("frond-warp: error: --log-level \"frond=loud\": "), "{}", stderr(&o));
        assert!(!out.exists(), "{args:?} rendered");
    }
    // A level and a filter are taken, in either place: the frames are rendered.
    for args in [
        [&render[..], &["--log-level", "debug"]].concat(),
        [&["--log-level", "warn,frond_sdk=trace"][..], &render[..]].concat(),
    ] {
        let o = run(&args);
        assert!(o.status.success(), "{args:?}: {}", stderr(&o));
        assert_eq!(frames(&out).len(), 2, "{args:?}");
        std::fs::remove_dir_all(&out).unwrap();
    }
}

#[test]
fn bad_input_gives_clear_errors() {
    let t = tempfile::tempdir().unwrap();
    let (pic, mask) = inputs(t.path());
    let out = t.path().join("o/");

    // Unreadable image.
    let junk = t.path().join("junk.png");
    std::fs::write(&junk, b"this is no png").unwrap();
    let o = run(&["render", "--image", s(&junk), "--layer", s(&mask), "--frames", "2", "-o", s(&out)]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("cannot read image") && stderr(&o).contains("junk.png"), "{}", stderr(&o));
    assert_eq!(stderr(&o).matches("could not be determined").count(), 1, "said once: {}", stderr(&o));
    let missing = t.path().join("missing.png");
    let o = run(&["render", "--image", s(&missing), "--layer", s(&mask), "--frames", "2", "-o", s(&out)]);
    assert!(stderr(&o).contains("missing.png"), "{}", stderr(&o));

    // Issue 14, point 13: no layer means nothing would move; refused, naming --layer.
    let o = run(&["render", "--image", s(&pic), "--frames", "2", "-o", s(&out)]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("nothing in the picture is marked as vegetation: give at least one --layer"));

    // Issue 14, point 9: a FIFO or a device is refused at once, never read or waited on.
    let fifo = t.path().join("pic.fifo");
    let c = std::ffi::CString::new(s(&fifo)).unwrap();
    // SAFETY: a valid NUL-terminated path; mkfifo only creates a node there.
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
    for (flag, path, what) in [("--image", s(&fifo), "a FIFO"), ("--layer", "/dev/zero", "a device")] {
        let (image, layer) = if flag == "--image" { (path, s(&mask)) } else { (s(&pic), path) };
        let o = run(&["render", "--image", image, "--layer", layer, "--frames", "2", "-o", s(&out)]);
        assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
        assert!(stderr(&o).contains(path) && stderr(&o).contains(what), "{}", stderr(&o));
    }

    // Mask of another size.
    let small = t.path().join("small.png");
    image::save_buffer(&small, &vec![255u8; 32 * 24], 32, 24, image::ColorType::L8).unwrap();
    let o = run(&["render", "--image", s(&pic), "--layer", s(&small), "--frames", "2", "-o", s(&out)]);
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(e.contains("small.png") && e.contains("32x24") && e.contains("64x48"), "{e}");

    // Negative grid size and out-of-range parameters: all reported at once, by name and range.
    let o = run(&[
        "render",
        "--image",
        s(&pic),
        "--layer",
        s(&mask),
        "--cell",
        "-4",
        "--fluid-grid",
        "-16",
        "--gamma",
        "1.5",
        "--c",
        "0",
        "--rigidity",
        "11",
        "--strength",
        "2",
        "--frames",
        "0",
        "--fps",
        "500",
        "-o",
        "out.mp4",
    ]);
    assert_eq!(o.status.code(), Some(2));
    let e = stderr(&o);
    for needle in [
        "cell = -4",
        "fluid-grid = -16",
        "gamma = 1.5 is out of range (allowed: 0.01 to 1)",
        "c = 0 is out of range (allowed: 1 to 10)",
        "rigidity = 11 is out of range (allowed: 0 to 10)",
        "--strength = 2 is out of range (allowed: 0 to 1)",
        "--frames = 0 is out of range (allowed: 1 to 100000)",
        "--fps = 500",
        "out.mp4",
    ] {
        assert!(e.contains(needle), "missing `{needle}` in:\n{e}");
    }
    assert!(!out.exists(), "nothing is written on bad input");
}

#[test]
fn make_samples_writes_the_committed_assets() {
    let t = tempfile::tempdir().unwrap();
    let o = run(&["make-samples", s(t.path())]);
    assert!(o.status.success(), "{}", stderr(&o));
    let committed = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../rig-files/images");
    for name in ["grass.png", "grass-mask.png", "grass-scale.png", "shrub-background.png", "shrub.png"] {
        let fresh = image::open(t.path().join(name)).unwrap();
        let size = std::fs::metadata(t.path().join(name)).unwrap().len();
        assert!(size < 200 * 1024, "{name} is {size} bytes");
        let shipped = image::open(committed.join(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(
            fresh.to_rgba8() == shipped.to_rgba8(),
            "{name}: committed asset differs from the generator's output"
        );
    }
    // The samples animate: the grass field renders and moves.
    let out = t.path().join("g/");
    let o = run(&[
        "render",
        "--image",
        s(&t.path().join("grass.png")),
        "--layer",
        s(&t.path().join("grass-mask.png")),
        "--scale-map",
        s(&t.path().join("grass-scale.png")),
        "--strength",
        "1",
        "--interval",
        "0",
        "--frames",
        "8",
        "-o",
        s(&out),
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let fs = frames(&out);
    assert_ne!(fs[0], fs[7]);
}

#[test]
fn serve_follows_the_simulation_wind_without_a_hand() {
    use std::io::{BufRead, BufReader, Read, Write};
    let t = tempfile::tempdir().unwrap();
    let (pic, mask) = inputs(t.path());
    let mut child = bin()
        .args(["serve", "--image", s(&pic), "--layer", s(&mask), "--listen", "127.0.0.1:0", "--no-daemon"])
        .args(["--wind-sim", "speed=4,dir=90,gust=0,seed=1"])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap()).read_line(&mut line).unwrap();
    let addr = line.trim().strip_prefix("listening on http://").unwrap().trim_end_matches('/').to_string();
    let status = || -> serde_json::Value {
        let mut c = std::net::TcpStream::connect(&addr).unwrap();
        write!(c, "GET /status HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n").unwrap();
        let mut r = String::new();
        c.read_to_string(&mut r).unwrap();
        serde_json::from_str(r.split("\r\n\r\n").nth(1).unwrap()).unwrap()
    };
    // The simulation thread applies the wind from its first frame on.
    let mut v = status();
    for _ in 0..50 {
        if v["frame"].as_u64().unwrap() > 2 {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
        v = status();
    }
    let _ = child.kill();
    let _ = child.wait();
    assert_eq!(v["wind_source"], "simulation", "{v}");
    // 4 m/s towards +Z: straight down at 4/10 of the full strength, continuous.
    let wind = &v["params"]["wind"];
    assert!((wind["direction_deg"].as_f64().unwrap() - 90.0).abs() < 1e-4, "{v}");
    assert!((wind["strength"].as_f64().unwrap() - 0.4).abs() < 1e-6, "{v}");
    assert_eq!(wind["interval_s"], 0.0);
}

#[test]
fn serve_mode_arguments_are_checked_before_anything_starts() {
    let t = tempfile::tempdir().unwrap();
    let (pic, mask) = inputs(t.path());
    // Cage-only flags on the wave page are refused by name.
    let o = run(&["serve", "--image", s(&pic), "--layer", s(&mask), "--cage", "x.json", "--no-prune"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(e.contains("--cage") && e.contains("--no-prune") && e.contains("add --mode cage"), "{e}");
    // The cage page: every problem at once (wind, two layers, morph time, anchor).
    let o = run(&[
        "serve",
        "--mode",
        "cage",
        "--image",
        s(&pic),
        "--layer",
        s(&mask),
        "--layer",
        s(&mask),
        "--morph-s",
        "0",
        "--anchor",
        "nope",
        "--wind-sim",
        "speed=3,dir=0",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let e = stderr(&o);
    for want in ["--wind-sim", "the cage mode has no wind", "exactly one layer", "--morph-s", "--anchor"] {
        assert!(e.contains(want), "{want}: {e}");
    }
    // A rig that does not exist is named.
    let o = run(&["serve", "--mode", "cage", "--image", s(&pic), "--layer", s(&mask), "--rig", "oak"]);
    assert_ne!(o.status.code(), Some(0));
    assert!(stderr(&o).contains("rig oak"), "{}", stderr(&o));
}

#[test]
fn outputs_that_are_not_files_to_replace_are_refused_before_rendering() {
    let t = tempfile::tempdir().unwrap();
    let (pic, mask) = inputs(t.path());
    let render = |out: &Path| {
        // A refusal comes before a frame is rendered: within seconds, where a FIFO without a
        // reader would block the old frond-warp's open for ever (the child is killed then).
        let mut child = bin()
            .args(["render", "--image", s(&pic), "--layer", s(&mask), "--frames", "3", "-o", s(out)])
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(60);
        while child.try_wait().unwrap().is_none() {
            if std::time::Instant::now() > deadline {
                let _ = child.kill();
                let _ = child.wait();
                panic!("frond-warp render -o {} hung", out.display());
            }
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
        let o = child.wait_with_output().unwrap();
        (o.status.code(), stderr(&o))
    };

    // A FIFO, for a GIF and for a WebP: refused, and still a FIFO.
    for name in ["out.gif", "out.webp"] {
        let fifo = t.path().join(name);
        let c = std::ffi::CString::new(s(&fifo)).unwrap();
        // SAFETY: a valid NUL-terminated path; mkfifo only creates a node there.
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
        let (code, e) = render(&fifo);
        assert_eq!(code, Some(1), "{e}");
        assert!(
            e.contains(&format!("cannot write {}: it is a FIFO, not a regular file", fifo.display())),
            "{e}"
        );
        use std::os::unix::fs::FileTypeExt;
        assert!(std::fs::symlink_metadata(&fifo).unwrap().file_type().is_fifo());
    }

    // A missing directory: refused, and not created (neither for a file nor for frames).
    for out in [t.path().join("no/such/out.gif"), t.path().join("no/such/frames/")] {
        let (code, e) = render(&out);
        assert_eq!(code, Some(1), "{e}");
        let missing = t.path().join("no/such");
        assert!(e.contains(&format!("the directory {} does not exist", missing.display())), "{e}");
        assert!(!t.path().join("no").exists(), "a mistyped path was made into directories");
    }

    // A file where a directory of frames is asked for.
    std::fs::write(t.path().join("plain"), b"keep").unwrap();
    let (code, e) = render(&t.path().join("plain/"));
    assert_eq!(code, Some(1), "{e}");
    assert!(e.contains("not a directory"), "{e}");
    assert_eq!(std::fs::read(t.path().join("plain")).unwrap(), b"keep");

    // A new directory of frames in one that exists is made (the leaf alone), and a GIF written
    // through its temporary file leaves only itself.
    let frames_dir = t.path().join("frames/");
    assert_eq!(render(&frames_dir).0, Some(0));
    assert_eq!(frames(&frames_dir).len(), 3);
    let gif_dir = t.path().join("gif");
    std::fs::create_dir(&gif_dir).unwrap();
    assert_eq!(render(&gif_dir.join("a.gif")).0, Some(0));
    let left: Vec<_> = std::fs::read_dir(&gif_dir).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(left, [std::ffi::OsString::from("a.gif")]);
}

#[test]
fn a_full_stdout_ends_serve_with_an_error_not_a_panic() {
    // The `listening on` line to a full disk (/dev/full): an error like any other, exit 1;
    // `println!` panicked (exit 101).
    let t = tempfile::tempdir().unwrap();
    let (pic, mask) = inputs(t.path());
    for mode in ["wave", "cage"] {
        let o = bin()
            .args(["serve", "--mode", mode, "--image", s(&pic), "--layer", s(&mask)])
            .args(["--listen", "127.0.0.1:0", "--no-daemon"])
            .stdout(std::fs::File::create("/dev/full").unwrap())
            .output()
            .unwrap();
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{mode}: {e}");
        assert!(e.contains("cannot write to standard output") && !e.contains("panicked"), "{mode}: {e}");
    }
}

/// One request to `addr` with `headers` (lines ending in CRLF) and `body`; status and body.
fn ask(addr: &str, method: &str, path: &str, headers: &str, body: &str) -> (u16, String) {
    use std::io::{Read, Write};
    let mut c = std::net::TcpStream::connect(addr).unwrap();
    write!(
        c,
        "{method} {path} HTTP/1.1\r\n{headers}Content-Length: {}\r\nConnection: close\r\n\r\n{body}",
        body.len()
    )
    .unwrap();
    let mut r = String::new();
    c.read_to_string(&mut r).unwrap();
    let (head, body) = r.split_once("\r\n\r\n").unwrap_or((&r, ""));
    (head.split(' ').nth(1).and_then(|s| s.parse().ok()).unwrap_or(0), body.to_string())
}

/// `frond-warp serve ARGS` on the wave page; the process and the first line it prints.
fn serve_wave(t: &Path, args: &[&str]) -> (std::process::Child, String) {
    use std::io::BufRead;
    let (pic, mask) = inputs(t);
    let mut child = bin()
        .args(["serve", "--image", s(&pic), "--layer", s(&mask), "--no-daemon"])
        .args(args)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let mut line = String::new();
    std::io::BufReader::new(child.stdout.take().unwrap()).read_line(&mut line).unwrap();
    (child, line.trim().to_string())
}

#[test]
fn serve_takes_the_consoles_access_rules() {
    let t = tempfile::tempdir().unwrap();
    let (mut child, line) = serve_wave(t.path(), &["--listen", "127.0.0.1:0"]);
    let addr = line.strip_prefix("listening on http://").unwrap().trim_end_matches('/').to_string();
    let port = addr.rsplit(':').next().unwrap();
    let own = format!("Host: {addr}\r\n");
    assert_eq!(ask(&addr, "GET", "/status", &own, "").0, 200);
    // DNS rebinding: a name that resolves here is not this server.
    let (status, body) =
        ask(&addr, "GET", "/status", &format!("Host: 127.0.0.1.evil.example:{port}\r\n"), "");
    assert_eq!(status, 403, "{body}");
    // Another site's page may not change the picture; the page's own may.
    let strength = r#"{"strength":0.9}"#;
    let evil = format!("{own}Origin: http://evil.example\r\n");
    assert_eq!(ask(&addr, "POST", "/params", &evil, strength).0, 403);
    assert_eq!(ask(&addr, "POST", "/params", &own, strength).0, 403, "a POST needs the page's Origin");
    let page = format!("{own}Origin: http://{addr}\r\n");
    assert_eq!(ask(&addr, "POST", "/params", &page, strength).0, 200);
    // Two Hosts: 400.
    assert_eq!(ask(&addr, "GET", "/status", &format!("{own}Host: evil.example\r\n"), "").0, 400);
    let _ = child.kill();
    let _ = child.wait();

    // Beyond loopback every request needs the token, which the printed URL carries.
    let (mut child, line) = serve_wave(t.path(), &["--listen", "0.0.0.0:0"]);
    let url = line.strip_prefix("listening on http://").unwrap();
    let (hostport, query) = url.split_once("/?token=").expect(&line);
    let port = hostport.rsplit(':').next().unwrap();
    let addr = format!("127.0.0.1:{port}");
    let host = format!("Host: {addr}\r\n");
    assert_eq!(ask(&addr, "GET", "/status", &host, "").0, 401);
    assert_eq!(ask(&addr, "GET", &format!("/status?token={query}"), &host, "").0, 200);
    let _ = child.kill();
    let _ = child.wait();
}

#[test]
fn a_take_is_found_by_name_in_the_takes_directory_as_every_tool_finds_it() {
    let t = tempfile::tempdir().unwrap();
    let (pic, mask) = inputs(t.path());
    let takes = t.path().join("takes");
    std::fs::create_dir(&takes).unwrap();
    write_take(&takes.join("sway.take"));
    let by_path = render_20(&pic, &mask, &["--take", s(&takes.join("sway.take"))], &t.path().join("p/"));
    // `--takes-dir DIR` and a name; `FROND_TAKES_DIR` and a name: the same take, the same frames.
    let by_name = render_20(&pic, &mask, &["--take", "sway", "--takes-dir", s(&takes)], &t.path().join("n/"));
    assert_eq!(by_path, by_name);
    let o = bin()
        .env("FROND_TAKES_DIR", &takes)
        .args(["render", "--image", s(&pic), "--layer", s(&mask), "--fluid-grid", "16", "--frames", "20"])
        .args(["-o", s(&t.path().join("e/")), "--quiet", "--take", "sway"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(frames(&t.path().join("e/")), by_path);
    // A name that could leave the directory is a usage error naming --take.
    let o = run(&[
        "render",
        "--image",
        s(&pic),
        "--layer",
        s(&mask),
        "--take",
        "..",
        "--frames",
        "2",
        "-o",
        s(&t.path().join("x.gif")),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("--take") && stderr(&o).contains("must not start with '.'"),
        "{}",
        stderr(&o)
    );
    // A name not there says where it looked.
    let o = run(&[
        "render",
        "--image",
        s(&pic),
        "--layer",
        s(&mask),
        "--take",
        "missing",
        "--takes-dir",
        s(&takes),
        "--frames",
        "2",
        "-o",
        s(&t.path().join("y.gif")),
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains(&takes.join("missing.take").display().to_string()), "{}", stderr(&o));
}
