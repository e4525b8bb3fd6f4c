//! `frond-warp`: thin entry point; everything lives in the `frond_warp` library.

use std::process::ExitCode;

use anyhow::Context;
use clap::CommandFactory;
use frond_warp::cli::{BenchArgs, CageCommand, Cli, Command, MorphArgs, RenderArgs, SceneArgs, ServeArgs};
use frond_warp::params::Checker;
use frond_warp::render::{OutputKind, PoseTrack, WindDriver};
use frond_warp::{Animator, Scene};

fn main() -> ExitCode {
    if let Some(code) = frond_binmain::DocsArgs::early("frond-warp", Cli::command) {
        return code;
    }
    let cli: Cli = match frond_binmain::parse("frond-warp") {
        Ok(cli) => cli,
        Err(code) => return code,
    };
    if let Err(code) = cli.log.init("frond-warp") {
        return code;
    }
    let result = match cli.command {
        Command::Render(args) => render(args),
        Command::Serve(args) => serve(args),
        Command::MakeSamples { dir } => make_samples(&dir),
        Command::Bench(args) => bench(args),
        Command::Cage(cmd) => cage(cmd),
        Command::Morph(args) => morph(args),
    };
    // Parameters out of range (the Checker's report, every problem at once) and a missing
    // --layer are usage errors; inputs that cannot be used (an unreadable image, a bad take or
    // sketch) and failures while running (a file that cannot be written) are not.
    frond_binmain::exit_with("frond-warp", result, |c| {
        c.downcast_ref::<frond_warp::params::InvalidParams>().is_some()
            || matches!(c.downcast_ref(), Some(frond_warp::layers::SceneError::NoLayers))
    })
}

/// `--frames` in `1..=max_frames`, `--fps` in 1..=240 and the output's kind, each problem into
/// `ck`: the checks every rendering command starts with.
fn check_frames_and_output(
    ck: &mut Checker,
    frames: i64,
    max_frames: i64,
    fps: f32,
    output: &std::path::Path,
) -> Result<OutputKind, frond_warp::render::RenderError> {
    ck.range_i64("--frames", frames, 1, max_frames);
    ck.range_f32("--fps", fps, 1.0, 240.0);
    let out = OutputKind::from_path(output);
    if let Err(e) = &out {
        ck.push("--output", output.display(), e);
    }
    out
}

/// Where `--take ARG` points ([`frond_protocol::paths::take_file`]: a path, or a name in the
/// takes directory), or its problem recorded in `ck`.
fn take_file(
    ck: &mut Checker,
    arg: Option<&str>,
    takes_dir: Option<&std::path::Path>,
) -> Option<std::path::PathBuf> {
    let arg = arg?;
    let dir = frond_protocol::paths::takes_dir(takes_dir.map(std::path::Path::to_path_buf));
    frond_protocol::paths::take_file(arg, &dir).map_err(|e| ck.push("--take", arg, e)).ok()
}

/// Reads a take's poses; a damaged take is read as far as it can be, with a warning ending
/// "`using` its N readable frames".
fn read_take(path: &std::path::Path, using: &str) -> anyhow::Result<PoseTrack> {
    let track = PoseTrack::from_take(path)?;
    if let Some(damage) = &track.damage {
        frond_binmain::errln!(
            "frond-warp: warning: take {}: {damage}; {using} its {} readable frames",
            path.display(),
            track.times_s.len()
        );
    }
    Ok(track)
}

fn load_scene(args: &SceneArgs) -> anyhow::Result<Scene> {
    Ok(Scene::load(&args.image, &args.layers, args.background.as_deref(), args.scale_map.as_deref())?)
}

