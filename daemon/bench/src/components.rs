//! Section 6: the motion toolkit and the exporters, each against a baseline measured in the same
//! run. Components that do not exist (yet) or cannot run here are reported as
//! `{"status": "not available", "reason": ...}` instead of failing the bench.

use std::hint::black_box;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Duration;

use frond_motion::JOINTS;
use frond_motion::clip::{Clip, Joints};
use frond_motion::controls::FieldControls;
use frond_motion::field::{FieldParams, make_field};
use frond_motion::field_player::{FieldPlayer, bench_field_1000};
use frond_motion::looping::{LoopParams, PlaybackParams, find_transitions, loop_clip};
use frondd::clock::monotonic_ns;
use serde_json::{Value, json};

use crate::Options;
use crate::error::BenchError;
use crate::latency::Subscribers;
use crate::procs::{Daemon, find_bin};
use crate::report::{Bound, Measurement, Section, Status};
use crate::tick::median;

/// A part of section 6, or why it is not measured: the status and the reason the report gives.
type Part = Result<Section, (Status, String)>;

fn part(name: &str, title: &str, f: impl FnOnce() -> Part) -> Section {
    let started = std::time::Instant::now();
    let mut s = f().unwrap_or_else(|(status, reason)| Section::unavailable(name, title, status, reason));
    s.seconds = started.elapsed().as_secs_f64();
    s
}

/// Section 6.
pub fn components(o: &Options) -> Section {
    let parts = vec![
        part("field_playback", "field playback cost per frame, 1,000 and 10,000 plants", || {
            field_playback(o)
        }),
        part(
            "loop_synthesis",
            "loop synthesis (Eq. 5 transitions + 60 s of loop playback) for a 60 s take",
            || loop_synthesis(o),
        ),
        part("gltf_bake", "glTF bake throughput", || gltf_bake(o)),
        part("warp", "warp time per 1080p frame vs OpenCV cv2.remap, single thread", || warp(o)),
        part(
            "cage_warp",
            "shape-preserving cage morph frame (Sketch-based shape-preserving tree animations) at 1080p (cage tree, field, warp) vs the plain remap",
            || cage_warp(o),
        ),
        part(
            "sim_step",
            "simulated plant: one implicit Euler step (Physically-based Driven Tree Animations, section 4)",
            || crate::plant_motion::sim_step(o),
        ),
        part(
            "graph_build",
            "motion graph build (Physically-based Driven Tree Animations, section 5) at 2k, 10k and 100k samples",
            || crate::plant_motion::graph_build(o),
        ),
        part(
            "graph_walk",
            "motion graph walkers (Physically-based Driven Tree Animations, section 6)",
            || crate::plant_motion::graph_walk(o),
        ),
        part("osc", "OSC latency: daemon stamp -> UDP receiver, vs a pose-socket subscriber", || osc(o)),
        part("console", "frond-console's CPU at 1 kHz with 2 pages, vs frond tap on the same stream", || {
            console(o)
        }),
    ];
    let mut s = Section::ok("components", "motion toolkit and exporters", Vec::new(), Value::Null);
    s.parts = parts;
    s
}

/// Seconds of `f`, median of `runs`.
fn time_median(runs: usize, mut f: impl FnMut()) -> f64 {
    let mut v: Vec<f64> = (0..runs)
        .map(|_| {
            let t = monotonic_ns();
            f();
            (monotonic_ns() - t) as f64 / 1e9
        })
        .collect();
    median(&mut v)
}

fn sway_joints(n: usize, fps: f64) -> Vec<Joints> {
    (0..n)
        .map(|k| {
            let t = k as f64 / fps;
            let s = ((t * 2.1).sin() * 20.0 + (t * 5.3).sin() * 4.0 + (t * 0.37).sin() * 7.0) as f32;
            [
                [s, -s * 0.5, 0.0],
                [s * 0.5, -s * 0.25, 0.0],
                [s * 0.5, -s * 0.25, 3.0],
                [s * 0.3, -s * 0.1, 3.0],
            ]
        })
        .collect()
}

