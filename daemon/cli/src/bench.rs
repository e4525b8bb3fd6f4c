//! `frond bench`: runs `frond-bench` (the measurements live in their own binary, so that `frond`
//! links neither the daemon's internals nor a counting allocator) with the same options.

use std::process::Command;

use anyhow::Context;
use clap::Args;

use crate::demo::find_program;

/// Runs `frond-bench` (beside `frond`, else on `PATH`); its report goes to stdout, progress to
/// stderr, and its exit status becomes ours.
pub fn run(a: &BenchArgs) -> anyhow::Result<()> {
    let program = find_program("frond-bench")?;
    let mut cmd = Command::new(&program);
    if a.quick {
        cmd.arg("--quick");
    }
    if a.json {
        cmd.arg("--json");
    }
    for s in &a.section {
        cmd.arg("--section").arg(s);
    }
    let status = cmd.status().with_context(|| format!("cannot run {}", program.display()))?;
    match status.code() {
        Some(0) => Ok(()),
        Some(code) => Err(crate::error::ChildFailed(code.clamp(1, 255) as u8).into()),
        None => Err(anyhow::anyhow!("{} was killed: {status}", program.display())),
    }
}

/// `frond bench` options.
#[derive(Debug, Clone, Args)]
pub struct BenchArgs {
    /// Short measurements (about 1-2 s each), for CI.
    #[arg(long)]
    pub quick: bool,
    /// Print the report as one JSON document instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Run only this section (repeatable): loop_timing, glove_latency, tick_cost, max_rate,
    /// daemon_resources, components, osc_latency, hidraw_latency, zenoh, field_wire, webcam.
    #[arg(long, value_name = "NAME")]
    pub section: Vec<String>,
}
