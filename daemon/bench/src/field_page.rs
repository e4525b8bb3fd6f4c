//! Section 10's part `page`: the console page drawing a live field (issue 48). A daemon on the
//! in-process glove plays a field of 1,000, 10,000 and (not in quick mode) 100,000 plants,
//! `frond-console` passes it on, and headless Chromium with software WebGL (SwiftShader) draws
//! it at 1280x720. Each frame's time (evaluate every plant, upload, draw, wait for the pixels)
//! is measured against the same instanced scene with the plants standing still (draw only),
//! frames of the two alternating in the same run; the page's evaluation per plant against the
//! SDK's measured in this section; and, with the page running on its own, each field frame's
//! publish by the daemon to the first frame the page drew with it, p50 and p99, against the
//! same at 1,000 plants. Last, a meadow of mixed rigs (issue 48): 5,000 grass and 5,000
//! flowers, a field of each rig, animating against standing still (`page_frame_ms_10000_mixed`).

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use frond_formats::rig_files::EMBEDDED_RIGS;
use frond_motion::field::{FieldParams, make_field};
use frond_protocol::{ControlReply, ControlRequest, StageSpec};
use frond_webdriver::Driver;
use serde_json::{Value, json};

use crate::Options;
use crate::error::BenchError;
use crate::procs::{Daemon, Proc, find_bin};
use crate::report::{Bound, Measurement, Section, Status};

/// The part's title.
pub const TITLE: &str =
    "the console page drawing a live field at 1280x720 (software WebGL): animating vs standing still";
/// The plant counts and their grids; quick mode leaves out the last.
pub(crate) const SIZES: [(usize, usize); 3] = [(25, 40), (100, 100), (250, 400)];
/// The take the fields play, recorded from the glove first.
pub(crate) const TAKE: &str = "sway";

/// The part (see the module docs); `sdk_plant_ns` is the SDK's evaluation per plant measured
/// in this section, the page's baseline.
pub fn field_page(o: &Options, sdk_plant_ns: Option<f64>) -> Section {
    let started = Instant::now();
    let mut section = match measure(o, sdk_plant_ns) {
        Ok(s) => s,
        Err(Missing(why)) => Section::unavailable("page", TITLE, Status::NotAvailable, why),
        Err(Failed(e)) => Section::unavailable("page", TITLE, Status::Error, e.to_string()),
    };
    section.seconds = started.elapsed().as_secs_f64();
    section
}

/// Why the part has no figures.
pub(crate) enum PartError {
    /// Chromium or chromedriver is not installed.
    Missing(String),
    /// The measurement failed.
    Failed(BenchError),
}
pub(crate) use PartError::{Failed, Missing};

impl From<BenchError> for PartError {
    fn from(e: BenchError) -> Self {
        Failed(e)
    }
}

/// Chromium and chromedriver, or why the part cannot run.
pub(crate) fn browser() -> Result<(PathBuf, PathBuf), PartError> {
    let chromium = frond_webdriver::find(&["chromium", "chromium-browser", "/usr/bin/chromium"]);
    let driver = frond_webdriver::find(&["chromedriver", "/usr/bin/chromedriver"]);
    let (Some(chromium), Some(driver)) = (chromium, driver) else {
        return Err(Missing(
            "chromium and chromedriver are not installed (exporters/warp/tests/install-browser.sh)".into(),
        ));
    };
    Ok((chromium, driver))
}

/// Headless Chromium at 1280x720 showing `url`, its profile under `scratch`.
pub(crate) fn open_page(
    browser: &(PathBuf, PathBuf),
    scratch: &Path,
    url: &str,
) -> Result<Driver, PartError> {
    let profile = scratch.join("profile");
    std::panic::catch_unwind(|| {
        frond_webdriver::start_session(&browser.0, &browser.1, &profile, "1280,720", url)
    })
    .map_err(|_| Failed(BenchError::NoData("headless Chromium did not start".into())))
}

