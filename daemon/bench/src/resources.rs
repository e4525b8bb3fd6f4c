//! Section 5: CPU use of `frondd` at 1 kHz with 4 subscribers as a fraction of one core, and its
//! resident memory.
//!
//! The target is a ratio: `frondd` fed a 1 kHz OSC sender with 4 subscribers against
//! `frond-relay` (the do-nothing relay of [`crate::relay`], no frond code) fed the same sender
//! with 4 readers, each process's CPU over a window of the same length, one after the other.
//! Both wake for every datagram and write it to 4 sockets; what `frondd` costs beyond that is
//! its loop, mapping and helper threads.
//!
//! Beside it, without a target: `frondd` on a 1 kHz hand recording (`--replay`: no device process
//! or generator thread in the figure), against the machine's cost of the job itself measured in
//! the same window (a bare 1 kHz `clock_nanosleep` loop that writes one pose-sized frame to 4
//! Unix sockets, each read by a blocking thread, as a minimal publisher would), and under it a
//! bare 1 kHz loop alone. On a virtual machine every wake-up is expensive (timer and IPI exits),
//! so that floor, not the daemon, decides what an absolute CPU figure can be there. A kernel
//! hidraw node adds a `ppoll` and a `read` per report; the virtual glove's FUSE node adds round
//! trips to its process, which the FUSE run (`frondd_cpu_fuse_glove_*`) shows.

use std::net::SocketAddr;
use std::path::Path;
use std::process::{Command, Stdio};
use std::thread;
use std::time::Duration;

use frondd::clock::monotonic_ns;
use serde_json::{Value, json};

use crate::Options;
use crate::daemon_run::{DaemonRun, measure_daemon, run_json};
use crate::error::BenchError;
use crate::latency::Subscribers;
use crate::osc_latency::{free_port, loopback, osc_stamp, send_for};
use crate::procs::{Daemon, Proc, process_cpu_ns, start_vhid, status_kb};
use crate::relay::Relay;
use crate::report::{Bound, Measurement, Section};

/// A 1 kHz hand recording of the virtual glove's sway, `seconds` long, as JSONL.
fn sway_jsonl(path: &Path, seconds: u32) -> Result<(), BenchError> {
    let mut text = String::new();
    for k in 0..seconds * 1000 {
        let (hand, _) = frond_vhid::sway_sample(f64::from(k) / 1000.0);
        frond_formats::jsonl::write_hand_line(&hand, &mut text);
        if !text.ends_with('\n') {
            text.push('\n');
        }
    }
    std::fs::write(path, text).map_err(BenchError::at(path))
}

/// The CPU (fraction of one core) of process `pid` over `window`, starting after `warm`, while
/// this process sends it a 1 kHz OSC hand sample stream at `to`.
fn cpu_while_sending(pid: u32, to: SocketAddr, warm: Duration, window: Duration) -> Result<f64, BenchError> {
    let sender = thread::spawn(move || send_for(to, warm + window + Duration::from_millis(100)));
    thread::sleep(warm);
    let (cpu0, wall0) = (process_cpu_ns(pid)?, monotonic_ns());
    thread::sleep(window);
    let (cpu1, wall1) = (process_cpu_ns(pid)?, monotonic_ns());
    sender.join().map_err(|_| BenchError::Panicked("the OSC sender thread"))??;
    Ok((cpu1 - cpu0) as f64 / (wall1 - wall0) as f64)
}

/// `frondd` (OSC source, 1 kHz, 4 subscribers) and then `frond-relay` (4 readers), each fed the
/// same 1 kHz OSC sender for the same window: their CPU, fractions of one core.
fn osc_cpu_against_relay(o: &Options, warm: Duration, window: Duration) -> Result<(f64, f64), BenchError> {
    let to = loopback(free_port()?);
    let daemon = Daemon::start(o, &["--source", &format!("osc://{to}"), "--rate", "1000"])?;
    let mut subs = Subscribers::new(1);
    subs.grow_to(&daemon.poses_socket(), 4)?;
    let frondd = cpu_while_sending(daemon.proc.pid(), to, warm, window)?;
    drop(subs);
    drop(daemon);
    let to = loopback(free_port()?);
    let relay = Relay::start(o, &format!("udp:{to}"), 4, osc_stamp)?;
    let relay_cpu = cpu_while_sending(relay.pid(), to, warm, window)?;
    Ok((frondd, relay_cpu))
}

