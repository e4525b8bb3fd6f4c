//! `frond-osc`: streams the daemon's poses as OSC (frond namespace or VMC) over UDP.

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::Duration;

use anyhow::Context;
use clap::{CommandFactory, Parser, ValueEnum};
use frond_osc::encode::{Timetags, VmcRig};
use frond_osc::resample::RATE_RANGE_HZ;
use frond_osc::{Bridge, BridgeConfig, DEFAULT_FROND_PORT, DEFAULT_VMC_PORT, Protocol, bench, rig, sender};

#[derive(Debug, Clone, Copy, ValueEnum)]
enum ProtocolArg {
    /// frond's own namespace: /frond/pose, /frond/joint/<i>/quat, /frond/status
    Frond,
    /// The VMC protocol (/VMC/Ext/Bone/Pos ...), Unity's left-handed frame
    Vmc,
}

/// Streams frond's live poses as OSC bundles over UDP (frond namespace or VMC).
#[derive(Debug, Parser)]
#[command(version, about)]
struct Args {
    /// Destination HOST:PORT (repeatable). Default 127.0.0.1 on port 9000 (frond) or 39539 (vmc);
    /// a HOST without port gets that default port.
    #[arg(long = "target", value_name = "HOST:PORT")]
    targets: Vec<String>,
    /// OSC dialect.
    #[arg(long, value_enum, default_value = "frond")]
    protocol: ProtocolArg,
    /// Output rate: HZ sends the newest frame at this rate (never a stale one twice); `every`
    /// sends every frame the daemon publishes. Default: 60 for vmc (what VMC tools expect),
    /// every frame for frond.
    #[arg(long, value_name = "HZ|every")]
    rate: Option<String>,
    /// Bundle timetags: `immediately` (apply on receipt) or `publish` (the frame's publish time,
    /// NTP). Default: immediately for vmc and for any --from zenoh:..., publish for frond.
    #[arg(long, value_name = "WHEN")]
    timetag: Option<String>,
    /// Local address to send from, e.g. 0.0.0.0:0 or 192.168.1.5:0.
    #[arg(long, value_name = "ADDR")]
    bind: Option<String>,
    /// Print counters (received, gaps, per-target sent/refused/dropped) to stderr every second
    /// and at exit.
    #[arg(long)]
    stats: bool,
    /// The daemon's socket directory [default: $FROND_SOCKET_DIR, else
    /// $XDG_RUNTIME_DIR/frond, else /run/frond for root, else /tmp/frond-UID].
    /// The variable is read only when --from is not given, so an operator's environment does
    /// not conflict with --from.
    #[arg(long, value_name = "DIR")]
    socket_dir: Option<PathBuf>,
    /// Read the poses of a daemon on another host through its frond-zenoh bridge:
    /// `zenoh:frond/<stage>/<source>[?connect=tcp/HOST:PORT]` (default: this host's daemon,
    /// --socket-dir). Over Zenoh, timetags default to `immediately` for both dialects: a
    /// frame's publish time is the other host's clock.
    #[arg(long, value_name = "ADDRESS", conflicts_with = "socket_dir")]
    from: Option<frond_sdk::Source>,
    /// Rig for VMC joint offsets and, if it has a [vmc] table, bone names: an embedded rig
    /// (grass, flower, shrub) or a rig file (rig-files/plants/*.toml). Default: the grass rig's
    /// heights.
    #[arg(long, value_name = "RIG|FILE")]
    rig: Option<String>,
    /// VMC bone names: `humanoid` (Unity HumanBodyBones Hips,Spine,Chest,Neck: what VMC
    /// receivers map), `joints` (the daemon's joint names, followed live) or four
    /// comma-separated names. Default: the --rig file's [vmc] bones, else humanoid.
    #[arg(long, value_name = "NAMES")]
    vmc_bones: Option<String>,
    /// Measure daemon-to-receiver latency (p50/p99) with 1 and 4 loopback targets, print JSON
    /// lines, and exit.
    #[arg(long)]
    bench: bool,
    /// Seconds per bench run.
    #[arg(long, default_value_t = 5.0, value_name = "S")]
    bench_seconds: f64,
    /// Log filter (error, warn, info, debug, trace).
    #[arg(long, default_value = "info", value_name = "LEVEL")]
    log_level: String,
    /// Handled by `DocsArgs::early` before parsing; here for `--help` and the man page.
    #[allow(dead_code)]
    #[command(flatten)]
    docs: frond_binmain::DocsArgs,
}

