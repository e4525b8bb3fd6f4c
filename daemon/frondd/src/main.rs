//! `frondd`: the frond daemon. See the crate docs and README for the data flow.

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use clap::{CommandFactory, Parser};
use frond_protocol::paths;
use frondd::config::{Config, DEFAULT_CONFIG, Overrides, RawConfig, RawHand};
use frondd::daemon::{ConfigLoader, Dirs, RunOptions, run};

/// frond daemon: reads a hand device at a fixed rate and publishes plant poses.
#[derive(Debug, Parser)]
#[command(version, about, long_about = None)]
struct Args {
    /// Configuration file (TOML); keys it sets override the embedded defaults.
    #[arg(long, env = "FROND_CONFIG")]
    config: Option<PathBuf>,
    /// With --config: a missing file means the embedded defaults (the file only overrides, and
    /// is read again on SIGHUP once it exists); any other problem with it is still an error.
    /// The service unit uses it, so a fresh install runs without /etc/frond/frondd.toml.
    #[arg(long, requires = "config")]
    config_optional: bool,
    #[arg(long, env = "FROND_SOCKET_DIR", value_name = "DIR", help = frond_protocol::paths::SOCKET_DIR_HELP)]
    socket_dir: Option<PathBuf>,
    #[arg(long, env = "FROND_TAKES_DIR", value_name = "DIR", help = frond_protocol::paths::TAKES_DIR_HELP)]
    takes_dir: Option<PathBuf>,
    /// Loop rate in Hz (30..=8000).
    #[arg(long)]
    rate: Option<u32>,
    /// Rig: embedded name (grass, flower, shrub) or a rig TOML file.
    #[arg(long)]
    rig: Option<String>,
    /// Calibration TOML file.
    #[arg(long)]
    calibration: Option<String>,
    /// Jitter filter: none, lowpass[:cutoff_hz=F], one-euro[:min_cutoff=..,beta=..,d_cutoff=..].
    #[arg(long)]
    filter: Option<String>,
    /// Hand source: auto, virtual, in-process, hid, replay, osc://IP:PORT,
    /// leap://HOST:PORT[?hand=left|right] (a Leap Motion / Ultraleap service),
    /// webcam[:DEVICE][?hand=left|right] (a camera through frond-hands).
    #[arg(long)]
    source: Option<String>,
    /// Device profile TOML (default: the embedded reference glove profile).
    #[arg(long)]
    profile: Option<String>,
    /// hidraw node to open (implies --source hid unless --source is given).
    #[arg(long)]
    device: Option<String>,
    /// JSONL hand recording to replay (implies --source replay).
    #[arg(long)]
    replay: Option<String>,
    /// A hand source of several (repeat, at most 8; replaces the config's `[[hands]]` and
    /// `--source`): NAME=KIND[,element=LAYER][,rig=RIG][,calibration=FILE][,profile=FILE], KIND one
    /// of auto, virtual, in-process, hid, hid:PATH, replay:PATH, osc://IP:PORT, leap://HOST:PORT, webcam[:DEVICE]. E.g.
    /// `--hand left=hid:/dev/hidraw3 --hand right=hid:/dev/hidraw4,element=leaf`.
    #[arg(long = "hand", value_name = "NAME=KIND[,key=value...]")]
    hands: Vec<String>,
    /// Follow a mocap stage's capture triggers (CaptureStart / CaptureStop over UDP) heard on
    /// this address, e.g. 0.0.0.0:30 (Vicon) or 0.0.0.0:1512 (Motive); `triggers.listen`.
    #[arg(long, value_name = "IP:PORT")]
    triggers: Option<String>,
    /// Follow triggers only from this host (repeat for several; replaces `triggers.allow`).
    #[arg(long = "trigger-allow", value_name = "IP")]
    trigger_allow: Vec<String>,
    /// Lead: send CaptureStart / CaptureStop to this address on frond's own record start / stop,
    /// e.g. 255.255.255.255:30; `triggers.lead`.
    #[arg(long, value_name = "IP:PORT")]
    trigger_lead: Option<String>,
    /// Read the stage's timecode (LTC) from an ALSA capture device (alsa:DEVICE, e.g.
    /// alsa:plughw:CARD=USB,DEV=0), or a file or FIFO of raw mono s16le samples, or a WAV
    /// file; at `ltc.sample_rate_hz` (default 48000) unless a WAV header says; `ltc.input`.
    #[arg(long, value_name = "alsa:DEVICE|PATH")]
    ltc: Option<String>,
    /// Log level or filter (error, warn, info, debug, trace, or a tracing filter).
    #[arg(long, env = "FROND_LOG", default_value = "info")]
    log_level: String,
    /// Print the embedded default configuration and exit.
    #[arg(long)]
    print_default_config: bool,
    /// Enable testing aids on the control socket (FreezeLoop). Never on a stage.
    #[arg(long, hide = true)]
    test_hooks: bool,
    /// Handled by `DocsArgs::early` before parsing; here for `--help` and the man page.
    #[allow(dead_code)]
    #[command(flatten)]
    docs: frond_binmain::DocsArgs,
}