fn measure(o: &Options, sdk_plant_ns: Option<f64>) -> Result<Section, PartError> {
    let browser = browser()?;
    let daemon = Daemon::start(o, &["--source", "in-process", "--rig", "grass"])?;
    expect_ok(&daemon, &ControlRequest::RecordStart { name: TAKE.into() })?;
    std::thread::sleep(Duration::from_millis(1200));
    expect_ok(&daemon, &ControlRequest::RecordStop)?;
    let scratch = tempfile::Builder::new().prefix("frond-bench-page-").tempdir().map_err(BenchError::from)?;
    let (_console, url) = start_console(o, &daemon.socket_dir, scratch.path())?;
    let d = open_page(&browser, scratch.path(), &url)?;
    let frames = if o.quick { 3 } else { 8 };
    let latency_ms = if o.quick { 1000 } else { 5000 };
    let mut first_latency: Option<(f64, f64)> = None;
    let sizes = if o.quick { &SIZES[..2] } else { &SIZES[..] };
    let (mut ms, mut rows) = (Vec::new(), Vec::new());
    for &(r, c) in sizes {
        let n = r * c;
        start_field(&daemon, r, c, None)?;
        let evaluated = wait_for_field(&d, n, 1, if o.quick { 20 } else { 90 })?;
        let got = d.script(&format!("return ({BENCH_JS})({frames});"));
        let (anim, still) = (median_of(&got["animating"])?, median_of(&got["still"])?);
        let eval_ns = got["evaluate_ms"].as_f64().unwrap_or(f64::NAN) * 1e6 / n as f64;
        let m = Measurement::new(
            format!("page_frame_ms_{n}"),
            "ms",
            anim,
            format!("the same scene standing still, {n} plants"),
            still,
        );
        ms.push(if n == 10_000 {
            m.with_target("animating 10,000 plants costs at most 1.5x drawing them", Bound::MaxRatio, 1.5)
        } else {
            m
        });
        if let (10_000, Some(sdk)) = (n, sdk_plant_ns) {
            ms.push(Measurement::new("page_plant_ns", "ns", eval_ns, "the SDK's evaluation per plant", sdk));
        }
        // Long enough for the page to draw 3 frames on its own first (2 in quick mode), and 10
        // while measured (5).
        let (settle, watch) = if o.quick { (2.0, 5.0) } else { (3.0, 10.0) };
        let settle_ms = (settle * still).max(500.0) as u64;
        let lat = latencies(&d, settle_ms, (watch * still).max(latency_ms as f64) as u64)?;
        let (p50, p99) = (percentile(&lat, 0.5), percentile(&lat, 0.99));
        match first_latency {
            None => first_latency = Some((p50, p99)),
            Some((b50, b99)) => {
                let base = "the same at 1,000 plants";
                ms.push(Measurement::new(format!("page_latency_p50_ms_{n}"), "ms", p50, base, b50));
                ms.push(Measurement::new(format!("page_latency_p99_ms_{n}"), "ms", p99, base, b99));
            }
        }
        rows.push(json!({
            "latency_ms": { "p50": p50, "p99": p99, "samples": lat.len() },
            "plants": n, "evaluated": evaluated, "animating_ms": got["animating"], "still_ms": got["still"],
            "fps_animating": 1000.0 / anim, "fps_still": 1000.0 / still, "page_plant_ns": eval_ns,
            "near_plants": got["near"], "draw_calls": got["calls"], "canvas": got["canvas"],
        }));
    }
    // A meadow of mixed rigs (issue 48): 5,000 grass and 5,000 flowers, a field of each rig
    // (the flowers' under a stage of their own), against the same two standing still.
    start_field(&daemon, 50, 100, None)?;
    start_field(&daemon, 50, 100, Some("flower"))?;
    let evaluated = wait_for_field(&d, 5_000, 2, if o.quick { 20 } else { 90 })?;
    let got = d.script(&format!("return ({BENCH_JS})({frames});"));
    let (anim, still) = (median_of(&got["animating"])?, median_of(&got["still"])?);
    ms.push(Measurement::new(
        "page_frame_ms_10000_mixed",
        "ms",
        anim,
        "the same two fields standing still, 5,000 grass and 5,000 flowers",
        still,
    ));
    let mixed = json!({
        "plants": { "grass": 5_000, "flower": 5_000 }, "evaluated_first": evaluated,
        "animating_ms": got["animating"], "still_ms": got["still"], "fps_animating": 1000.0 / anim,
        "fps_still": 1000.0 / still, "draw_calls": got["calls"], "canvas": got["canvas"],
    });
    let details =
        json!({ "sizes": rows, "mixed": mixed, "frames_each": frames, "take": TAKE, "rig": "grass" });
    Ok(Section::ok("page", TITLE, ms, details))
}

