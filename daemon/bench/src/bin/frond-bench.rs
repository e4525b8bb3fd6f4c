//! `frond-bench`: frond's measurements, each beside a baseline measured in the same run. Its own
//! binary, so that `frond` (which runs it for `frond bench`) links neither the daemon's internals
//! nor a counting allocator.

use std::io::Write;
use std::process::ExitCode;

use clap::Parser;

/// Counts allocations only on a thread inside a measurement; otherwise one relaxed load per
/// allocation on top of the system allocator.
#[global_allocator]
static ALLOCATOR: frond_bench::alloc::CountingAlloc = frond_bench::alloc::CountingAlloc;

/// Measure frond: every figure beside a baseline from the same run, as a table or JSON.
#[derive(Parser)]
#[command(name = "frond-bench", version)]
struct Args {
    /// Short measurements (about 1-2 s each), for CI.
    #[arg(long)]
    quick: bool,
    /// Print the report as one JSON document instead of a table.
    #[arg(long)]
    json: bool,
    /// Run only this section (repeatable): loop_timing, glove_latency, tick_cost, max_rate,
    /// daemon_resources, components, osc_latency, hidraw_latency, zenoh.
    #[arg(long, value_name = "NAME")]
    section: Vec<String>,
}

fn main() -> ExitCode {
    let args: Args = match frond_binmain::parse("frond-bench") {
        Ok(args) => args,
        Err(code) => return code,
    };
    let unknown = frond_bench::unknown_sections(&args.section);
    if !unknown.is_empty() {
        eprintln!(
            "frond-bench: error: --section {}: unknown section (known: {})",
            unknown.join(", "),
            frond_bench::SECTIONS.join(", ")
        );
        return ExitCode::from(2);
    }
    let options =
        frond_bench::Options { quick: args.quick, sections: args.section, bin_dir: None, progress: true };
    let report = frond_bench::run(&options);
    let mut out = std::io::stdout().lock();
    let written = if args.json {
        serde_json::to_writer_pretty(&mut out, &report)
            .map_err(std::io::Error::other)
            .and_then(|()| writeln!(out))
    } else {
        write!(out, "{}", report.to_table())
    };
    match written.and_then(|()| out.flush()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("frond-bench: error: writing the report: {e}");
            ExitCode::FAILURE
        }
    }
}