/// A field of `rows x cols` plants over a 10 s sway at 30 FPS, as `bench_field_1000` builds it.
fn field_player(rows: usize, cols: usize) -> Result<(FieldPlayer, Vec<Joints>), BenchError> {
    if rows * cols == 1000 {
        return Ok(bench_field_1000());
    }
    let clip = Clip::from_joints(sway_joints(300, 30.0), 30.0);
    let transitions = find_transitions(&clip, &LoopParams::default())?;
    let params =
        FieldParams { rows, cols, cell_m: 0.2, speed_m_s: 1.5, direction_deg: 30.0, density: 1.0, seed: 1 };
    let field = make_field(&params, "bench", clip.len(), clip.fps)?;
    let out = vec![[[0.0; 3]; JOINTS]; field.plants.len()];
    Ok((FieldPlayer::new(field, clip, &transitions, 1, FieldControls::default()), out))
}

fn field_playback(o: &Options) -> Part {
    let frames = if o.quick { 60 } else { 600 };
    let mut measurements = Vec::new();
    let mut details = serde_json::Map::new();
    for (rows, cols) in [(20, 50), (100, 100)] {
        let (mut player, mut out) = field_player(rows, cols).map_err(|e| (Status::Error, e.to_string()))?;
        let plants = out.len();
        let mut t = 0.0;
        for _ in 0..30 {
            t += 1.0 / 60.0;
            player.frame(t, &mut out);
        }
        let mut per_frame = Vec::new();
        let mut per_copy = Vec::new();
        let copy_src = out.clone();
        for _ in 0..frames {
            t += 1.0 / 60.0;
            let a = monotonic_ns();
            player.frame(t, &mut out);
            let b = monotonic_ns();
            // Baseline: writing the same frame of poses without computing it.
            out.copy_from_slice(black_box(&copy_src));
            black_box(&out);
            let c = monotonic_ns();
            per_frame.push((b - a) as f64 / 1e3);
            per_copy.push((c - b) as f64 / 1e3);
        }
        measurements.push(Measurement::new(
            format!("field_frame_{plants}_plants_us"),
            "us",
            median(&mut per_frame),
            "copying one frame of the same plants' poses (memcpy)",
            median(&mut per_copy),
        ));
        details.insert(format!("{plants}_plants"), json!({"rows": rows, "cols": cols, "frames": frames}));
    }
    Ok(Section::ok(
        "field_playback",
        "field playback cost per frame, 1,000 and 10,000 plants",
        measurements,
        Value::Object(details),
    ))
}

fn loop_synthesis(o: &Options) -> Part {
    let runs = if o.quick { 3 } else { 11 };
    let mut measurements = Vec::new();
    let mut details = serde_json::Map::new();
    for fps in [30.0, 1000.0] {
        let joints = sway_joints((60.0 * fps) as usize, fps);
        let clip = Clip::from_joints(joints.iter().copied(), fps);
        let params = LoopParams::default();
        let mut transitions = None;
        let synth = time_median(runs, || {
            let t = find_transitions(&clip, &params).expect("a 60 s take is long enough");
            let (out, _) = loop_clip(&clip, &t, 1, PlaybackParams::default(), 0, clip.len());
            black_box(out);
            transitions = Some(t);
        });
        // Baseline: building the same 60 s clip from its joint angles (one pass over the data).
        let build = time_median(runs, || {
            black_box(Clip::from_joints(joints.iter().copied(), fps));
        });
        let f = fps as u32;
        measurements.push(Measurement::new(
            format!("loop_synthesis_60s_take_{f}fps_ms"),
            "ms",
            synth * 1e3,
            "building the same 60 s clip from its joints (Clip::from_joints)",
            build * 1e3,
        ));
        details.insert(
            format!("{f}fps"),
            json!({"frames": clip.len(), "transitions": transitions.map(|t| t.transitions.len())}),
        );
    }
    Ok(Section::ok(
        "loop_synthesis",
        "loop synthesis (Eq. 5 transitions + 60 s of loop playback) for a 60 s take",
        measurements,
        Value::Object(details),
    ))
}