/// The page's side: `frames` frames animating and `frames` standing still, alternating, at
/// 1280x720 (after one of each to warm up); the evaluation alone; the draw calls.
const BENCH_JS: &str = "(frames) => {
  const m = globalThis.frondMeadow, r = m.renderer, c = r.domElement;
  const [w, h, aspect] = [c.width, c.height, m.camera.aspect];
  r.setSize(1280, 720, false); m.camera.aspect = 1280 / 720; m.camera.updateProjectionMatrix();
  m.timeFrames(1, true); m.timeFrames(1, false);
  const animating = [], still = [];
  for (let k = 0; k < frames; k++) { animating.push(...m.timeFrames(1, true)); still.push(...m.timeFrames(1, false)); }
  const f = [...m.fields.values()][0];
  const t0 = performance.now();
  for (let k = 0; k < 3; k++) f.evaluate(f.tauNow(performance.now()));
  const evaluate_ms = (performance.now() - t0) / 3;
  const calls = m.drawCalls();
  const canvas = [c.width, c.height];
  r.setSize(w, h, false); m.camera.aspect = aspect; m.camera.updateProjectionMatrix();
  return { animating, still, evaluate_ms, near: f.nearCount, calls: calls.meadow, canvas };
}";

/// For `ms` milliseconds of the page running on its own (after `settle_ms` for it to take what
/// came while the bench held it in a script): each field frame's daemon publish to
/// the first frame the page drew with it (its pixels read back), milliseconds, sorted. The page
/// stamps wall-clock time; the daemon's stamp is `CLOCK_MONOTONIC`, moved to the wall clock
/// by the two clocks' offset read here (one machine).
fn latencies(d: &Driver, settle_ms: u64, ms: u64) -> Result<Vec<f64>, BenchError> {
    let got = d.async_script(&format!(
        "const done = arguments[arguments.length - 1], m = globalThis.frondMeadow; \
         setTimeout(() => {{ m.latency = []; \
           setTimeout(() => {{ const l = m.latency; m.latency = null; done(l); }}, {ms}); }}, {settle_ms});"
    ));
    let offset_ns = wall_minus_monotonic_ns();
    let mut out: Vec<f64> = got
        .as_array()
        .into_iter()
        .flatten()
        .filter_map(|p| Some(p[1].as_f64()? - (p[0].as_f64()? + offset_ns) / 1e6))
        .collect();
    if out.len() < 3 {
        return Err(BenchError::NoData(format!("the page drew {} field frames in {ms} ms", out.len())));
    }
    out.sort_by(f64::total_cmp);
    Ok(out)
}

/// The wall clock (the page's `performance.timeOrigin + performance.now()`) minus
/// `CLOCK_MONOTONIC` (the daemon's stamps), nanoseconds, now: one machine, so a monotonic time
/// plus this is the same moment on the page's clock.
pub(crate) fn wall_minus_monotonic_ns() -> f64 {
    let wall_ns =
        std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |t| t.as_nanos()) as f64;
    wall_ns - frondd::clock::monotonic_ns() as f64
}

/// The `q` quantile of sorted `v` (nearest rank).
pub(crate) fn percentile(v: &[f64], q: f64) -> f64 {
    v[((v.len() as f64 - 1.0) * q).round() as usize]
}

fn median_of(v: &Value) -> Result<f64, BenchError> {
    let mut xs: Vec<f64> = v.as_array().into_iter().flatten().filter_map(Value::as_f64).collect();
    if xs.is_empty() {
        return Err(BenchError::NoData(format!("the page timed no frames: {v}")));
    }
    Ok(crate::tick::median(&mut xs))
}