/// Validates the raw arguments into a bridge configuration, reporting every problem at once.
fn validate(args: &Args) -> anyhow::Result<BridgeConfig> {
    let mut problems = Vec::new();
    let protocol = match args.protocol {
        ProtocolArg::Frond => Protocol::Frond,
        ProtocolArg::Vmc => Protocol::Vmc,
    };
    let default_port = match protocol {
        Protocol::Frond => DEFAULT_FROND_PORT,
        Protocol::Vmc => DEFAULT_VMC_PORT,
    };
    let specs = if args.targets.is_empty() { vec!["127.0.0.1".to_string()] } else { args.targets.clone() };
    let mut targets = Vec::new();
    for spec in &specs {
        match sender::parse_target(spec, default_port) {
            Ok(t) => targets.push(t),
            Err(e) => problems.push(e.to_string()),
        }
    }
    let bind = match &args.bind {
        None => None,
        Some(b) => match b.parse() {
            Ok(addr) => Some(addr),
            Err(_) => {
                problems.push(format!("--bind `{b}`: expected IP:PORT, e.g. 0.0.0.0:0"));
                None
            }
        },
    };
    let rate_hz = match (args.rate.as_deref(), protocol) {
        (Some("every"), _) | (None, Protocol::Frond) => None,
        (None, Protocol::Vmc) => Some(frond_osc::DEFAULT_VMC_RATE_HZ),
        (Some(r), _) => match r.parse::<f64>() {
            Ok(rate) if RATE_RANGE_HZ.contains(&rate) => Some(rate),
            _ => {
                problems.push(format!(
                    "--rate {r}: must be `every` or between {} and {} Hz",
                    RATE_RANGE_HZ.start(),
                    RATE_RANGE_HZ.end()
                ));
                None
            }
        },
    };
    let timetags = match (args.timetag.as_deref(), protocol) {
        (None, _) if matches!(args.from, Some(frond_sdk::Source::Zenoh(_))) => Timetags::Immediately,
        (Some("immediately"), _) | (None, Protocol::Vmc) => Timetags::Immediately,
        (Some("publish"), _) | (None, Protocol::Frond) => Timetags::Publish,
        (Some(other), _) => {
            problems.push(format!("--timetag {other}: expected `immediately` or `publish`"));
            Timetags::Publish
        }
    };
    if !(args.bench_seconds.is_finite() && args.bench_seconds > 0.0 && args.bench_seconds <= 3600.0) {
        problems.push(format!("--bench-seconds {}: must be in (0, 3600]", args.bench_seconds));
    }
    let mut vmc_rig = VmcRig::default();
    let mut names_fixed = true;
    let mut from_rig_table = false;
    if let Some(path) = &args.rig {
        match rig::load(path) {
            Ok(file) => {
                vmc_rig.heights_m = file.vmc.heights_m;
                if file.has_vmc_bones {
                    vmc_rig.bone_names = file.vmc.bone_names;
                    from_rig_table = true;
                }
            }
            Err(e) => problems.push(e.to_string()),
        }
    }
    match args.vmc_bones.as_deref() {
        Some("joints") => names_fixed = false,
        Some(spec) => match rig::parse_bone_names(spec) {
            Ok(names) => vmc_rig.bone_names = names,
            Err(e) => problems.push(e.to_string()),
        },
        None if from_rig_table => {}
        None => vmc_rig.bone_names = frond_osc::encode::vmc_humanoid_names(),
    }
    if !problems.is_empty() {
        return Err(frond_binmain::invalid_arguments(&problems));
    }
    if args.bench && args.from.is_some() {
        return Err(frond_binmain::usage(
            "--bench measures from this host's daemon (--socket-dir), not --from",
        ));
    }
    let source = match &args.from {
        Some(source) => source.clone(),
        None => frond_sdk::Source::Socket(
            args.socket_dir.clone().unwrap_or_else(frond_protocol::paths::default_socket_dir),
        ),
    };
    let mut config = BridgeConfig::new(source, protocol, targets);
    config.bind = bind;
    config.rate_hz = rate_hz;
    config.timetags = timetags;
    config.vmc_rig = vmc_rig;
    config.vmc_names_fixed = names_fixed;
    Ok(config)
}

fn run(args: &Args) -> anyhow::Result<()> {
    let config = validate(args)?;
    if args.bench {
        for n in [1, 4] {
            let frond_sdk::Source::Socket(dir) = &config.source else { unreachable!("checked in validate") };
            let report = bench::run(dir, n, Duration::from_secs_f64(args.bench_seconds))
                .with_context(|| format!("bench with {n} target(s)"))?;
            frond_binmain::outln!("{}", report.to_json())?;
        }
        return Ok(());
    }
    let stop = Arc::new(AtomicBool::new(false));
    for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register(sig, Arc::clone(&stop)).context("install signal handler")?;
    }
    let mut bridge = Bridge::connect(&config)?;
    for t in bridge.sender().targets() {
        tracing::info!(target_addr = %t.addr(), local = ?t.local_addr().ok(), protocol = ?config.protocol, "sending");
    }
    let every = args.stats.then_some(Duration::from_secs(1));
    let result = bridge.run(&stop, every, |s| frond_binmain::errln!("frond-osc stats: {s}"));
    let stats = bridge.stats();
    if args.stats {
        frond_binmain::errln!("frond-osc stats: {stats}");
    } else {
        tracing::info!(%stats, "stopped");
    }
    Ok(result?)
}

fn main() -> ExitCode {
    if let Some(code) = frond_binmain::DocsArgs::early("frond-osc", Args::command) {
        return code;
    }
    let args: Args = match frond_binmain::parse("frond-osc") {
        Ok(args) => args,
        Err(code) => return code,
    };
    if let Err(code) = frond_binmain::logging("frond-osc", &args.log_level) {
        return code;
    }
    frond_binmain::exit("frond-osc", run(&args))
}
