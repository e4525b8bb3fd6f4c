//! `frond completions SHELL` and `frond man -o DIR`: generated from the same clap definitions
//! the command parses with (clap_complete, clap_mangen), so they cannot fall out of date.

use std::path::Path;

use clap::CommandFactory;

use crate::args::Cli;

/// Prints the completion script for `shell` on stdout.
pub(crate) fn completions(shell: clap_complete::Shell) -> anyhow::Result<()> {
    frond_binmain::completions(Cli::command(), "frond", shell)
}

/// Writes `frond.1` and a page per subcommand (`frond-take-export.1`, ...) into `dir`.
pub(crate) fn man(dir: &Path) -> anyhow::Result<()> {
    let written = frond_binmain::man(Cli::command(), "frond", dir)?;
    frond_binmain::outln!("wrote {written} man pages to {}", dir.display())?;
    Ok(())
}