/// Section 5.
pub fn daemon_resources(o: &Options) -> Result<Section, BenchError> {
    let (warm, window) = if o.quick {
        (Duration::from_millis(500), Duration::from_secs(2))
    } else {
        (Duration::from_secs(2), Duration::from_secs(20))
    };
    let dir = tempfile::Builder::new().prefix("frond-bench-res-").tempdir()?;
    let hand = dir.path().join("sway-1khz.jsonl");
    let seconds = (warm + window).as_secs() as u32 + 10;
    sway_jsonl(&hand, seconds)?;
    let hand_arg = hand.to_string_lossy().into_owned();
    let replay = measure_daemon(o, &["--replay", &hand_arg], warm, window)?;
    let (osc_frondd, osc_relay) = osc_cpu_against_relay(o, warm, window)?;

    // The same with the virtual glove in its own process, where a node can be served.
    let fuse = if Path::new("/dev/fuse").exists() {
        let node = dir.path().join("glove").join(frond_vhid::NODE_NAME);
        let node_arg = node.to_string_lossy().into_owned();
        let (_vhid, node, _out) =
            start_vhid(o, &["--sway", "--rate", "1000", "--backend", "fuse", "--node", &node_arg])?;
        let node = node.to_string_lossy().into_owned();
        Some(measure_daemon(o, &["--device", &node], warm, window)?)
    } else {
        None
    };

    // An idle process's resident memory: the floor any daemon starts from.
    let sleeper = Command::new("sleep")
        .arg("30")
        .stdout(Stdio::null())
        .spawn()
        .map_err(BenchError::start("`sleep` for the memory baseline"))?;
    let sleeper = Proc { child: sleeper };
    thread::sleep(Duration::from_millis(100));
    let idle_rss = status_kb(sleeper.pid(), "VmRSS")?;
    drop(sleeper);

    let mut section = resources_section(&replay, fuse.as_ref(), (osc_frondd, osc_relay), idle_rss, window);
    // Issue 46: the loop with a mocap stage's triggers and LTC running, against without.
    let (rows, details) = crate::stage_sync::measure(o, dir.path(), &hand, &replay, warm, window)?;
    section.measurements.extend(rows);
    if let Value::Object(map) = &mut section.details {
        map.insert("stage_sync".into(), details);
    }
    Ok(section)
}

/// Section 5's rows and details from its runs: `replay` (frondd replaying a 1 kHz recording),
/// `fuse` (frondd reading the FUSE glove, where it could run), `(frondd, relay)` CPU with the
/// same OSC sender, and an idle process's resident memory.
fn resources_section(
    replay: &DaemonRun,
    fuse: Option<&DaemonRun>,
    (osc_frondd, osc_relay): (f64, f64),
    idle_rss: u64,
    window: Duration,
) -> Section {
    const FLOOR: &str = "minimal publisher: bare 1 kHz clock_nanosleep loop writing each frame to 4 reading threads, same window";
    let mut measurements = vec![
        Measurement::new(
            "frondd_cpu_osc_1000hz_4_subscribers",
            "fraction_of_core",
            osc_frondd,
            "frond-relay's CPU, the same 1 kHz OSC sender, 4 reading threads, same window length",
            osc_relay,
        )
        .with_target(
            "frondd CPU <= 1.3x frond-relay's at 1 kHz with 4 subscribers (both fed the same 1 kHz OSC sender)",
            Bound::MaxRatio,
            1.3,
        ),
        Measurement::new(
            "frondd_cpu_1000hz_4_subscribers",
            "fraction_of_core",
            replay.cpu,
            FLOOR,
            replay.floor,
        ),
        Measurement::new(
            "fanout_floor_cpu_1000hz_4_subscribers",
            "fraction_of_core",
            replay.floor,
            "bare 1 kHz clock_nanosleep loop's CPU, same window",
            replay.bare,
        ),
        Measurement::new(
            "frondd_rss",
            "bytes",
            replay.rss as f64,
            "resident memory of an idle `sleep` process",
            idle_rss as f64,
        )
        .with_target("frondd under 16 MiB RSS", Bound::MaxMeasured, 16.0 * 1024.0 * 1024.0),
    ];
    let mut details = serde_json::Map::new();
    details.insert("replay".into(), run_json(replay));
    details.insert(
        "osc_against_relay".into(),
        json!({ "window_s": window.as_secs_f64(), "frondd_cpu_fraction": osc_frondd, "relay_cpu_fraction": osc_relay }),
    );
    if let Some(f) = fuse {
        measurements.push(Measurement::new(
            "frondd_cpu_fuse_glove_1000hz_4_subscribers",
            "fraction_of_core",
            f.cpu,
            FLOOR,
            f.floor,
        ));
        details.insert("fuse_glove".into(), run_json(f));
    } else {
        details.insert("fuse_glove".into(), json!("not measured: /dev/fuse is absent"));
    }
    details.insert(
        "source".into(),
        json!("target run (frondd_cpu_osc_*): frondd's OSC source and then frond-relay, each fed the same 1 kHz OSC sender of this process with 4 readers, CPU of the whole process over the same window length; frondd_cpu_1000hz_*: --replay of a 1 kHz recording (no device process or thread); fuse_glove: frond-vhid's FUSE node"),
    );
    Section::ok(
        "daemon_resources",
        "frondd CPU (fraction of one core) and resident memory at 1 kHz with 4 subscribers",
        measurements,
        serde_json::Value::Object(details),
    )
}