fn main() -> ExitCode {
    if let Some(code) = frond_binmain::DocsArgs::early("frondd", Args::command) {
        return code;
    }
    let args: Args = match frond_binmain::parse("frondd") {
        Ok(args) => args,
        Err(code) => return code,
    };
    if args.print_default_config {
        return frond_binmain::exit("frondd", frond_binmain::out!("{DEFAULT_CONFIG}").map_err(Into::into));
    }
    if let Err(code) = frond_binmain::logging("frondd", &args.log_level) {
        return code;
    }
    match Options::from_args(args).and_then(run_daemon) {
        Ok(()) => ExitCode::SUCCESS,
        Err(exit) => exit.report(),
    }
}

/// The command line, validated: what the daemon runs with besides the configuration's contents.
struct Options {
    /// `--config`: the file whose keys override the embedded defaults.
    config_file: Option<PathBuf>,
    /// `--config-optional`: a missing `config_file` means the embedded defaults.
    config_optional: bool,
    /// What the command line sets over the file (`--rate`, `--rig`, `--source`, `--hand`, ...).
    overrides: RawConfig,
    /// Socket and takes directories.
    dirs: Dirs,
    /// `--test-hooks`.
    test_hooks: bool,
}

impl Options {
    /// Validates the raw arguments (the `--hand` flags, and that they replace the single hand's
    /// options rather than meet them).
    fn from_args(args: Args) -> Result<Options, Exit> {
        let overrides = overrides(&args)?;
        Ok(Options {
            config_file: args.config,
            config_optional: args.config_optional,
            overrides,
            dirs: Dirs {
                socket_dir: paths::socket_dir(args.socket_dir),
                takes_dir: paths::takes_dir(args.takes_dir),
            },
            test_hooks: args.test_hooks,
        })
    }

    /// Reads the configuration now, and returns with it the loader SIGHUP reads it again with.
    fn load_config(&self) -> Result<(Config, ConfigLoader), Exit> {
        let (path, optional, overrides) =
            (self.config_file.clone(), self.config_optional, self.overrides.clone());
        let loader: ConfigLoader =
            Box::new(move || Config::load(present_file(&path, optional).as_deref(), overrides.clone()));
        let file = present_file(&self.config_file, self.config_optional);
        if let (Some(p), None) = (&self.config_file, &file) {
            tracing::info!(path = %p.display(), "no config file there (optional): the embedded defaults apply");
        }
        let config = Config::load(file.as_deref(), self.overrides.clone())
            .map_err(|errors| Exit::Usage(errors.problems.iter().map(ToString::to_string).collect()))?;
        Ok((config, loader))
    }
}

