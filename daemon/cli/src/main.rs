//! `frond`, the operator's command. Thin: parse, run, map errors to exit codes.

use std::process::ExitCode;

fn main() -> ExitCode {
    frond_cli::main_with_args(std::env::args_os())
}