/// Seconds to write `keys` rotation keys (4 x f32) as little-endian bytes into a fresh buffer:
/// the least any baker must do to emit them.
fn raw_key_write_s(keys: usize) -> f64 {
    time_median(3, || {
        let mut buf = Vec::with_capacity(keys * 16);
        for k in 0..keys {
            let q = [k as f32, 0.5, -0.5, 1.0];
            for v in q {
                buf.extend_from_slice(&v.to_le_bytes());
            }
        }
        black_box(&buf);
    })
}

fn gltf_bake(o: &Options) -> Part {
    let minutes = if o.quick { 0.5 } else { 5.0 };
    let (plants, seconds) = if o.quick { (100, 5.0) } else { (1000, 20.0) };
    let runs = [
        ("take", frond_gltf::bench::take_bake(minutes, 1000.0)),
        ("field", frond_gltf::bench::field_bake(plants, seconds)),
    ];
    let mut measurements = Vec::new();
    let mut details = serde_json::Map::new();
    for (kind, r) in runs {
        let r = r.map_err(|e| (Status::Error, format!("glTF {kind} bake: {e}")))?;
        let keys = r.keys * r.channels;
        let raw_s = raw_key_write_s(keys);
        measurements.push(Measurement::new(
            format!("gltf_{kind}_bake_keys_per_s"),
            "keys/s",
            r.keys_per_s(),
            "writing the same number of rotation keys as raw f32 bytes",
            keys as f64 / raw_s.max(1e-9),
        ));
        details.insert(
            kind.into(),
            json!({
                "name": r.name, "frames_in": r.frames_in, "plants": r.plants, "keys": r.keys,
                "channels": r.channels, "glb_bytes": r.bytes, "seconds": r.elapsed.as_secs_f64(),
            }),
        );
    }
    Ok(Section::ok(
        "gltf_bake",
        "glTF bake throughput (take and field, GLB in memory)",
        measurements,
        Value::Object(details),
    ))
}

/// Runs `cmd`, returns its stdout when it succeeds.
fn output(cmd: &mut Command, what: &str) -> Result<String, (Status, String)> {
    let out = cmd
        .stdin(Stdio::null())
        .stderr(Stdio::piped())
        .output()
        .map_err(|e| (Status::NotAvailable, format!("cannot run {what}: {e}")))?;
    if !out.status.success() {
        let err = String::from_utf8_lossy(&out.stderr);
        let last = err.lines().last().unwrap_or("").trim().to_string();
        return Err((Status::NotAvailable, format!("{what} failed ({}): {last}", out.status)));
    }
    Ok(String::from_utf8_lossy(&out.stdout).into_owned())
}

fn json_line(text: &str, what: &str) -> Result<Value, (Status, String)> {
    text.lines()
        .rev()
        .find_map(|l| serde_json::from_str::<Value>(l.trim()).ok().filter(Value::is_object))
        .ok_or((Status::Error, format!("{what} printed no JSON object")))
}

/// Where `exporters/warp/bench/remap.py` is: `$FROND_REMAP_PY`, else this source tree's.
fn remap_py() -> PathBuf {
    std::env::var_os("FROND_REMAP_PY")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../exporters/warp/bench/remap.py"))
}

/// The Python that runs remap.py: `$FROND_BENCH_PYTHON`, else the tests' venv
/// (`tests/python/.venv`) when this source tree has one, else `python3`.
fn python() -> String {
    if let Ok(p) = std::env::var("FROND_BENCH_PYTHON") {
        return p;
    }
    let venv = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/python/.venv/bin/python");
    if venv.is_file() { venv.to_string_lossy().into_owned() } else { "python3".into() }
}