/// What the command line sets over the configuration file: `--source` (or the kind `--replay`
/// or `--device` implies), every `--hand`, and the single hand's options, which `--hand` replaces.
fn overrides(args: &Args) -> Result<RawConfig, Exit> {
    let source = args.source.clone().or_else(|| {
        if args.replay.is_some() {
            Some("replay".into())
        } else if args.device.is_some() {
            Some("hid".into())
        } else {
            None
        }
    });
    let hands = (args.hands.iter().enumerate())
        .map(|(i, flag)| {
            RawHand::parse_flag(flag).map_err(|e| Exit::Usage(vec![format!("--hand (#{}): {e}", i + 1)]))
        })
        .collect::<Result<Vec<_>, _>>()?;
    if !hands.is_empty() && (source.is_some() || args.profile.is_some()) {
        return Err(Exit::Usage(vec![
            "--hand replaces --source, --device, --replay and --profile; give each hand its own".into(),
        ]));
    }
    let overrides = RawConfig::from_overrides(Overrides {
        rate: args.rate,
        rig: args.rig.clone(),
        calibration: args.calibration.clone(),
        filter: args.filter.clone(),
        source,
        profile: args.profile.clone(),
        device: args.device.clone(),
        replay: args.replay.clone(),
        triggers: args.triggers.clone(),
        trigger_allow: args.trigger_allow.clone(),
        trigger_lead: args.trigger_lead.clone(),
        ltc: args.ltc.clone(),
    });
    Ok(overrides.with_hands(hands))
}

/// The configuration file to read now: `path`, unless it is optional and absent.
fn present_file(path: &Option<PathBuf>, optional: bool) -> Option<PathBuf> {
    path.clone().filter(|p| {
        !(optional && std::fs::symlink_metadata(p).is_err_and(|e| e.kind() == std::io::ErrorKind::NotFound))
    })
}

/// The flags the signals set: SIGTERM and SIGINT `stop`, SIGHUP `reload`.
fn signal_flags() -> Result<(Arc<AtomicBool>, Arc<AtomicBool>), Exit> {
    let stop = Arc::new(AtomicBool::new(false));
    let reload = Arc::new(AtomicBool::new(false));
    let handlers = [
        (signal_hook::consts::SIGTERM, &stop),
        (signal_hook::consts::SIGINT, &stop),
        (signal_hook::consts::SIGHUP, &reload),
    ];
    for (signal, flag) in handlers {
        signal_hook::flag::register(signal, flag.clone())
            .map_err(|e| Exit::Failure(format!("cannot install the signal handler: {e}")))?;
    }
    Ok((stop, reload))
}

/// Loads the configuration, installs the signal handlers and runs the daemon until it stops.
fn run_daemon(options: Options) -> Result<(), Exit> {
    let (config, loader) = options.load_config()?;
    let (stop, reload) = signal_flags()?;
    let run_options = RunOptions { dirs: options.dirs, stop, reload, loader, test_hooks: options.test_hooks };
    run(config, run_options).map_err(|e| {
        let text = frond_binmain::error_text(&e);
        // Hands that clash (two on one element, an element the rig lacks) are a problem of the
        // configuration, as the config file's own problems are: exit 2.
        // So is an LTC input that is not one (absent, a directory, a WAV file frond does not read).
        if matches!(e, frondd::error::DaemonError::Hand { .. } | frondd::error::DaemonError::Ltc(_)) {
            Exit::Usage(vec![text])
        } else {
            Exit::Failure(text)
        }
    })
}

/// Why `frondd` stopped with an error, and so its exit status.
enum Exit {
    /// The command line or the configuration is wrong: every problem, one line each; exit 2.
    Usage(Vec<String>),
    /// Anything else: exit 1.
    Failure(String),
}

impl Exit {
    /// Says why, once, on stderr (the journal under systemd: not also as a log line), and gives
    /// the exit status.
    fn report(self) -> ExitCode {
        match self {
            Exit::Usage(problems) => {
                for problem in problems {
                    frond_binmain::say_error("frondd", &problem);
                }
                ExitCode::from(2)
            }
            Exit::Failure(text) => {
                frond_binmain::say_error("frondd", &text);
                ExitCode::FAILURE
            }
        }
    }
}
