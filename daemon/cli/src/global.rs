//! The options every `frond` command takes: where the daemon's sockets and takes are, how to
//! reach a daemon on another host, and the log level. A module of its own, importing nothing of
//! the crate, so that the commands use it without importing the command-line tree that is built
//! from them.

use std::path::PathBuf;

use clap::Args;

/// Where the daemon's sockets and takes are.
#[derive(Debug, Clone, Args)]
pub struct Global {
    /// Directory of the daemon's sockets ([`frond_protocol::paths::SOCKET_DIR_HELP`]).
    #[arg(long, global = true, env = "FROND_SOCKET_DIR", value_name = "DIR", help = frond_protocol::paths::SOCKET_DIR_HELP)]
    pub socket_dir: Option<PathBuf>,
    /// Directory of recorded takes ([`frond_protocol::paths::TAKES_DIR_HELP`]).
    #[arg(long, global = true, env = "FROND_TAKES_DIR", value_name = "DIR", help = frond_protocol::paths::TAKES_DIR_HELP)]
    pub takes_dir: Option<PathBuf>,
    /// Send control commands (status, record, mark, rig set, filter, stage ...) to a daemon on
    /// another host, through its frond-zenoh bridge started with --control:
    /// `zenoh:frond/<stage>/<source>[?connect=tcp/HOST:PORT]`. Needs --as and --key-file.
    #[arg(long, global = true, env = "FROND_REMOTE", value_name = "ADDRESS")]
    pub remote: Option<frond_sdk::Source>,
    /// The principal remote control requests are signed as (a name in the bridge's --control
    /// file).
    #[arg(long = "as", global = true, env = "FROND_REMOTE_AS", value_name = "NAME")]
    pub remote_as: Option<String>,
    /// The principal's key: a file holding its hex key, readable by its owner only.
    #[arg(long = "key-file", global = true, env = "FROND_REMOTE_KEY_FILE", value_name = "FILE")]
    pub remote_key_file: Option<PathBuf>,
    /// Log level or filter of the libraries frond runs on (its Zenoh sessions among them):
    /// error, warn, info, debug, trace, or a tracing filter such as `zenoh=debug` [default: off].
    #[arg(long, global = true, value_name = "LEVEL")]
    pub log_level: Option<String>,
}