fn render(args: RenderArgs) -> anyhow::Result<()> {
    if args.mode == frond_warp::cli::RenderMode::Cage {
        return render_cage(args);
    }
    // Every argument problem at once: output kind, frames, fps and the simulation parameters.
    let mut ck = Checker::new();
    let out = check_frames_and_output(&mut ck, args.frames, 100_000, args.fps, &args.output);
    let take = take_file(&mut ck, args.take.as_deref(), args.takes_dir.as_deref());
    let sim_wind = frond_warp::cli::sim_wind(args.wind_sim.as_deref(), &mut ck);
    let params = args.sim.to_params(args.scene.layers.len());
    let mut problems = ck.finish().err().map(|e| e.0).unwrap_or_default();
    if let Err(e) = &params {
        problems.extend(e.0.iter().cloned());
    }
    if !problems.is_empty() {
        return Err(frond_warp::InvalidParams(problems).into());
    }
    let (out, params) = (out?, params?);
    // Where the frames go, refused before anything is rendered (a FIFO, a device, a missing
    // directory), not after.
    out.check_destination()?;
    let scene = load_scene(&args.scene)?;
    let track = take.as_deref().map(|p| read_take(p, "the wind follows")).transpose()?;
    let mut animator = Animator::new(scene, params)?;
    let driver = match (&track, &sim_wind) {
        (Some(t), _) => WindDriver::Take(t),
        (None, Some(w)) => WindDriver::Sim(w),
        (None, None) => WindDriver::Procedural,
    };
    let n =
        frond_warp::render::render(&mut animator, driver, args.frames as usize, args.fps, &out, args.quiet)?;
    if !args.quiet {
        frond_binmain::errln!(
            "frond-warp: wrote {n} frames to {} (wind: {})",
            args.output.display(),
            match driver {
                WindDriver::Take(_) => "take".to_string(),
                WindDriver::Sim(w) => format!("simulation {}", w.spec()),
                WindDriver::Procedural => "procedural".to_string(),
            }
        );
    }
    Ok(())
}

fn serve(args: ServeArgs) -> anyhow::Result<()> {
    if args.mode == frond_warp::cli::RenderMode::Cage {
        return serve_cage(args);
    }
    let mut ck = Checker::new();
    for (flag, given) in [
        ("--cage", args.cage.cage.is_some()),
        ("--anchor", args.cage.anchor.is_some()),
        ("--rig", args.cage.rig.is_some()),
        ("--no-adapt", args.no_adapt),
        ("--no-prune", args.no_prune),
    ] {
        if given {
            ck.push(flag, "given", "only the cage mode uses it: add --mode cage or drop it");
        }
    }
    let sim_wind = frond_warp::cli::sim_wind(args.wind_sim.as_deref(), &mut ck);
    ck.finish()?;
    let params = args.sim.to_params(args.scene.layers.len())?;
    let scene = load_scene(&args.scene)?;
    let animator = Animator::new(scene, params)?;
    let source = args.pose_source();
    frond_warp::serve::serve(
        animator,
        frond_warp::serve::ServeOptions {
            listen: args.listen,
            source,
            no_daemon: args.no_daemon,
            sim_wind,
            token_file: args.token_file,
        },
    )
}

/// The checks both cage modes make (no wind, one layer, a readable anchor), into `ck`; the
/// anchor if one was given and it parses.
fn check_cage_mode(
    ck: &mut Checker,
    wind_sim: Option<&str>,
    layers: usize,
    cage: &frond_warp::cli::CageArgs,
) -> Option<Result<[f64; 2], frond_warp::cages::BadPoint>> {
    if let Some(spec) = wind_sim {
        ck.push("--wind-sim", spec, "the cage mode has no wind; drop it");
    }
    if layers != 1 {
        ck.push("--layer", layers, "the cage mode bends exactly one layer");
    }
    let anchor = cage.anchor.as_deref().map(frond_warp::cages::parse_point);
    if let Some(Err(e)) = &anchor {
        ck.push("--anchor", cage.anchor.as_deref().unwrap_or_default(), e);
    }
    anchor
}

/// `serve --mode cage`.
fn serve_cage(args: ServeArgs) -> anyhow::Result<()> {
    let mut ck = Checker::new();
    let anchor = check_cage_mode(&mut ck, args.wind_sim.as_deref(), args.scene.layers.len(), &args.cage);
    if !(args.morph_s > 0.0 && args.morph_s <= 60.0) {
        ck.push("--morph-s", args.morph_s, "out of range (allowed: above 0 to 60 seconds)");
    }
    ck.finish()?;
    let rig = match &args.cage.rig {
        Some(spec) => {
            let rig = frond_formats::rig_files::load_rig(spec).with_context(|| format!("rig {spec}"))?;
            Some((rig.rig.name.clone(), frond_motion::skeleton::Skeleton::from_rig(&rig.rig)))
        }
        None => None,
    };
    let scene = load_scene(&args.scene)?;
    let tree = frond_warp::morph::scene_tree(&scene, args.cage.cage.as_deref())?;
    let source = args.pose_source();
    frond_warp::serve_cage::serve_cage(
        scene,
        tree,
        frond_warp::serve_cage::CageServeOptions {
            listen: args.listen,
            source,
            no_daemon: args.no_daemon,
            anchor: anchor.transpose().map_err(anyhow::Error::msg)?,
            rig,
            morph_s: args.morph_s,
            opts: frond_cage::morph::MorphOptions { adapt: !args.no_adapt, prune: !args.no_prune },
            token_file: args.token_file,
        },
    )
}

