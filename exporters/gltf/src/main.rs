//! `frond-gltf`: bake frond takes, layered takes and fields into skinned, animated glTF files.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use anyhow::{Context, bail};
use clap::{Args, CommandFactory, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};

use frond_gltf::live::{LiveMode, capture};
use frond_gltf::{BakeOptions, Baked, Baker, Field, Format, LoadedRig, TakeInput, output};

#[derive(Parser)]
#[command(
    name = "frond-gltf",
    version,
    about = "Bake frond takes into skinned, animated glTF 2.0 (GLB) files",
    // `--log-level` before or after the subcommand.
    mut_arg("log_level", |a| a.global(true))
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
    #[command(flatten)]
    log: frond_binmain::LogArgs,
    /// Handled by `DocsArgs::early` before parsing; here for `--help` and the man page.
    #[allow(dead_code)]
    #[command(flatten)]
    docs: frond_binmain::DocsArgs,
}

#[derive(Subcommand)]
enum Command {
    /// Bake a take on one plant, several takes as a grove (one plant each, on a grid), or (with
    /// --field) a take on every plant of a field.
    Bake(BakeArgs),
    /// Capture the running daemon's next recording (or everything until Ctrl-C with --all) and
    /// bake it when recording stops or on Ctrl-C.
    Live(LiveArgs),
}

#[derive(Args)]
struct Common {
    /// Output file (.glb; with --gltf a .gltf and a .bin beside it).
    #[arg(short = 'o', long = "output", value_name = "FILE")]
    output: PathBuf,
    /// Key rate of the baked animation, frames per second.
    #[arg(long, default_value_t = 30.0, value_name = "FPS")]
    fps: f64,
    /// Write .gltf + .bin instead of one .glb.
    #[arg(long)]
    gltf: bool,
    /// Seed of the random assignment of secondary layers to similar elements.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// No progress bar and no summary (errors are still printed).
    #[arg(short, long)]
    quiet: bool,
    /// Bake a take past 1,080,000 keys (never past 16,777,216).
    #[arg(long)]
    force: bool,
}

#[derive(Args)]
struct BakeArgs {
    /// Take: a name in the takes directory, or a path to a .take file. Repeat it (or give several
    /// after one --take) to bake a grove: one plant per take, e.g. the walks of
    /// `frond take walk --plants N`.
    #[arg(long, value_name = "TAKE", num_args = 1.., required = true)]
    take: Vec<String>,
    /// Distance between the plants of a grove, metres [default: the rig's top joint height].
    #[arg(long, value_name = "METRES", conflicts_with = "field")]
    spacing: Option<f32>,
    /// Field file (field.json from `frond take field`): bake every plant of the field.
    #[arg(long, value_name = "FILE", requires = "duration")]
    field: Option<PathBuf>,
    /// Length of a field bake, seconds.
    #[arg(long, value_name = "SECONDS", requires = "field")]
    duration: Option<f64>,
    #[arg(long, value_name = "DIR", help = frond_protocol::paths::TAKES_DIR_HELP)]
    takes_dir: Option<PathBuf>,
    /// Rig: an embedded rig name (grass, flower, shrub) or a rig file.
    #[arg(long, value_name = "RIG")]
    rig: String,
    #[command(flatten)]
    common: Common,
}

#[derive(Args)]
struct LiveArgs {
    #[arg(long, value_name = "DIR", help = frond_protocol::paths::SOCKET_DIR_HELP)]
    socket_dir: Option<PathBuf>,
    /// Capture a daemon on another host through its frond-zenoh bridge:
    /// `zenoh:frond/<stage>/<source>[?connect=tcp/HOST:PORT]` [default: this host's daemon].
    #[arg(long, value_name = "ADDRESS", conflicts_with = "socket_dir")]
    from: Option<frond_sdk::Source>,
    /// Animation name [default: the output file's stem].
    #[arg(long, value_name = "NAME")]
    name: Option<String>,
    /// Capture every pose from now until Ctrl-C, not only a recording.
    #[arg(long)]
    all: bool,
    /// Bake every plant of the running field (`frond field start`), not the poses: each plant
    /// evaluated from the field's frames as the daemon's own field code does. With several
    /// fields running, NAME (the field's stage name, `frond field start --name`) picks one.
    #[arg(long, value_name = "NAME", num_args = 0..=1, default_missing_value = "")]
    field: Option<String>,
    /// Rig: an embedded rig name (grass, flower, shrub) or a rig file. With --field: the field's
    /// rig by default (an embedded rig of the name the field gives); a rig given must have that
    /// name (a field of a rig file needs the file here).
    #[arg(long, value_name = "RIG", required_unless_present = "field")]
    rig: Option<String>,
    #[command(flatten)]
    common: Common,
}

