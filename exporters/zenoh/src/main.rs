//! `frond-zenoh`: publishes one daemon's streams on Zenoh (see the crate docs and README).

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use anyhow::Context;
use clap::{CommandFactory, Parser};
use frond_sdk::{ZenohAddr, source};
use frond_zenoh::{Bridge, BridgeConfig, DEFAULT_STATUS_INTERVAL, STATUS_INTERVAL_RANGE};

/// Publishes the frond daemon's poses, elements, hello and status on Zenoh under
/// frond/<stage>/<source>, for subscribers on other hosts (`--from zenoh:frond/<stage>/<source>`).
#[derive(Debug, Parser)]
#[command(version, about)]
struct Args {
    /// Stage name: every daemon of one performance space shares it.
    #[arg(long, env = "FROND_STAGE", default_value = "default", value_name = "NAME")]
    stage: String,
    /// Source name, unique on the stage (e.g. the performer's glove). Default: this host's name.
    #[arg(long, env = "FROND_SOURCE", value_name = "NAME")]
    source: Option<String>,
    /// Zenoh endpoint to listen on (repeatable), e.g. tcp/0.0.0.0:7447. Default: Zenoh's
    /// (a peer listens on a free TCP port and is found by scouting).
    #[arg(long, value_name = "ENDPOINT")]
    listen: Vec<String>,
    /// Zenoh endpoint to connect to (repeatable): another peer, or a router (zenohd).
    #[arg(long, value_name = "ENDPOINT")]
    connect: Vec<String>,
    /// Zenoh configuration file (JSON5): mode, scouting, TLS, user/password; the endpoint flags
    /// apply on top of it.
    #[arg(long = "zenoh-config", value_name = "FILE")]
    zenoh_config: Option<PathBuf>,
    /// Answer remote control requests (`frond --remote ...`) signed by the principals this
    /// allow-list file names (TOML, see the README's "Remote control"); off without it.
    #[arg(long, value_name = "FILE")]
    control: Option<PathBuf>,
    /// Milliseconds between two status publications (50 to 10000).
    #[arg(long, value_name = "MS")]
    status_interval_ms: Option<u64>,
    /// Poses kept for reliable subscribers to fetch what they lost (a stage recorder does);
    /// 0 keeps none. Default 10000: 10 s at 1 kHz, about 3 MB.
    #[arg(long, value_name = "N", default_value_t = frond_zenoh::DEFAULT_REPLAY_FRAMES)]
    replay_frames: usize,
    #[arg(long, env = "FROND_SOCKET_DIR", value_name = "DIR", help = frond_protocol::paths::SOCKET_DIR_HELP)]
    socket_dir: Option<PathBuf>,
    /// Print the bridge's counters to stderr every second (they are printed once at exit anyway).
    #[arg(long)]
    stats: bool,
    /// Log filter (error, warn, info, debug, trace).
    #[arg(long, default_value = "info", value_name = "LEVEL")]
    log_level: String,
    /// Handled by `DocsArgs::early` before parsing; here for `--help` and the man page.
    #[allow(dead_code)]
    #[command(flatten)]
    docs: frond_binmain::DocsArgs,
}