/// `render --mode cage --take TAKE`.
fn render_cage(args: RenderArgs) -> anyhow::Result<()> {
    let mut ck = Checker::new();
    let out = check_frames_and_output(&mut ck, args.frames, 100_000, args.fps, &args.output);
    if args.take.is_none() {
        ck.push("--take", "(none)", "--mode cage needs a take: its poses bend the plant");
    }
    let take = take_file(&mut ck, args.take.as_deref(), args.takes_dir.as_deref());
    let anchor = check_cage_mode(&mut ck, args.wind_sim.as_deref(), args.scene.layers.len(), &args.cage);
    ck.finish()?;
    out.as_ref().map_or(Ok(()), |o| o.check_destination())?;
    let take = take.as_deref().expect("checked");
    let track = read_take(take, "using")?;
    // `--rig` (a name or a file, the operator's word), else the rig the take was recorded on:
    // an embedded rig only, as a name read from a take is never opened as a path.
    let rig = match (&args.cage.rig, track.rig_name.as_deref().filter(|n| !n.is_empty())) {
        (Some(spec), _) => {
            frond_formats::rig_files::load_rig(spec).with_context(|| format!("--rig {spec}"))?
        }
        (None, Some(name)) => frond_formats::rig_files::recorded_rig(name)
            .with_context(|| format!("the rig take {} was recorded on", take.display()))?,
        (None, None) => frond_formats::rig_files::recorded_rig("grass")?,
    };
    let scene = load_scene(&args.scene)?;
    let job = frond_warp::cage_skin::CageTakeJob {
        cage: args.cage.cage.clone(),
        anchor: anchor.transpose().map_err(anyhow::Error::msg)?,
        skeleton: frond_motion::skeleton::Skeleton::from_rig(&rig.rig),
        frames: args.frames as usize,
        fps: args.fps,
        output: out?,
        adapt: true,
        quiet: args.quiet,
    };
    let n = frond_warp::cage_skin::render_take(&scene, &track, &job)?;
    if !args.quiet {
        frond_binmain::errln!(
            "frond-warp: wrote {n} frames to {} (cage mode, rig {}, take {})",
            args.output.display(),
            frond_protocol::printable(&rig.rig.name),
            take.display()
        );
    }
    Ok(())
}

fn morph(a: MorphArgs) -> anyhow::Result<()> {
    let mut ck = Checker::new();
    let out = check_frames_and_output(&mut ck, a.frames, 10_000, a.fps, &a.output);
    ck.finish()?;
    let out = out?;
    out.check_destination()?;
    if let Some(report) = &a.report
        && let Err(e) = frond_formats::rig_files::output_destination(report)
    {
        anyhow::bail!("cannot write {}: {e}", report.display());
    }
    let job = frond_warp::morph::MorphJob {
        image: a.image,
        layer: a.layer,
        background: a.background,
        cage: a.cage,
        sketch: a.sketch,
        frames: a.frames as usize,
        fps: a.fps,
        output: out,
        report: a.report.clone(),
        opts: frond_cage::morph::MorphOptions { adapt: !a.no_adapt, prune: !a.no_prune },
        quiet: a.quiet,
    };
    let summary = frond_warp::morph::run(&job)?;
    if let Some(path) = &a.report {
        frond_warp::cages::write_file(path, &summary.report_json())
            .with_context(|| format!("writing {}", path.display()))?;
    }
    if !a.quiet {
        let worst = summary.frechet_px.iter().copied().fold(0.0, f64::max);
        frond_binmain::errln!(
            "frond-warp: wrote {} frames to {} (crown {}, {} cages pruned, outline within {worst:.1} px of the reference)",
            summary.frames,
            a.output.display(),
            summary.crown,
            summary.pruned.len()
        );
    }
    Ok(())
}

fn cage(cmd: CageCommand) -> anyhow::Result<()> {
    use frond_warp::cages;
    match cmd {
        CageCommand::Build(a) => {
            let opts = frond_cage::BuildOptions {
                levels: a.levels,
                vertices: a.vertices,
                lobes: a.lobes,
                threshold: a.threshold,
                min_part_fraction: a.min_part,
            };
            let (tree, text) = cages::build_file(&a.layer, &opts)?;
            if a.output.as_os_str() == "-" {
                frond_binmain::out!("{text}")?;
            } else {
                cages::write_file(&a.output, &text)
                    .with_context(|| format!("writing {}", a.output.display()))?;
                let leaves = tree.cages.iter().filter(|c| c.kind == frond_cage::CageKind::Leaf).count();
                frond_binmain::errln!(
                    "frond-warp: wrote {} cages ({} crowns, {leaves} leaves, {} levels deep) to {}",
                    tree.cages.len(),
                    tree.roots().count(),
                    (0..tree.cages.len()).map(|i| tree.depth(i) + 1).max().unwrap_or(0),
                    a.output.display()
                );
            }
        }
        CageCommand::Coords(a) => {
            let tree = cages::read_cage_file(&a.cage)?;
            frond_binmain::outln!("{}", cages::coords_json(&tree, a.id, &a.at)?)?;
        }
    }
    Ok(())
}

