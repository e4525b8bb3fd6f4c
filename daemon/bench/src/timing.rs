//! Sections 1 and 4: loop lateness against the machine's limit, and the highest sustainable rate.

use std::time::{Duration, Instant};

use serde_json::json;

use crate::Options;
use crate::error::BenchError;
use crate::loops::{Accum, FullLoop, LoopRun, Pacing};
use crate::report::{Bound, Measurement, Section};

/// Subscribers of the full loop in sections 1 and 4.
pub const SUBSCRIBERS: usize = 8;

/// Section 1: lateness of the full loop, the bare `clock_nanosleep` loop and the naive sleep loop
/// at 1 kHz and 8 kHz, run in alternating slices so all three see the same machine load.
pub fn loop_timing(o: &Options, priority: u8) -> Result<Section, BenchError> {
    let (total_s, slice_s) = if o.quick { (0.6, 0.2) } else { (20.0, 1.0) };
    let slice = Duration::from_secs_f64(slice_s);
    let slices = (total_s / slice_s).round() as usize;
    let mut full = FullLoop::new(SUBSCRIBERS)?;
    let mut measurements = Vec::new();
    let mut details = serde_json::Map::new();
    for rate in [1000.0, 8000.0] {
        let (mut bare, mut naive, mut fl) = (Accum::new(rate), Accum::new(rate), Accum::new(rate));
        for _ in 0..slices {
            bare.pace(Pacing::Bare, slice, priority);
            naive.pace(Pacing::NaiveSleep, slice, priority);
            fl.full(&mut full, slice, priority)?;
        }
        let (b, n, f) = (bare.result(), naive.result(), fl.result());
        let r = rate as u32;
        let bare_name = |q: &str| format!("bare clock_nanosleep loop {q}");
        let lat = |name: &str, q: &str, m: f64, base: f64| {
            Measurement::new(format!("{name}_{r}hz"), "us", m, bare_name(q), base)
        };
        measurements.push(lat("full_lateness_p50", "p50", f.lateness.p50_us, b.lateness.p50_us));
        measurements.push(lat("full_lateness_p99", "p99", f.lateness.p99_us, b.lateness.p99_us).with_target(
            format!("full loop p99 lateness <= 1.5x the bare loop's at {r} Hz"),
            Bound::MaxRatio,
            1.5,
        ));
        measurements.push(lat("full_lateness_p999", "p99.9", f.lateness.p999_us, b.lateness.p999_us));
        measurements.push(lat("full_lateness_max", "max", f.lateness.max_us, b.lateness.max_us));
        measurements.push(lat("naive_sleep_lateness_p99", "p99", n.lateness.p99_us, b.lateness.p99_us));
        measurements.push(Measurement::new(
            format!("full_achieved_rate_{r}hz"),
            "hz",
            f.achieved_hz,
            "bare loop achieved rate",
            b.achieved_hz,
        ));
        measurements.push(Measurement::new(
            format!("naive_sleep_achieved_rate_{r}hz"),
            "hz",
            n.achieved_hz,
            "bare loop achieved rate",
            b.achieved_hz,
        ));
        details.insert(format!("{r}hz"), json!({ "bare": b, "naive_sleep": n, "full": f }));
    }
    details.insert("subscribers".into(), json!(SUBSCRIBERS));
    details.insert("subscriber_bytes_read".into(), json!(full.received_bytes()));
    details.insert("slices_per_loop".into(), json!(slices));
    details.insert("slice_s".into(), json!(slice_s));
    Ok(Section::ok(
        "loop_timing",
        "wake-up lateness: full loop (read, calibrate, filter, map, publish to 8 subscribers) vs bare clock_nanosleep loop vs naive thread::sleep loop",
        measurements,
        serde_json::Value::Object(details),
    ))
}

/// Highest rate at which `probe(rate)` is sustainable: doubling from 1 kHz, then bisecting.
fn search(
    mut probe: impl FnMut(f64) -> Result<LoopRun, BenchError>,
    cap_hz: f64,
    steps: usize,
) -> Result<(f64, Vec<LoopRun>), BenchError> {
    let mut tried = Vec::new();
    let mut ok = 0.0;
    let mut bad = None;
    let mut rate = 1000.0;
    while rate <= cap_hz {
        let run = probe(rate)?;
        tried.push(run);
        if run.sustainable() {
            ok = rate;
            rate *= 2.0;
        } else {
            bad = Some(rate);
            break;
        }
    }
    if let Some(mut hi) = bad {
        let mut lo = ok;
        for _ in 0..steps {
            let mid = ((lo + hi) / 2.0 / 100.0).round() * 100.0;
            if mid <= lo || mid >= hi {
                break;
            }
            let run = probe(mid)?;
            tried.push(run);
            if run.sustainable() {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        ok = lo;
    }
    Ok((ok, tried))
}

/// Section 4: the highest sustainable tick rate of the full loop with 8 subscribers (p99 lateness
/// under one period and at least 98% of the asked rate achieved), against the same search on the
/// bare loop.
pub fn max_rate(o: &Options, priority: u8) -> Result<Section, BenchError> {
    let probe_s = if o.quick { 0.15 } else { 1.0 };
    let probe = Duration::from_secs_f64(probe_s);
    let (cap, steps) = (256_000.0, if o.quick { 3 } else { 5 });
    let started = Instant::now();
    let mut full = FullLoop::new(SUBSCRIBERS)?;
    let (full_max, full_runs) = search(
        |rate| {
            let mut a = Accum::new(rate);
            a.full(&mut full, probe, priority)?;
            Ok(a.result())
        },
        cap,
        steps,
    )?;
    drop(full);
    let (bare_max, bare_runs) = search(
        |rate| {
            let mut a = Accum::new(rate);
            a.pace(Pacing::Bare, probe, priority);
            Ok(a.result())
        },
        cap,
        steps,
    )?;
    let m = Measurement::new(
        "max_sustainable_rate_8_subscribers",
        "hz",
        full_max,
        "bare clock_nanosleep loop, same search",
        bare_max,
    );
    Ok(Section::ok(
        "max_rate",
        "highest sustainable tick rate with 8 subscribers (p99 lateness < one period, >= 98% of the rate)",
        vec![m],
        json!({
            "probe_s": probe_s,
            "search_cap_hz": cap,
            "sustains_daemon_max_8000hz": full_max >= 8000.0,
            "full_probes": full_runs,
            "bare_probes": bare_runs,
            "search_s": started.elapsed().as_secs_f64(),
        }),
    ))
}