fn warp(o: &Options) -> Part {
    let bin = find_bin(o, "frond-warp").map_err(|e| (Status::NotAvailable, e.to_string()))?;
    let script = remap_py();
    if !script.is_file() {
        return Err((Status::NotAvailable, format!("{} not found (set FROND_REMAP_PY)", script.display())));
    }
    let python = python();
    let (iterations, rounds) = if o.quick { (3, 1) } else { (20, 3) };
    let dir = tempfile::Builder::new()
        .prefix("frond-bench-warp-")
        .tempdir()
        .map_err(|e| (Status::Error, e.to_string()))?;
    let (mut ours, mut theirs) = (Vec::new(), Vec::new());
    let (mut ours_json, mut cv_json) = (Value::Null, Value::Null);
    for round in 0..rounds {
        let mut cmd = Command::new(&bin);
        cmd.args(["bench", "--json", "--pipeline-frames", "0", "--cage-frames", "0", "--iterations"])
            .arg(iterations.to_string());
        if round == 0 {
            cmd.arg("--write-field").arg(dir.path());
        }
        let v = json_line(&output(&mut cmd, "frond-warp bench")?, "frond-warp bench")?;
        ours.push(
            v["warp"]["median_ms"]
                .as_f64()
                .ok_or((Status::Error, "frond-warp bench: no warp.median_ms".to_string()))?,
        );
        ours_json = v;
        let mut cmd = Command::new(&python);
        cmd.arg(&script).arg(dir.path()).arg("--iterations").arg(iterations.to_string());
        let v = match output(&mut cmd, &format!("{python} remap.py (OpenCV)")) {
            Ok(text) => json_line(&text, "remap.py")?,
            Err((status, reason)) => {
                // Without OpenCV there is no baseline: keep frond-warp's own figures beside the
                // reason instead of a ratio.
                let mut s = Section::unavailable(
                    "warp",
                    "warp time per 1080p frame vs OpenCV cv2.remap, single thread",
                    status,
                    format!(
                        "{reason} (set FROND_BENCH_PYTHON to a Python with numpy and opencv-python-headless)"
                    ),
                );
                s.details = json!({"frond_warp": ours_json});
                return Ok(s);
            }
        };
        theirs.push(v["median_ms"].as_f64().ok_or((Status::Error, "remap.py: no median_ms".to_string()))?);
        cv_json = v;
    }
    let m = Measurement::new(
        "warp_1080p_frame_ms",
        "ms",
        median(&mut ours),
        "OpenCV cv2.remap INTER_LINEAR, 1 thread, same frame and field",
        median(&mut theirs),
    )
    .with_target(
        "warp at least as fast as cv2.remap single-threaded on the same grid",
        Bound::MaxRatio,
        1.0,
    );
    Ok(Section::ok(
        "warp",
        "warp time per 1080p frame vs OpenCV cv2.remap, single thread",
        vec![m],
        json!({"frond_warp": ours_json, "cv2_remap": cv_json, "rounds": rounds}),
    ))
}

/// Seed 004: one morph frame of a 13-cage tree at 1080p against the plain grid-warp remap (Simulation-guided Grid-based Warping) timed
/// in the same run, interleaved (`frond-warp bench --cage-frames N`).
fn cage_warp(o: &Options) -> Part {
    let bin = find_bin(o, "frond-warp").map_err(|e| (Status::NotAvailable, e.to_string()))?;
    let frames = if o.quick { 3 } else { 20 };
    let mut cmd = Command::new(&bin);
    cmd.args(["bench", "--json", "--pipeline-frames", "0", "--iterations", "1", "--cage-frames"])
        .arg(frames.to_string());
    let v = json_line(&output(&mut cmd, "frond-warp bench")?, "frond-warp bench")?;
    let c = &v["cage"];
    let get = |k: &str| c[k].as_f64().ok_or((Status::Error, format!("frond-warp bench: no cage.{k}")));
    let m = Measurement::new(
        "cage_morph_1080p_frame_ms",
        "ms",
        get("frame_ms")?,
        "the plain grid-warp remap (Simulation-guided Grid-based Warping) of a 1080p frame, same run, interleaved",
        get("remap_ms")?,
    )
    .with_target("a 1080p cage morph frame within 2.5x the plain remap", Bound::MaxRatio, 2.5);
    // The page's preview: a 512 px picture morphing at display rate (60 Hz).
    let mut cmd = Command::new(&bin);
    cmd.args([
        "bench",
        "--json",
        "--pipeline-frames",
        "0",
        "--iterations",
        "1",
        "--width",
        "512",
        "--height",
        "512",
    ])
    .arg("--cage-frames")
    .arg(frames.to_string());
    let v512 = json_line(&output(&mut cmd, "frond-warp bench")?, "frond-warp bench")?;
    let c512 = &v512["cage"];
    let get512 = |k: &str| c512[k].as_f64().ok_or((Status::Error, format!("frond-warp bench: no cage.{k}")));
    let preview = Measurement::new(
        "cage_preview_512_frame_ms",
        "ms",
        get512("frame_ms")?,
        "the plain grid-warp remap (Simulation-guided Grid-based Warping) of a 512x512 frame, same run, interleaved",
        get512("remap_ms")?,
    )
    .with_target(
        "a 512 px cage preview frame within one 60 Hz display frame",
        Bound::MaxMeasured,
        1000.0 / 60.0,
    );
    Ok(Section::ok(
        "cage_warp",
        "shape-preserving cage morph frame (Sketch-based shape-preserving tree animations) at 1080p and at the page's 512 px (cage tree, field, warp) vs the plain remap",
        vec![m, preview],
        json!({"frond_warp": c, "frond_warp_512": c512}),
    ))
}