fn make_samples(dir: &std::path::Path) -> anyhow::Result<()> {
    let names = frond_warp::samples::write_samples(dir)
        .with_context(|| format!("writing samples to {}", dir.display()))?;
    for n in names {
        frond_binmain::outln!("{}", dir.join(n).display())?;
    }
    Ok(())
}

fn bench(args: BenchArgs) -> anyhow::Result<()> {
    if cfg!(debug_assertions) {
        frond_binmain::errln!(
            "frond-warp: warning: debug build; build with --release for meaningful timings"
        );
    }
    let warp = frond_warp::bench::bench_warp(args.width, args.height, args.iterations);
    let kernels: Vec<_> = if args.all_kernels {
        frond_warp::warp::RemapKernel::available()
            .into_iter()
            .map(|k| frond_warp::bench::bench_warp_with(k, args.width, args.height, args.iterations))
            .collect()
    } else {
        Vec::new()
    };
    let pipeline: Vec<_> = if args.pipeline_frames > 0 {
        [(1280, 720), (1920, 1080)]
            .iter()
            .map(|&(w, h)| frond_warp::bench::bench_pipeline(w, h, args.pipeline_frames))
            .collect()
    } else {
        Vec::new()
    };
    let cage = (args.cage_frames > 0)
        .then(|| frond_warp::bench::bench_cage(args.width, args.height, args.cage_frames));
    if let Some(dir) = &args.write_field {
        frond_warp::bench::write_field(dir, args.width, args.height)
            .with_context(|| format!("writing the field to {}", dir.display()))?;
    }
    if args.json {
        let v = serde_json::json!({
            "warp": warp,
            "warp_kernels": kernels,
            "pipeline": pipeline,
            "cage": cage,
            "field_dir": args.write_field,
            "threads": 1,
            "release": !cfg!(debug_assertions),
        });
        frond_binmain::outln!("{v}")?;
    } else {
        print_bench(&warp, &kernels, &pipeline, cage.as_ref(), args.write_field.as_deref())?;
    }
    Ok(())
}

/// `frond-warp bench`'s results as text (without `--json`).
fn print_bench(
    warp: &frond_warp::bench::WarpBench,
    kernels: &[frond_warp::bench::WarpBench],
    pipeline: &[frond_warp::bench::PipelineBench],
    cage: Option<&frond_warp::bench::CageBench>,
    write_field: Option<&std::path::Path>,
) -> anyhow::Result<()> {
    frond_binmain::outln!(
        "warp {}x{} ({}): median {:.2} ms, min {:.2} ms, median thread CPU {:.2} ms ({:.0} Mpx/s, single \
         thread, {} iterations)",
        warp.width,
        warp.height,
        warp.kernel,
        warp.median_ms,
        warp.min_ms,
        warp.median_cpu_ms,
        warp.mpix_per_s,
        warp.iterations
    )?;
    for k in kernels {
        frond_binmain::outln!(
            "  kernel {}: median {:.2} ms, min {:.2} ms, median thread CPU {:.2} ms",
            k.kernel,
            k.median_ms,
            k.min_ms,
            k.median_cpu_ms
        )?;
    }
    for p in pipeline {
        frond_binmain::outln!(
            "pipeline {}x{}: {:.1} frames/s ({} frames)",
            p.width,
            p.height,
            p.fps,
            p.frames
        )?;
    }
    if let Some(c) = cage {
        frond_binmain::outln!(
            "cage morph {}x{} ({} cages of {} vertices): frame {:.2} ms (tree {:.2}, field {:.2}, layer {:.2}, \
             warp {:.2}) against the plain remap's {:.2} ms: {:.2}x",
            c.width,
            c.height,
            c.cages,
            c.vertices,
            c.frame_ms,
            c.tree_update_ms,
            c.field_ms,
            c.layer_ms,
            c.warp_ms,
            c.remap_ms,
            c.frame_ms / c.remap_ms
        )?;
    }
    if let Some(dir) = write_field {
        frond_binmain::outln!(
            "field written to {} (python3 exporters/warp/bench/remap.py {})",
            dir.display(),
            dir.display()
        )?;
    }
    Ok(())
}