pub(crate) fn expect_ok(daemon: &Daemon, req: &ControlRequest) -> Result<(), BenchError> {
    match daemon.control(req)? {
        ControlReply::Ok | ControlReply::Recording(_) => Ok(()),
        other => Err(BenchError::UnexpectedReply(format!("{other:?}"))),
    }
}

/// Has the daemon play a `rows x cols` field of the take (its field.json without the plants,
/// which every reader makes from the parameters): of the daemon's rig as stage `field`,
/// replacing the one before, or of embedded rig `rig` as a stage of that name beside it (its own
/// layout seed, so that the two fields' plants interleave).
pub(crate) fn start_field(
    daemon: &Daemon,
    rows: usize,
    cols: usize,
    rig: Option<&str>,
) -> Result<(), BenchError> {
    let seed = if rig.is_some() { 4 } else { 3 };
    let p = FieldParams { rows, cols, cell_m: 0.2, speed_m_s: 1.5, direction_deg: 0.0, density: 1.0, seed };
    let field = make_field(&p, TAKE, 30, 30.0)?;
    let mut v = serde_json::to_value(&field).map_err(|e| BenchError::NoData(e.to_string()))?;
    if let Some(o) = v.as_object_mut() {
        o.remove("plants");
    }
    let (take, field_json) = (TAKE.to_string(), v.to_string());
    let (name, spec) = match rig {
        None => (None, StageSpec::Field { take, field_json, plants: 1, seed: 1 }),
        Some(rig) => {
            let rig_toml = EMBEDDED_RIGS
                .iter()
                .find(|(n, _)| *n == rig)
                .map(|(_, text)| text.to_string())
                .ok_or_else(|| BenchError::NoData(format!("no embedded rig {rig}")))?;
            (Some(rig.to_string()), StageSpec::FieldOfRig { take, field_json, plants: 1, seed: 1, rig_toml })
        }
    };
    expect_ok(daemon, &ControlRequest::StageStart { name, spec })
}

/// Waits until the page evaluates `fields` fields of `n` plants each (every plant once its
/// history has come, most of them before); how many it evaluated (of the field furthest behind).
pub(crate) fn wait_for_field(d: &Driver, n: usize, fields: usize, seconds: u64) -> Result<u64, BenchError> {
    let deadline = Instant::now() + Duration::from_secs(seconds);
    let mut best;
    loop {
        let v = d.script(&format!(
            "const m = globalThis.frondMeadow; if (!m) return 0; \
             const fs = [...m.fields.values()].filter(f => f.n === {n}); \
             return fs.length < {fields} ? 0 : Math.min(...fs.map(f => f.evaluated || 0));"
        ));
        best = v.as_u64().unwrap_or(0);
        if best == n as u64 {
            return Ok(best);
        }
        if Instant::now() > deadline {
            break;
        }
        std::thread::sleep(Duration::from_millis(200));
    }
    if best * 10 >= n as u64 * 9 {
        return Ok(best); // nearly all: the frame's cost is measured all the same
    }
    Err(BenchError::NoData(format!(
        "the page evaluated {best} of {n} plants ({fields} fields) in {seconds} s"
    )))
}

/// Starts `frond-console` on the daemon; it and its URL.
pub(crate) fn start_console(
    o: &Options,
    socket_dir: &Path,
    scratch: &Path,
) -> Result<(Proc, String), BenchError> {
    let mut child = Command::new(find_bin(o, "frond-console")?)
        .arg("--socket-dir")
        .arg(socket_dir)
        .arg("--takes-dir")
        .arg(PathBuf::from(scratch))
        .args(["--listen", "127.0.0.1:0", "--no-warp", "--log-level", "warn"])
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .map_err(BenchError::start("frond-console"))?;
    let out = child.stdout.take().ok_or(BenchError::NoPipe("frond-console has no stdout"))?;
    let proc = Proc { child };
    let mut line = String::new();
    BufReader::new(out)
        .read_line(&mut line)
        .map_err(|source| BenchError::Read { what: "frond-console's address", source })?;
    let url = line
        .strip_prefix("frond-console: ")
        .and_then(|r| r.split_whitespace().next())
        .ok_or_else(|| BenchError::NoData(format!("frond-console said {line:?}")))?;
    Ok((proc, url.to_string()))
}