fn osc(o: &Options) -> Part {
    let bin = find_bin(o, "frond-osc").map_err(|e| (Status::NotAvailable, e.to_string()))?;
    let seconds = if o.quick { 1.0 } else { 10.0 };
    let daemon = Daemon::start(o, &["--source", "in-process", "--rate", "1000"])
        .map_err(|e| (Status::Error, e.to_string()))?;
    // Baseline in the same window: a pose-socket subscriber here, daemon stamp -> receipt.
    let mut subs = Subscribers::new(1);
    subs.grow_to(&daemon.poses_socket(), 1).map_err(|e| (Status::Error, e.to_string()))?;
    subs.record(Some(0));
    let mut cmd = Command::new(&bin);
    cmd.arg("--socket-dir")
        .arg(&daemon.socket_dir)
        .args(["--bench", "--bench-seconds"])
        .arg(seconds.to_string());
    let text = output(&mut cmd, "frond-osc --bench")?;
    subs.record(None);
    std::thread::sleep(Duration::from_millis(10));
    let reports: Vec<Value> = text.lines().filter_map(|l| serde_json::from_str(l.trim()).ok()).collect();
    let one = reports
        .iter()
        .find(|r| r["targets"] == 1)
        .ok_or((Status::Error, format!("frond-osc --bench printed no 1-target report: {text}")))?;
    let base = subs.hists(0).publish_to_receipt.summary();
    let mut measurements = Vec::new();
    for q in ["p50", "p99"] {
        let v = one[format!("{q}_us")].as_f64().ok_or((Status::Error, format!("frond-osc: no {q}_us")))?;
        let b = if q == "p50" { base.p50_us } else { base.p99_us };
        measurements.push(Measurement::new(
            format!("osc_latency_{q}_1_target"),
            "us",
            v,
            format!("pose-socket subscriber, daemon stamp -> receipt, {q}, same window"),
            b,
        ));
    }
    Ok(Section::ok(
        "osc",
        "OSC latency: daemon stamp -> UDP receiver, vs a pose-socket subscriber",
        measurements,
        json!({"frond_osc": reports, "subscriber": base, "seconds_per_run": seconds}),
    ))
}

/// A page's pose WebSocket to the console at `addr`, read and discarded on a thread until
/// `stop`; returns the bytes received.
fn console_page(
    addr: std::net::SocketAddr,
    stop: std::sync::Arc<std::sync::atomic::AtomicBool>,
) -> Result<std::thread::JoinHandle<u64>, BenchError> {
    use std::io::{Read, Write};
    let mut s = std::net::TcpStream::connect(addr).map_err(BenchError::at("connect to frond-console"))?;
    write!(
        s,
        "GET /ws HTTP/1.1\r\nHost: {addr}\r\nOrigin: http://{addr}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n\
         Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n"
    )?;
    s.set_read_timeout(Some(Duration::from_millis(200)))?;
    Ok(std::thread::spawn(move || {
        let mut buf = [0u8; 16384];
        let mut total = 0u64;
        while !stop.load(std::sync::atomic::Ordering::Relaxed) {
            match s.read(&mut buf) {
                Ok(0) => break,
                Ok(n) => total += n as u64,
                Err(e)
                    if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) => {}
                Err(_) => break,
            }
        }
        total
    }))
}