/// This host's name as a key chunk (characters a name may not hold become `-`).
fn host_name() -> String {
    let raw = std::fs::read_to_string("/proc/sys/kernel/hostname").unwrap_or_default();
    let name: String = raw
        .trim()
        .chars()
        .take(source::MAX_NAME_LEN)
        .map(|c| if c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.') { c } else { '-' })
        .collect();
    if name.is_empty() { "frond".into() } else { name }
}

/// The test hook's environment variable (see [`BridgeConfig::clock_offset_ns`]).
const CLOCK_OFFSET_ENV: &str = "FROND_TEST_CLOCK_OFFSET_NS";
/// Largest offset the hook accepts: one day.
const MAX_TEST_CLOCK_OFFSET_NS: u64 = 86_400_000_000_000;

fn validate(args: &Args) -> anyhow::Result<BridgeConfig> {
    let mut problems = Vec::new();
    let source_name = args.source.clone().unwrap_or_else(host_name);
    let mut addr = match ZenohAddr::new(&args.stage, &source_name) {
        Ok(addr) => addr,
        Err(e) => {
            problems.push(format!("--stage/--source: {e}"));
            ZenohAddr::new("default", "frond").expect("valid names")
        }
    };
    // The endpoints go through the same checks as a subscriber's address.
    let mut spec = format!("zenoh:{}", addr.key);
    let mut sep = '?';
    for (name, list) in [("connect", &args.connect), ("listen", &args.listen)] {
        for endpoint in list {
            spec.push(sep);
            spec.push_str(&format!("{name}={endpoint}"));
            sep = '&';
        }
    }
    match spec.parse::<frond_sdk::Source>() {
        Ok(frond_sdk::Source::Zenoh(parsed)) if problems.is_empty() => addr = parsed,
        Ok(_) => {}
        Err(e) => problems.push(e.to_string()),
    }
    addr.config = args.zenoh_config.clone();
    let status_interval = match args.status_interval_ms {
        None => DEFAULT_STATUS_INTERVAL,
        Some(ms) if STATUS_INTERVAL_RANGE.contains(&Duration::from_millis(ms)) => Duration::from_millis(ms),
        Some(ms) => {
            problems.push(format!("--status-interval-ms {ms}: must be between 50 and 10000"));
            DEFAULT_STATUS_INTERVAL
        }
    };
    // Test hook: pretend this host's realtime clock is off by this much (stage-time tests).
    let clock_offset_ns = match std::env::var(CLOCK_OFFSET_ENV) {
        Err(_) => 0,
        Ok(text) => match text.parse::<i64>() {
            Ok(ns) if ns.unsigned_abs() <= MAX_TEST_CLOCK_OFFSET_NS => ns,
            _ => {
                problems.push(format!(
                    "{CLOCK_OFFSET_ENV}={text:?}: nanoseconds, an integer within +-{MAX_TEST_CLOCK_OFFSET_NS}"
                ));
                0
            }
        },
    };
    if args.replay_frames > frond_zenoh::MAX_REPLAY_FRAMES {
        problems.push(format!(
            "--replay-frames {}: at most {}",
            args.replay_frames,
            frond_zenoh::MAX_REPLAY_FRAMES
        ));
    }
    let control = match &args.control {
        None => None,
        Some(path) => match frond_zenoh::control::ControlPolicy::read(path) {
            Ok(policy) => Some(policy),
            Err(e) => {
                problems.push(format!("--control: {e}"));
                None
            }
        },
    };
    if !problems.is_empty() {
        return Err(frond_binmain::invalid_arguments(&problems));
    }
    let socket_dir = args.socket_dir.clone().unwrap_or_else(frond_protocol::paths::default_socket_dir);
    let replay_frames = args.replay_frames;
    Ok(BridgeConfig { socket_dir, addr, status_interval, clock_offset_ns, control, replay_frames })
}

fn run(args: &Args) -> anyhow::Result<()> {
    let config = validate(args)?;
    let stop = Arc::new(AtomicBool::new(false));
    for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register(sig, Arc::clone(&stop)).context("install signal handler")?;
    }
    let key = config.addr.key.clone();
    let mut bridge = Bridge::open(config).context("opening the Zenoh session")?;
    tracing::info!(%key, zid = %bridge.zid(), "frond-zenoh up");
    let printer = args.stats.then(|| {
        let stop = stop.clone();
        let stats = bridge.stats_handle();
        std::thread::spawn(move || {
            while !stop.load(Ordering::Relaxed) {
                std::thread::sleep(Duration::from_secs(1));
                frond_binmain::errln!("frond-zenoh stats: {stats}");
            }
        })
    });
    let result = bridge.run(&stop);
    stop.store(true, Ordering::Relaxed);
    if let Some(p) = printer {
        let _ = p.join();
    }
    frond_binmain::errln!("frond-zenoh stats: {}", bridge.stats());
    Ok(result?)
}

fn main() -> ExitCode {
    if let Some(code) = frond_binmain::DocsArgs::early("frond-zenoh", Args::command) {
        return code;
    }
    let args: Args = match frond_binmain::parse("frond-zenoh") {
        Ok(args) => args,
        Err(code) => return code,
    };
    if let Err(code) = frond_binmain::logging("frond-zenoh", &args.log_level) {
        return code;
    }
    frond_binmain::exit("frond-zenoh", run(&args))
}
