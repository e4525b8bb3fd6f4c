//! `frond-vhid`: the virtual frond glove. Plays a JSONL hand file or a procedural sway as
//! reference-glove HID reports through a real device node (UHID where `/dev/uhid` exists,
//! otherwise a FUSE file that behaves as a hidraw node), with fault injection.
//!
//! Prints the node path as the first line on stdout once the node is ready; logs to stderr.

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use clap::{CommandFactory, Parser, ValueEnum};
use frond_vhid::{
    self as vhid, DeviceClock, FaultPlan, GloveSource, UnplugPlan, VhidStats, VirtualGloveConfig,
    uhid::UhidGlove,
};

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum Clock {
    /// The glove's own counter: each sample's time on the played schedule.
    Schedule,
    /// Host CLOCK_MONOTONIC microseconds (truncated to u32) at the moment each report is
    /// written, for measuring glove-to-subscriber latency across processes.
    Monotonic,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum Backend {
    /// UHID if /dev/uhid exists, else FUSE.
    Auto,
    /// A FUSE file that behaves as a hidraw node.
    Fuse,
    /// A kernel HID device through /dev/uhid.
    Uhid,
}

/// The virtual frond glove.
#[derive(Debug, Parser)]
#[command(name = "frond-vhid", version)]
struct Args {
    /// Play this JSONL hand file (`{"t":..,"wrist":[p,y,r],"thumb":[g1,g2,g3]}` per line) at its
    /// timestamps.
    #[arg(long, value_name = "FILE.jsonl", conflicts_with = "sway")]
    play: Option<PathBuf>,
    /// Play the built-in procedural sway (the default).
    #[arg(long)]
    sway: bool,
    /// Report rate of the sway, 1..=8000 Hz (a JSONL file's rate comes from its timestamps).
    #[arg(long, value_name = "HZ", default_value_t = 1000.0)]
    rate: f64,
    /// Node path for the FUSE backend; its parent directory becomes the mount point (created if
    /// missing, must be empty). Default: $XDG_RUNTIME_DIR (or /tmp)/frond-vhid-PID/hidraw-frond.
    #[arg(long, value_name = "PATH")]
    node: Option<PathBuf>,
    /// Device node backend.
    #[arg(long, value_enum, default_value_t = Backend::Auto)]
    backend: Backend,
    /// Instead of a device node, send `/frond/hand` OSC messages to HOST:PORT (UDP), as a
    /// tracker bridge would: the reference sender for `frondd --source osc://HOST:PORT`.
    #[arg(long, value_name = "HOST:PORT", conflicts_with_all = ["node", "backend"])]
    osc: Option<String>,
    /// Probability of dropping each report.
    #[arg(long = "drop", value_name = "P", default_value_t = 0.0)]
    drop_prob: f64,
    /// Probability of corrupting one byte of each report.
    #[arg(long = "corrupt", value_name = "P", default_value_t = 0.0)]
    corrupt_prob: f64,
    /// Unplug this many milliseconds after the first report...
    #[arg(long, value_name = "T", requires = "unplug_ms")]
    unplug_at_ms: Option<u64>,
    /// ...for this many milliseconds (remove the node and re-create it).
    #[arg(long, value_name = "N", requires = "unplug_at_ms")]
    unplug_ms: Option<u64>,
    /// Repeat the unplug with this period in milliseconds.
    #[arg(long, value_name = "P", requires = "unplug_at_ms")]
    unplug_every_ms: Option<u64>,
    /// Stall (stay plugged in, send nothing) this many milliseconds after the first report.
    #[arg(long, value_name = "T", requires = "stall_ms")]
    stall_at_ms: Option<u64>,
    /// How long each stall lasts, milliseconds.
    #[arg(long, value_name = "N", requires = "stall_at_ms")]
    stall_ms: Option<u64>,
    /// Repeat the stall with this period in milliseconds.
    #[arg(long, value_name = "P", requires = "stall_at_ms")]
    stall_every_ms: Option<u64>,
    /// Shift the reports' device time this many milliseconds after the first report...
    #[arg(long, value_name = "T", requires_all = ["time_jump_ms", "time_jump_s"])]
    time_jump_at_ms: Option<u64>,
    /// ...for this many milliseconds...
    #[arg(long, value_name = "N", requires = "time_jump_at_ms")]
    time_jump_ms: Option<u64>,
    /// ...by this many seconds (negative: back), as a glitching or restarting clock would.
    #[arg(long, value_name = "S", allow_negative_numbers = true, requires = "time_jump_at_ms")]
    time_jump_s: Option<f64>,
    /// Delay each report by a random 0..=J microseconds.
    #[arg(long, value_name = "J", default_value_t = 0)]
    jitter_us: u32,
    /// Start the JSONL file over at its end.
    #[arg(long = "loop", requires = "play")]
    looped: bool,
    /// Wait this long after the node is ready before the first report.
    #[arg(long, value_name = "N", default_value_t = 0)]
    start_delay_ms: u64,
    /// Keep the node alive this long after the last report of a JSONL file, then exit 0.
    #[arg(long, value_name = "N", default_value_t = 500)]
    linger_ms: u64,
    /// What each report's device-time field carries.
    #[arg(long, value_enum, default_value_t = Clock::Schedule)]
    clock: Clock,
    /// Seed of the fault injection.
    #[arg(long, default_value_t = 0x5EED_F20D)]
    seed: u64,
    /// Log level (error, warn, info, debug, trace).
    #[arg(long, default_value = "info")]
    log_level: String,
    /// Handled by `DocsArgs::early` before parsing; here for `--help` and the man page.
    #[allow(dead_code)]
    #[command(flatten)]
    docs: frond_binmain::DocsArgs,
}

static STOP: AtomicBool = AtomicBool::new(false);

extern "C" fn on_signal(_sig: libc::c_int) {
    STOP.store(true, Ordering::SeqCst);
}

fn install_signal_handlers() -> Result<()> {
    for sig in [libc::SIGINT, libc::SIGTERM, libc::SIGHUP] {
        // SAFETY: a zeroed sigaction is a valid "no flags, empty mask" value; the handler only
        // stores to an atomic, which is async-signal-safe; `act` outlives the call.
        let r = unsafe {
            let mut act: libc::sigaction = std::mem::zeroed();
            act.sa_sigaction = on_signal as *const () as libc::sighandler_t;
            act.sa_flags = libc::SA_RESTART;
            libc::sigemptyset(&mut act.sa_mask);
            libc::sigaction(sig, &act, std::ptr::null_mut())
        };
        if r != 0 {
            bail!("cannot install signal handler: {}", std::io::Error::last_os_error());
        }
    }
    Ok(())
}

fn config(args: &Args) -> Result<VirtualGloveConfig> {
    let source = match &args.play {
        Some(path) => GloveSource::Jsonl { path: path.clone(), looped: args.looped },
        None => GloveSource::Sway { rate_hz: args.rate },
    };
    let unplug = match (args.unplug_at_ms, args.unplug_ms) {
        (Some(at_ms), Some(duration_ms)) => {
            Some(UnplugPlan { at_ms, duration_ms, every_ms: args.unplug_every_ms })
        }
        _ => None,
    };
    Ok(VirtualGloveConfig {
        source,
        faults: FaultPlan {
            drop_prob: args.drop_prob,
            corrupt_prob: args.corrupt_prob,
            unplug,
            stall: match (args.stall_at_ms, args.stall_ms) {
                (Some(at_ms), Some(duration_ms)) => {
                    Some(UnplugPlan { at_ms, duration_ms, every_ms: args.stall_every_ms })
                }
                _ => None,
            },
            time_jump: match (args.time_jump_at_ms, args.time_jump_ms, args.time_jump_s) {
                (Some(at_ms), Some(duration_ms), Some(s)) => {
                    if !(s.is_finite() && s.abs() <= 4294.0) {
                        return Err(frond_binmain::usage(format!(
                            "--time-jump-s must be within +-4294 s (the 32-bit microsecond clock), got {s}"
                        )));
                    }
                    Some(vhid::TimeJump { at_ms, duration_ms, by_us: (s * 1e6).round() as i64 })
                }
                _ => None,
            },
            jitter_us: args.jitter_us,
            seed: args.seed,
        },
        start_delay_ms: args.start_delay_ms,
        clock: match args.clock {
            Clock::Schedule => DeviceClock::Schedule,
            Clock::Monotonic => DeviceClock::Monotonic,
        },
    })
}

fn default_node() -> PathBuf {
    let base = std::env::var_os("XDG_RUNTIME_DIR")
        .map(PathBuf::from)
        .filter(|p| p.is_dir())
        .unwrap_or_else(std::env::temp_dir);
    base.join(format!("frond-vhid-{}", std::process::id())).join(vhid::NODE_NAME)
}

enum Glove {
    Fuse(vhid::VirtualGloveHandle),
    Uhid(UhidGlove),
    Osc(vhid::OscGlove, String),
}

impl Glove {
    /// What the first line of stdout names: the node, or the OSC target.
    fn node(&self) -> std::path::PathBuf {
        match self {
            Self::Fuse(g) => g.node_path().to_owned(),
            Self::Uhid(g) => g.node_path().to_owned(),
            Self::Osc(_, target) => PathBuf::from(format!("osc://{target}")),
        }
    }
    fn stats(&self) -> std::sync::Arc<VhidStats> {
        match self {
            Self::Fuse(g) => g.stats(),
            Self::Uhid(g) => g.stats(),
            Self::Osc(g, _) => g.stats(),
        }
    }
}

fn run(args: Args) -> Result<()> {
    let config = config(&args)?;
    install_signal_handlers()?;
    let use_uhid = match args.backend {
        Backend::Uhid => true,
        Backend::Fuse => false,
        Backend::Auto => vhid::uhid::available(),
    };
    let glove = if let Some(target) = &args.osc {
        use std::net::ToSocketAddrs;
        let addr = target.to_socket_addrs().ok().and_then(|mut a| a.next()).ok_or_else(|| {
            frond_binmain::usage(format!("--osc {target:?}: expected HOST:PORT, e.g. 127.0.0.1:9001"))
        })?;
        Glove::Osc(
            vhid::OscGlove::start(config, addr).context("cannot start the OSC sender")?,
            target.clone(),
        )
    } else if use_uhid {
        Glove::Uhid(UhidGlove::create(config).context("cannot create the UHID glove")?)
    } else {
        let node = args.node.clone().unwrap_or_else(default_node);
        Glove::Fuse(
            vhid::mount_fuse_node(&node, config)
                .context("cannot serve the virtual glove as a FUSE hidraw node")?,
        )
    };
    frond_binmain::outln!("{}", glove.node().display())?;
    tracing::info!(node = %glove.node().display(), "virtual glove ready");
    let stats = glove.stats();
    let mut finished_at: Option<Instant> = None;
    loop {
        if STOP.load(Ordering::SeqCst) {
            tracing::info!("signal received, unplugging");
            break;
        }
        if stats.finished.load(Ordering::Acquire) {
            let at = *finished_at.get_or_insert_with(Instant::now);
            if at.elapsed() >= Duration::from_millis(args.linger_ms) {
                tracing::info!("hand file played to the end");
                break;
            }
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let result = match glove {
        Glove::Fuse(g) => g.unmount().context("unmount failed"),
        Glove::Uhid(g) => {
            drop(g);
            Ok(())
        }
        Glove::Osc(g, _) => {
            drop(g);
            Ok(())
        }
    };
    let r = |a: &std::sync::atomic::AtomicU64| a.load(Ordering::Relaxed);
    tracing::info!(
        sent = r(&stats.sent),
        dropped = r(&stats.dropped),
        corrupted = r(&stats.corrupted),
        unplugged_lost = r(&stats.unplugged_lost),
        unplugs = r(&stats.unplugs),
        clamped = r(&stats.clamped),
        "virtual glove stopped"
    );
    result
}

fn main() -> ExitCode {
    if let Some(code) = frond_binmain::DocsArgs::early("frond-vhid", Args::command) {
        return code;
    }
    let args: Args = match frond_binmain::parse("frond-vhid") {
        Ok(args) => args,
        Err(code) => return code,
    };
    if let Err(code) = frond_binmain::logging("frond-vhid", &args.log_level) {
        return code;
    }
    // An invalid configuration (a rate of 0, a probability past 1) comes from the arguments.
    let bad_config = |e: &(dyn std::error::Error + 'static)| {
        e.downcast_ref::<vhid::VhidError>().is_some_and(|e| matches!(e, vhid::VhidError::Config(_)))
    };
    frond_binmain::exit_with("frond-vhid", run(args), bad_config)
}
