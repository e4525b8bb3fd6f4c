//! The `frond` command as a library, so that its pieces are unit-tested beside the code.
//!
//! Exit codes: 0 success, 1 failure, 2 usage error (bad arguments or values), 130 interrupted.
//! Errors are printed as `frond: error: ...` on stderr. A closed stdout (`frond tap | head`)
//! ends the command quietly with status 0.

#![warn(missing_docs)]

pub mod args;
mod bench;
mod calibrate;
mod control;
mod demo;
mod docs;
mod doctor;
mod error;
mod global;
mod graph_live;
mod live;
mod map;
mod signals;
mod soak;
mod stage_record;
mod status;
mod take_align;
mod take_bvh;
mod take_export;
mod take_file;
mod take_graph;
mod take_io;
mod take_sim;
mod take_tools;
mod take_usd;
mod takes;
mod tap;
mod tap_stage;

use std::ffi::OsString;
use std::io::{self, Write};
use std::process::ExitCode;

use clap::Parser;

pub use args::{Cli, Command};
pub use error::{ChildFailed, Interrupted, UsageError};

/// Parses `args` and runs the command; returns the process exit code.
pub fn main_with_args<I, T>(args: I) -> ExitCode
where
    I: IntoIterator<Item = T>,
    T: Into<OsString> + Clone,
{
    let cli = match Cli::try_parse_from(args) {
        Ok(cli) => cli,
        Err(e) if !e.use_stderr() => {
            // --help, --version
            let _ = e.print();
            return ExitCode::SUCCESS;
        }
        Err(e) => {
            let rendered = e.render().to_string();
            let msg = rendered.strip_prefix("error: ").unwrap_or(&rendered);
            // Not eprint!: a stderr that cannot be written must not turn exit 2 into a panic.
            let _ = write!(io::stderr().lock(), "frond: error: {msg}");
            return ExitCode::from(2);
        }
    };
    // Without --log-level nothing is installed: the libraries' logs stay unwritten, as they
    // always were.
    if let Some(level) = &cli.global.log_level
        && let Err(code) = frond_binmain::logging("frond", level)
    {
        return code;
    }
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => exit_for(&e),
    }
}

fn exit_for(e: &anyhow::Error) -> ExitCode {
    if frond_binmain::is_closed_stdout(e) {
        return ExitCode::SUCCESS;
    }
    if let Some(ChildFailed(code)) = e.downcast_ref::<ChildFailed>() {
        return ExitCode::from(*code);
    }
    if e.downcast_ref::<Interrupted>().is_some() {
        frond_binmain::errln!("frond: interrupted");
        return ExitCode::from(130);
    }
    frond_binmain::say_error("frond", &frond_binmain::error_text(e.as_ref()));
    if e.downcast_ref::<UsageError>().is_some() { ExitCode::from(2) } else { ExitCode::FAILURE }
}

/// Runs one parsed command.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    let g = &cli.global;
    match cli.command {
        Command::Status { json, from } => status::run(g, json, from.as_ref()),
        Command::Tap { jsonl, count, include_held, element, from } => match from {
            Some(frond_sdk::Source::Zenoh(addr)) if !addr.is_concrete() => {
                tap_stage::run(&addr, jsonl, count, include_held, element.as_deref())
            }
            from => tap::run(g, jsonl, count, include_held, element.as_deref(), from.as_ref()),
        },
        Command::Map { rig, calibration, filter, input } => {
            map::run(&rig, calibration.as_deref(), filter.as_deref(), input.as_deref())
        }
        Command::Calibrate(a) => calibrate::run(g, &a),
        Command::Calibration(args::CalibrationCommand::Apply { file }) => {
            control::apply_calibration(g, &file)
        }
        Command::Rig(args::RigCommand::Set { file }) => control::set_rig(g, &file),
        Command::Filter { spec } => control::set_filter(g, &spec),
        Command::Mark { label } => control::mark(g, &label),
        Command::Triggers { mode } => control::set_triggers(g, mode == args::TriggerMode::Follow),
        Command::Record(args::RecordCommand::Start(a)) => match &a.stage {
            None => control::record_start(g, &a.name),
            Some(stage) => stage_record::start(g, stage, &a),
        },
        Command::Record(args::RecordCommand::Stop) => control::record_stop(g),
        Command::Record(args::RecordCommand::Layer { name, layer, over, seed }) => {
            live::record_layer(g, &name, &layer, over, seed)
        }
        Command::Play { take, stop, seed } => live::play(g, take, stop, seed),
        Command::Field(args::FieldCommand::Start { take, field, plants, seed, rig, name }) => {
            let ask = live::FieldStart { plants, seed, rig: rig.as_deref(), name: name.as_deref() };
            live::field_start(g, &take, &field, ask)
        }
        Command::Field(args::FieldCommand::Stop { name }) => live::field_stop(g, name.as_deref()),
        Command::Field(args::FieldCommand::Key { key, name }) => live::field_key(g, &key, name.as_deref()),
        Command::Control => live::control(g),
        Command::Graph(cmd) => graph_live::run(g, cmd),
        Command::Sim(cmd) => graph_live::sim(g, cmd),
        Command::Guided { spec } => live::guided(g, &spec),
        Command::Take(args::TakeCommand::List { json }) => takes::list(g, json),
        Command::Take(args::TakeCommand::Export(a)) => take_export::run(g, a),
        Command::Take(args::TakeCommand::Repair { name }) => takes::repair(g, &name),
        Command::Take(args::TakeCommand::Tool(t)) => take_tools::run(g, t),
        Command::Demo { seconds, name, stay } => demo::run(g, seconds, name, stay),
        Command::Bench(a) => bench::run(&a),
        Command::Soak { duration, json, seed } => soak::run(duration, json, seed),
        Command::Doctor { json } => match doctor::run(g, json)? {
            true => Ok(()),
            // The report said what is wrong: exit 1, adding nothing.
            false => Err(anyhow::Error::new(ChildFailed(1))),
        },
        Command::Completions { shell } => docs::completions(shell),
        Command::Man { dir } => docs::man(&dir),
    }
}