/// Issue 19: the console next to a 1 kHz daemon with two pages open costs a small fraction of a
/// core; against `frond tap --jsonl` (a plain subscriber printing every frame) on the same
/// stream, measured over the same window.
fn console(o: &Options) -> Part {
    use std::io::BufRead;
    use std::sync::Arc;
    use std::sync::atomic::{AtomicBool, Ordering};
    let bin = find_bin(o, "frond-console").map_err(|e| (Status::NotAvailable, e.to_string()))?;
    let frond = find_bin(o, "frond").map_err(|e| (Status::NotAvailable, e.to_string()))?;
    let (warm, window) = if o.quick {
        (Duration::from_millis(500), Duration::from_secs(2))
    } else {
        (Duration::from_secs(2), Duration::from_secs(10))
    };
    let daemon = Daemon::start(o, &["--source", "in-process", "--rate", "1000"])
        .map_err(|e| (Status::Error, e.to_string()))?;
    let err = |e: String| (Status::Error, e);
    let failed = |e: BenchError| err(e.to_string());
    let mut child = Command::new(&bin)
        .arg("--socket-dir")
        .arg(&daemon.socket_dir)
        .args(["--listen", "127.0.0.1:0"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .map_err(|e| err(format!("cannot start frond-console: {e}")))?;
    let mut line = String::new();
    let out = child.stdout.take().ok_or_else(|| err("frond-console: no stdout".into()))?;
    std::io::BufReader::new(out).read_line(&mut line).map_err(|e| err(e.to_string()))?;
    let console = crate::procs::Proc { child };
    let addr: std::net::SocketAddr = line
        .strip_prefix("frond-console: http://")
        .and_then(|r| r.split('/').next())
        .and_then(|a| a.parse().ok())
        .ok_or_else(|| err(format!("frond-console printed {line:?}")))?;
    let tap = Command::new(&frond)
        .arg("--socket-dir")
        .arg(&daemon.socket_dir)
        .args(["tap", "--jsonl"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .map_err(|e| err(format!("cannot start frond tap: {e}")))?;
    let tap = crate::procs::Proc { child: tap };
    let stop = Arc::new(AtomicBool::new(false));
    let pages = [
        console_page(addr, stop.clone()).map_err(failed)?,
        console_page(addr, stop.clone()).map_err(failed)?,
    ];
    std::thread::sleep(warm);
    let cpu = |pid| crate::procs::process_cpu_ns(pid).map_err(failed);
    let (c0, t0, w0) = (cpu(console.pid())?, cpu(tap.pid())?, monotonic_ns());
    std::thread::sleep(window);
    let (c1, t1, w1) = (cpu(console.pid())?, cpu(tap.pid())?, monotonic_ns());
    stop.store(true, Ordering::Relaxed);
    let bytes: Vec<u64> = pages.into_iter().map(|p| p.join().unwrap_or(0)).collect();
    let wall = (w1 - w0) as f64;
    let (console_cpu, tap_cpu) = ((c1 - c0) as f64 / wall, (t1 - t0) as f64 / wall);
    if bytes.contains(&0) {
        return Err(err(format!("a page received nothing from frond-console ({bytes:?} bytes)")));
    }
    let m = Measurement::new(
        "console_cpu_1000hz_2_pages",
        "fraction_of_core",
        console_cpu,
        "frond tap --jsonl on the same 1 kHz stream (prints every frame), same window",
        tap_cpu,
    )
    .with_target("frond-console under 5 % of a core at 1 kHz with 2 pages", Bound::MaxMeasured, 0.05);
    Ok(Section::ok(
        "console",
        "frond-console's CPU at 1 kHz with 2 pages, vs frond tap on the same stream",
        vec![m],
        json!({ "window_s": wall / 1e9, "page_bytes_per_s": bytes.iter().map(|&b| b as f64 / (wall / 1e9)).collect::<Vec<_>>() }),
    ))
}
