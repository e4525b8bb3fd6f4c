//! `frond bench`: frond's speed, each measurement beside a baseline measured in the same run
//! (machines are shared and noisy: a ratio counts, an absolute time alone does not).
//!
//! Sections (issue 9): [`timing::loop_timing`] (1), [`latency::glove_latency`] (2),
//! [`tick::tick_cost`] (3), [`timing::max_rate`] (4), [`resources::daemon_resources`] (5) and
//! [`components::components`] (6), [`osc_latency::osc_latency`] (7: the OSC source against a
//! do-nothing relay, `frond-relay`, see [`relay`]) and [`hidraw_latency::hidraw_latency`] (8: a
//! hidraw node's reports through frondd against the same relay reading the node) and
//! [`zenoh::zenoh`] (9: poses over Zenoh between network namespaces against plain UDP) and
//! [`field_wire::field_wire`] (10: a live field at 1 to 100,000 plants against per-plant poses, and
//! [`field_page`], the console page drawing it, and [`field_hand`], a hand sample to the first
//! plant moving on it). [`run`] returns a [`report::Report`]; `frond bench --json`
//! prints it, `frond bench` prints [`report::Report::to_table`].

#![warn(missing_docs)]

pub mod alloc;
pub mod components;
mod daemon_run;
pub mod error;
pub mod field_hand;
pub mod field_page;
pub mod field_wire;
pub mod hidraw_latency;
pub mod latency;
pub mod loops;
pub mod osc_latency;
pub mod plant_motion;
pub mod procs;
pub mod relay;
pub mod report;
pub mod resources;
pub mod rig;
mod stage_sync;
pub mod tick;
pub mod timing;
pub mod webcam;
pub mod zenoh;

use std::path::PathBuf;
use std::time::Instant;

pub use error::BenchError;
use report::{Machine, Report, SCHEMA, Section, Status};

/// Section keys, in report order.
pub const SECTIONS: [&str; 11] = [
    "loop_timing",
    "glove_latency",
    "tick_cost",
    "max_rate",
    "daemon_resources",
    "components",
    "osc_latency",
    "hidraw_latency",
    "zenoh",
    "field_wire",
    "webcam",
];

/// What to run.
#[derive(Debug, Clone, Default)]
pub struct Options {
    /// Short measurements (about 1-2 s each), for CI.
    pub quick: bool,
    /// Sections to run (keys of [`SECTIONS`]); empty = all.
    pub sections: Vec<String>,
    /// Where `frondd`, `frond-vhid` and the exporters' binaries are [default: `$FROND_BIN_DIR`,
    /// else the directory of the running executable].
    pub bin_dir: Option<PathBuf>,
    /// Print progress on stderr.
    pub progress: bool,
}

/// Checks section names; returns the unknown ones.
pub fn unknown_sections(names: &[String]) -> Vec<String> {
    names.iter().filter(|n| !SECTIONS.contains(&n.as_str())).cloned().collect()
}

fn title(name: &str) -> &'static str {
    match name {
        "loop_timing" => "loop wake-up lateness at 1 kHz and 8 kHz",
        "glove_latency" => "virtual glove report write -> subscriber receipt",
        "tick_cost" => "per-tick cost and allocations",
        "max_rate" => "highest sustainable tick rate with 8 subscribers",
        "daemon_resources" => "frondd CPU and memory at 1 kHz with 4 subscribers",
        "osc_latency" => "OSC hand sample -> subscriber receipt vs a do-nothing relay",
        "hidraw_latency" => "hidraw report -> subscriber receipt vs a do-nothing relay",
        "zenoh" => zenoh::TITLE,
        "field_wire" => field_wire::TITLE,
        "webcam" => webcam::TITLE,
        _ => "motion toolkit and exporters",
    }
}

/// Runs the selected sections and returns the report.
pub fn run(options: &Options) -> Report {
    let fifo = loops::probe_fifo(loops::BENCH_PRIORITY);
    let priority = if fifo.is_ok() { loops::BENCH_PRIORITY } else { 0 };
    let realtime = match &fifo {
        Ok(()) => format!("SCHED_FIFO priority {} for every measured loop", loops::BENCH_PRIORITY),
        Err(e) => format!("normal scheduling (SCHED_FIFO refused: {e})"),
    };
    let machine = procs::machine(realtime);
    let mut sections = Vec::new();
    for name in SECTIONS {
        if !options.sections.is_empty() && !options.sections.iter().any(|s| s == name) {
            continue;
        }
        if options.progress {
            eprintln!("frond bench: {name} ...");
        }
        let started = Instant::now();
        let result = match name {
            "loop_timing" => timing::loop_timing(options, priority),
            "glove_latency" => latency::glove_latency(options),
            "tick_cost" => tick::tick_cost(options),
            "max_rate" => timing::max_rate(options, priority),
            "daemon_resources" => resources::daemon_resources(options),
            "osc_latency" => osc_latency::osc_latency(options),
            "hidraw_latency" => hidraw_latency::hidraw_latency(options),
            "zenoh" => zenoh::zenoh(options),
            "field_wire" => field_wire::field_wire(options),
            "webcam" => webcam::webcam(options),
            _ => Ok(components::components(options)),
        };
        let mut section =
            result.unwrap_or_else(|e| Section::unavailable(name, title(name), Status::Error, e.to_string()));
        section.seconds = started.elapsed().as_secs_f64();
        if options.progress {
            eprintln!("frond bench: {name} done in {:.1} s", section.seconds);
        }
        sections.push(section);
    }
    let mut report = Report {
        schema: SCHEMA,
        frond_version: env!("CARGO_PKG_VERSION").into(),
        quick: options.quick,
        machine: Machine { ..machine },
        sections,
        targets: Vec::new(),
    };
    report.collect_targets();
    report
}
