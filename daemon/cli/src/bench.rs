//! `frond bench`: runs the measurements of `frond_bench` and prints a table or JSON.

use std::io::Write;

use crate::args::BenchArgs;
use crate::usage;

/// Runs the selected sections; prints the report on stdout (progress on stderr).
pub fn run(a: &BenchArgs) -> anyhow::Result<()> {
    let unknown = frond_bench::unknown_sections(&a.section);
    if !unknown.is_empty() {
        return usage(format!(
            "--section {}: unknown section (known: {})",
            unknown.join(", "),
            frond_bench::SECTIONS.join(", ")
        ));
    }
    let options =
        frond_bench::Options { quick: a.quick, sections: a.section.clone(), bin_dir: None, progress: true };
    let report = frond_bench::run(&options);
    let mut out = std::io::stdout().lock();
    if a.json {
        serde_json::to_writer_pretty(&mut out, &report)?;
        writeln!(out)?;
    } else {
        write!(out, "{}", report.to_table())?;
    }
    out.flush()?;
    Ok(())
}