fn main() -> ExitCode {
    if let Some(code) = frond_binmain::DocsArgs::early("frond-gltf", Cli::command) {
        return code;
    }
    let cli: Cli = match frond_binmain::parse("frond-gltf") {
        Ok(cli) => cli,
        Err(code) => return code,
    };
    if let Err(code) = cli.log.init("frond-gltf") {
        return code;
    }
    let result = match cli.command {
        Command::Bake(a) => bake(a),
        Command::Live(a) => live(a),
    };
    // An option out of range (`BakeError::Option`, found once the inputs are known) is a usage
    // error like clap's own; a take or file that cannot be used is a failure.
    frond_binmain::exit_with("frond-gltf", result, |c| {
        matches!(c.downcast_ref(), Some(frond_gltf::BakeError::Option { .. }))
    })
}

fn options(c: &Common) -> anyhow::Result<(BakeOptions, Format)> {
    if let Err(reason) = frond_gltf::anim::check_fps(c.fps) {
        return Err(frond_binmain::usage(format!("--fps {reason}")));
    }
    let format = if c.gltf { Format::Gltf } else { Format::Glb };
    Ok((BakeOptions { fps: c.fps, seed: c.seed, force: c.force }, format))
}

fn progress_bar(quiet: bool) -> ProgressBar {
    if quiet {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(0);
    if let Ok(style) = ProgressStyle::with_template("{msg} [{bar:40}] {percent:>3}% {elapsed}/{eta}") {
        bar.set_style(style.progress_chars("=> "));
    }
    bar
}

fn bake(a: BakeArgs) -> anyhow::Result<()> {
    let (opts, format) = options(&a.common)?;
    let rig = LoadedRig::resolve(&a.rig)?;
    let takes_dir = frond_protocol::paths::takes_dir(a.takes_dir.clone());
    if a.field.is_some() && a.take.len() > 1 {
        return Err(frond_binmain::usage(format!(
            "--field bakes one take on every plant of the field, got {} takes",
            a.take.len()
        )));
    }
    if a.spacing.is_some() && a.take.len() < 2 {
        return Err(frond_binmain::usage("--spacing places the plants of a grove: give two or more takes"));
    }
    if a.take.len() > frond_gltf::grove::MAX_GROVE_PLANTS {
        return Err(frond_binmain::usage(format!(
            "a grove has at most {} takes, got {}",
            frond_gltf::grove::MAX_GROVE_PLANTS,
            a.take.len()
        )));
    }
    let takes = a.take.iter().map(|t| TakeInput::resolve(t, &takes_dir)).collect::<Result<Vec<_>, _>>()?;
    let field = a.field.as_deref().map(Field::read).transpose()?;
    let model = rig.model()?;
    let bar = progress_bar(a.common.quiet);
    bar.set_message(match takes.len() {
        1 => format!("baking {}", takes[0].name),
        n => format!("baking a grove of {n} takes"),
    });
    let mut progress = |done: u64, total: u64| {
        bar.set_length(total);
        bar.set_position(done);
    };
    let mut baker = Baker::new();
    let baked = match (&field, a.duration, takes.as_slice()) {
        (Some(field), Some(duration), [take]) => {
            baker.bake_field(&rig, &model, take, field, duration, &opts, &mut progress)?
        }
        (_, _, [take]) => baker.bake_take(&rig, &model, take, &opts, &mut progress)?,
        _ => {
            let spacing = a.spacing.unwrap_or_else(|| frond_gltf::grove::default_spacing_m(&rig));
            let name = a.common.output.file_stem().and_then(|s| s.to_str()).unwrap_or("grove");
            baker.bake_grove(&rig, &model, &takes, spacing, name, &opts, &mut progress)?
        }
    };
    bar.finish_and_clear();
    finish(baked, &a.common.output, format, a.common.quiet)
}

fn finish(mut baked: Baked, path: &Path, format: Format, quiet: bool) -> anyhow::Result<()> {
    for note in &baked.notes {
        // Notes quote names from the take and field files: escaped (`printable`) again here,
        // whatever made them.
        frond_binmain::errln!("frond-gltf: note: {}", frond_protocol::printable(note));
    }
    output::write(&mut baked, path, format)?;
    if !quiet {
        let s = baked.stats;
        frond_binmain::errln!(
            "frond-gltf: wrote {} ({} plant{}, {} channels x {} keys, {} vertices)",
            path.display(),
            s.plants,
            if s.plants == 1 { "" } else { "s" },
            s.channels,
            s.keys,
            s.vertices
        );
    }
    frond_binmain::outln!("{}", path.display())?;
    Ok(())
}

/// What `live` and `live --field` share: the options, the destination checked, Ctrl-C and
/// SIGTERM turned into a stop flag, the source.
fn live_setup(a: &LiveArgs) -> anyhow::Result<(BakeOptions, Format, Arc<AtomicBool>, frond_sdk::Source)> {
    let (opts, format) = options(&a.common)?;
    // Refuse an unwritable destination before the performance, not after it.
    if let Err(e) = frond_formats::rig_files::output_destination(&a.common.output) {
        bail!("cannot write {}: {e}", a.common.output.display());
    }
    let stop = Arc::new(AtomicBool::new(false));
    for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register(sig, Arc::clone(&stop)).context("installing the signal handler")?;
    }
    let source = match &a.from {
        Some(source) => source.clone(),
        None => frond_sdk::Source::Socket(frond_protocol::paths::socket_dir(a.socket_dir.clone())),
    };
    Ok((opts, format, stop, source))
}

