//! `frondd`: the frond daemon. See the crate docs and README for the data flow.

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use clap::{CommandFactory, Parser};
use frond_protocol::paths;
use frondd::config::{Config, DEFAULT_CONFIG, RawConfig, RawHand};
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
    /// Directory of poses.sock and control.sock [default: $XDG_RUNTIME_DIR/frond].
    #[arg(long, env = "FROND_SOCKET_DIR")]
    socket_dir: Option<PathBuf>,
    /// Directory where takes are recorded [default: $XDG_DATA_HOME/frond/takes].
    #[arg(long, env = "FROND_TAKES_DIR")]
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
    /// leap://HOST:PORT[?hand=left|right] (a Leap Motion / Ultraleap service).
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
    /// of auto, virtual, in-process, hid, hid:PATH, replay:PATH, osc://IP:PORT, leap://HOST:PORT. E.g.
    /// `--hand left=hid:/dev/hidraw3 --hand right=hid:/dev/hidraw4,element=leaf`.
    #[arg(long = "hand", value_name = "NAME=KIND[,key=value...]")]
    hands: Vec<String>,
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
    let args = Args::parse();
    if args.print_default_config {
        return frond_binmain::exit("frondd", frond_binmain::out!("{DEFAULT_CONFIG}").map_err(Into::into));
    }
    if let Err(code) = frond_binmain::logging("frondd", &args.log_level) {
        return code;
    }

    let source = args.source.clone().or_else(|| {
        if args.replay.is_some() {
            Some("replay".into())
        } else if args.device.is_some() {
            Some("hid".into())
        } else {
            None
        }
    });
    let mut hands = Vec::new();
    for (i, flag) in args.hands.iter().enumerate() {
        match RawHand::parse_flag(flag) {
            Ok(hand) => hands.push(hand),
            Err(e) => {
                frond_binmain::say_error("frondd", &format!("--hand (#{}): {e}", i + 1));
                return ExitCode::from(2);
            }
        }
    }
    if !hands.is_empty() && (source.is_some() || args.profile.is_some()) {
        frond_binmain::say_error(
            "frondd",
            "--hand replaces --source, --device, --replay and --profile; give each hand its own",
        );
        return ExitCode::from(2);
    }
    let overrides = RawConfig::from_overrides(
        args.rate,
        args.rig,
        args.calibration,
        args.filter,
        source,
        args.profile,
        args.device,
        args.replay,
    )
    .with_hands(hands);
    let (config_path, optional) = (args.config.clone(), args.config_optional);
    // The file to read now: none when it is optional and absent.
    let present = move || {
        config_path.clone().filter(|p| {
            !(optional
                && std::fs::symlink_metadata(p).is_err_and(|e| e.kind() == std::io::ErrorKind::NotFound))
        })
    };
    let reload_overrides = overrides.clone();
    let reload_present = present.clone();
    let loader: ConfigLoader =
        Box::new(move || Config::load(reload_present().as_deref(), reload_overrides.clone()));
    let file = present();
    if let (Some(p), None) = (&args.config, &file) {
        tracing::info!(path = %p.display(), "no config file there (optional): the embedded defaults apply");
    }
    let config = match Config::load(file.as_deref(), overrides) {
        Ok(c) => c,
        Err(errors) => {
            for e in errors.problems {
                frond_binmain::say_error("frondd", &e.to_string());
            }
            return ExitCode::from(2);
        }
    };
    let dirs =
        Dirs { socket_dir: paths::socket_dir(args.socket_dir), takes_dir: paths::takes_dir(args.takes_dir) };
    let stop = Arc::new(AtomicBool::new(false));
    let reload = Arc::new(AtomicBool::new(false));
    let handlers = [
        (signal_hook::consts::SIGTERM, &stop),
        (signal_hook::consts::SIGINT, &stop),
        (signal_hook::consts::SIGHUP, &reload),
    ];
    for (signal, flag) in handlers {
        if let Err(e) = signal_hook::flag::register(signal, flag.clone()) {
            frond_binmain::say_error("frondd", &format!("cannot install the signal handler: {e}"));
            return ExitCode::FAILURE;
        }
    }
    let options = RunOptions { dirs, stop, reload, loader, test_hooks: args.test_hooks };
    match run(config, options) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            // Once, on stderr (the journal under systemd): not also as a log line.
            frond_binmain::say_error("frondd", &frond_binmain::error_text(&e));
            // Hands that clash (two on one element, an element the rig lacks) are a problem of
            // the configuration, as the config file's own problems are: exit 2.
            if matches!(e, frondd::error::DaemonError::Hand { .. }) {
                ExitCode::from(2)
            } else {
                ExitCode::FAILURE
            }
        }
    }
}
