//! `frond-console`: serves the operator's console page (see the crate docs and README.md).

use std::net::{SocketAddr, TcpListener};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;

use anyhow::{Context, bail};
use clap::{CommandFactory, Parser};
use frond_binmain::outln;
use frond_console::access::{self, Access};
use frond_console::scene::{self, RigScene};
use frond_console::server::{Config, Console};

/// The operator's console: the plant live in 3D, the stage's health, takes and controls, in the
/// browser.
#[derive(Parser, Debug)]
#[command(name = "frond-console", version)]
struct Args {
    /// Address to listen on. Anything but a loopback address needs a token for every request.
    #[arg(long, value_name = "ADDR:PORT", default_value = "127.0.0.1:8790")]
    listen: SocketAddr,
    /// File holding the token (16-256 printable ASCII bytes) instead of a fresh random one; only
    /// its owner may read it (chmod 600).
    #[arg(long, value_name = "FILE")]
    token_file: Option<PathBuf>,
    #[arg(long, value_name = "DIR", help = frond_protocol::paths::SOCKET_DIR_HELP)]
    socket_dir: Option<PathBuf>,
    #[arg(long, value_name = "DIR", help = frond_protocol::paths::TAKES_DIR_HELP)]
    takes_dir: Option<PathBuf>,
    /// Show this rig (embedded name or file) instead of the daemon's, and bake the takes recorded
    /// on a rig that is not embedded with it (a rig file is never opened by the name a take or
    /// the daemon gives).
    #[arg(long, value_name = "NAME|FILE")]
    rig: Option<String>,
    /// Pose messages per second to each page (the display rate).
    #[arg(long, value_name = "HZ", default_value_t = 60, value_parser = clap::value_parser!(u32).range(1..=240))]
    display_hz: u32,
    /// Leave out the image-warp preview panel (it only runs while a page shows it).
    #[arg(long)]
    no_warp: bool,
    #[command(flatten)]
    log: frond_binmain::LogArgs,
    /// Handled by `DocsArgs::early` before parsing; here for `--help` and the man page.
    #[allow(dead_code)]
    #[command(flatten)]
    docs: frond_binmain::DocsArgs,
}

/// What the arguments ask, checked: the token file's token and the `--rig` scene.
struct Checked {
    token_from_file: Option<String>,
    rig: Option<Arc<RigScene>>,
}

/// Checks the arguments that name files before anything starts, every problem at once (a usage
/// error, exit 2): a console that started would answer 503 for its whole life for a rig it
/// cannot show, and an exposed token file is refused as `frond-zenoh` refuses its key file.
fn check(args: &Args) -> anyhow::Result<Checked> {
    let mut problems = Vec::new();
    let token_from_file = args.token_file.as_deref().and_then(|path| {
        access::read_token_file(path).map_err(|e| problems.push(format!("--token-file {e}"))).ok()
    });
    let rig = args.rig.as_deref().and_then(|name| {
        scene::load(name)
            .map(Arc::new)
            .map_err(|e| problems.push(format!("--rig {name}: {}", e.reason())))
            .ok()
    });
    if !problems.is_empty() {
        return Err(frond_binmain::invalid_arguments(&problems));
    }
    Ok(Checked { token_from_file, rig })
}

fn run(args: Args) -> anyhow::Result<()> {
    let checked = check(&args)?;
    // On a loopback address the console needs no token.
    let loopback = args.listen.ip().is_loopback();
    let token = match checked.token_from_file {
        Some(t) => Some(t),
        None if loopback => None,
        None => Some(access::new_token()),
    };
    let listener = TcpListener::bind(args.listen).with_context(|| format!("--listen {}", args.listen))?;
    let addr = listener.local_addr()?;
    let socket_dir = frond_protocol::paths::socket_dir(args.socket_dir.clone());
    let console = Console::start(Config {
        socket_dir: socket_dir.clone(),
        takes_dir: frond_protocol::paths::takes_dir(args.takes_dir.clone()),
        access: Access { loopback, port: addr.port(), token: token.clone() },
        rig: checked.rig,
        display_hz: args.display_hz,
        warp: !args.no_warp,
    })?;
    let host = if addr.ip().is_unspecified() { format!("HOST:{}", addr.port()) } else { addr.to_string() };
    match (&token, loopback) {
        (Some(t), false) if args.token_file.is_none() => {
            outln!("frond-console: http://{host}/?token={t}  (daemon {})", socket_dir.display())?
        }
        (Some(_), false) => outln!(
            "frond-console: http://{host}/?token=<the token in {}>  (daemon {})",
            args.token_file.as_deref().unwrap_or(std::path::Path::new("?")).display(),
            socket_dir.display()
        )?,
        _ => outln!("frond-console: http://{addr}/  (daemon {})", socket_dir.display())?,
    }
    if !loopback && token.is_none() {
        bail!("internal: a console beyond loopback without a token");
    }
    console.serve(listener);
    Ok(())
}

fn main() -> ExitCode {
    if let Some(code) = frond_binmain::DocsArgs::early("frond-console", Args::command) {
        return code;
    }
    let args: Args = match frond_binmain::parse("frond-console") {
        Ok(args) => args,
        Err(code) => return code,
    };
    if let Err(code) = args.log.init("frond-console") {
        return code;
    }
    frond_binmain::exit("frond-console", run(args))
}