fn live(a: LiveArgs) -> anyhow::Result<()> {
    if a.field.is_some() {
        return live_field(a);
    }
    let rig = LoadedRig::resolve(a.rig.as_deref().unwrap_or_default())?;
    let model = rig.model()?;
    let (opts, format, stop, source) = live_setup(&a)?;
    let quiet = a.common.quiet;
    let mut status = |line: &str| {
        if !quiet {
            frond_binmain::errln!("frond-gltf: {line}");
        }
    };
    let mode = if a.all { LiveMode::All } else { LiveMode::Recording };
    let (cap, hello) =
        capture(&source, mode, &stop, &mut status).with_context(|| format!("live capture from {source}"))?;
    if cap.missing > 0 {
        frond_binmain::errln!(
            "frond-gltf: note: the daemon dropped {} frames for this subscriber during the capture",
            cap.missing
        );
    }
    let name = a.name.clone().unwrap_or_else(|| {
        a.common.output.file_stem().and_then(|s| s.to_str()).unwrap_or("live").to_string()
    });
    let take = cap.into_take(&name, &hello);
    let baked = Baker::new().bake_take(&rig, &model, &take, &opts, &mut |_, _| {})?;
    finish(baked, &a.common.output, format, quiet)
}

/// `live --field`: the running field's frames captured, then every plant baked.
fn live_field(a: LiveArgs) -> anyhow::Result<()> {
    let given = a.rig.as_deref().map(LoadedRig::resolve).transpose()?;
    let (opts, format, stop, source) = live_setup(&a)?;
    let quiet = a.common.quiet;
    let mut status = |line: &str| {
        if !quiet {
            frond_binmain::errln!("frond-gltf: {line}");
        }
    };
    let name = a.field.as_deref().filter(|n| !n.is_empty());
    let mode = if a.all { LiveMode::All } else { LiveMode::Recording };
    // The field's rig, settled as soon as the field is picked (before the performance): the
    // rig given, which must be the one the field names, or the embedded rig of that name.
    let mut rig: Option<LoadedRig> = None;
    let mut accept = |d: &frond_protocol::field::FieldDefinition| -> Result<(), String> {
        let field = frond_protocol::printable(&d.source);
        let chosen = match &given {
            Some(r) if r.rig.name == d.rig => r.clone(),
            Some(r) => {
                return Err(format!(
                    "field `{field}`'s plants are rig `{}`; --rig gave rig `{}` ({}): give the field's rig, or leave \
                     --rig out to use the embedded rig of its name",
                    frond_protocol::printable(&d.rig),
                    frond_protocol::printable(&r.rig.name),
                    r.origin
                ));
            }
            None => LoadedRig::recorded(&d.rig).map_err(|e| {
                format!(
                    "field `{field}`'s rig: {e} (give the rig file the field was started with: --rig FILE)"
                )
            })?,
        };
        rig = Some(chosen);
        Ok(())
    };
    let cap =
        frond_gltf::live_field::capture_field(&source, mode, name, &stop, &opts, &mut accept, &mut status)
            .with_context(|| format!("live capture from {source}"))?;
    let rig = rig.context("the field's rig was not settled")?;
    let model = rig.model()?;
    let anim_name = a.name.clone().unwrap_or_else(|| {
        a.common.output.file_stem().and_then(|s| s.to_str()).unwrap_or("live").to_string()
    });
    let bar = progress_bar(quiet);
    bar.set_message(format!(
        "baking {} plants of field `{}`",
        cap.definition().plants,
        frond_protocol::printable(&cap.definition().source)
    ));
    let mut progress = |done: u64, total: u64| {
        bar.set_length(total);
        bar.set_position(done);
    };
    let baked = match Baker::new().bake_live_field(&rig, &model, &cap, &anim_name, &opts, &mut progress) {
        // The performance cannot be captured again: baked whole at the highest rate that fits
        // rather than lost.
        Err(frond_gltf::BakeError::LiveFieldTooLong(t)) => {
            let Some(fps) = t.fitting_fps() else {
                return Err(frond_gltf::BakeError::LiveFieldTooLong(t).into());
            };
            bar.suspend(|| status(&format!("warning: {t}; baking the whole capture at {fps} FPS instead")));
            let lower = BakeOptions { fps, ..opts };
            Baker::new().bake_live_field(&rig, &model, &cap, &anim_name, &lower, &mut progress)?
        }
        r => r?,
    };
    bar.finish_and_clear();
    finish(baked, &a.common.output, format, quiet)
}
