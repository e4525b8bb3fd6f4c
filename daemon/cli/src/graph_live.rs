//! Seed 003 live in the daemon: `frond graph play|goal|stop`, plants walking a motion graph
//! (section 6), directed live (the graph is `NAME.graph.json` in the takes directory, where
//! `frond take graph` writes it, read by the daemon); and `frond sim start|stop`, the simulated
//! plant (section 4) blown by the hand.

use clap::Subcommand;
use frond_motion::graph::{PoseGoalError, PoseGoalSpec};
use frond_protocol::{
    ControlReply, ControlRequest, GraphGoal, GraphSource, MAX_GRAPH_SOURCES, StageInput, StageSpec,
};

use crate::control::Control;
use crate::global::Global;

/// The stage's name.
const STAGE: &str = "graph";

/// `frond graph ...`
#[derive(Debug, Subcommand)]
pub enum GraphCommand {
    /// N plants walk the graphs of the takes live, each an announced element (`walker0`..);
    /// plant i walks take i mod count (section 6.1 instancing: each take its own graph and
    /// control point).
    Play {
        /// Take names (in the takes directory), at most 8.
        #[arg(required = true, num_args = 1..)]
        takes: Vec<String>,
        /// Graphs, one per take in order: a NAME (NAME.graph.json in the takes directory) or
        /// the path of a graph file in that directory (the daemon reads only its own takes
        /// directory) [default: each take's own, TAKE.graph.json].
        #[arg(long, value_name = "NAME|FILE")]
        graph: Vec<String>,
        /// Plants walking (1..=64).
        #[arg(long, default_value_t = 8, value_name = "N")]
        plants: u16,
        /// Seed of the first plant's walk (plant i gets seed + i).
        #[arg(long, default_value_t = 1, value_name = "S")]
        seed: u64,
    },
    /// Direct the walk: `dir DEG` (0 towards +X, 90 towards +Z), `hand` (the hand's bend
    /// direction, live), `pose frame=N` (the pose of take frame N) or `pose A,B,...` (12 angles,
    /// degrees: pitch, yaw, roll of joints 0..3; the nearest node, by the shortest path) or `off`
    /// (random walks).
    Goal {
        /// dir, hand, pose or off.
        kind: String,
        /// The direction in degrees (dir); frame=N or 12 comma-separated angles (pose).
        #[arg(allow_hyphen_values = true)]
        value: Option<String>,
    },
    /// Stop the walk.
    Stop,
}

/// `frond sim ...`
#[derive(Debug, Subcommand)]
pub enum SimCommand {
    /// Run the simulated plant in the loop as the global element; the hand's bend blows it
    /// (direction of the bend, 0.2 m/s per degree, at most 12 m/s; under 5 degrees: --wind).
    Start {
        /// Rig: an embedded name or a rig file [default: the active rig].
        #[arg(long, value_name = "NAME|FILE")]
        rig: Option<std::path::PathBuf>,
        /// The wind while the hand does not blow: `speed=S,dir=DEG,gust=G,seed=N`.
        #[arg(long, default_value = "speed=0,dir=0,gust=0,seed=1", value_name = "SPEC")]
        wind: String,
    },
    /// Stop the simulation.
    Stop,
}

/// Runs one `frond sim` command.
pub(crate) fn sim(g: &Global, cmd: SimCommand) -> anyhow::Result<()> {
    match cmd {
        SimCommand::Start { rig, wind } => {
            if let Err(e) = wind.parse::<frond_motion::sim::WindSpec>() {
                return crate::error::usage(format!("--wind {wind:?}: {e}"));
            }
            let rig_toml = match &rig {
                Some(spec) => Some(crate::control::load_rig(spec)?.1),
                None => None,
            };
            let mut c = Control::from_global(g)?;
            c.expect_ok(&ControlRequest::StageStart { name: None, spec: StageSpec::Sim { rig_toml, wind } })?;
            frond_binmain::outln!("simulated plant running as the global element; bend the hand to blow it")?;
            Ok(())
        }
        SimCommand::Stop => {
            Control::from_global(g)?.expect_ok(&ControlRequest::StageStop { name: "sim".into() })?;
            frond_binmain::outln!("simulation stopped")?;
            Ok(())
        }
    }
}

/// What is wrong with `frond graph goal KIND [VALUE]` ([`parse_goal`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub(crate) enum GoalError {
    /// `dir` with a value that is not a finite angle within +-360 degrees.
    #[error("goal dir {0:?}: expected an angle in degrees within +-360")]
    Angle(String),
    /// `pose` with a value that is neither `frame=N` nor 12 angles: the parser's reason.
    #[error("goal pose {0}")]
    Pose(PoseGoalError),
    /// `off` or `hand` given a value.
    #[error("goal {kind} takes no value, got {value:?}")]
    NoValueTaken {
        /// The goal kind.
        kind: String,
        /// The value given.
        value: String,
    },
    /// `dir` or `pose` without a value.
    #[error("goal {0} needs a value (dir DEG, pose frame=N|12 angles)")]
    ValueNeeded(String),
    /// A kind that is none of the goals.
    #[error("unknown goal {0:?}: expected dir DEG, hand, pose frame=N|12 angles, or off")]
    Unknown(String),
}

/// Parses `frond graph goal KIND [VALUE]`.
pub(crate) fn parse_goal(kind: &str, value: Option<&str>) -> Result<GraphGoal, GoalError> {
    match (kind, value) {
        ("off", None) => Ok(GraphGoal::Off),
        ("hand", None) => Ok(GraphGoal::Hand),
        ("dir", Some(v)) => match v.trim().parse::<f64>() {
            Ok(deg) if deg.is_finite() && deg.abs() <= 360.0 => Ok(GraphGoal::Dir { deg }),
            _ => Err(GoalError::Angle(v.to_string())),
        },
        ("pose", Some(v)) => match v.parse::<PoseGoalSpec>() {
            Ok(PoseGoalSpec::Frame(frame)) => Ok(GraphGoal::Frame { frame }),
            Ok(PoseGoalSpec::Angles(joints_deg)) => Ok(GraphGoal::Pose { joints_deg }),
            Err(e) => Err(GoalError::Pose(e)),
        },
        ("off" | "hand", Some(v)) => {
            Err(GoalError::NoValueTaken { kind: kind.to_string(), value: v.to_string() })
        }
        ("dir" | "pose", None) => Err(GoalError::ValueNeeded(kind.to_string())),
        (other, _) => Err(GoalError::Unknown(other.to_string())),
    }
}

/// Why a `--graph` argument names no graph the daemon can read ([`graph_name`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
enum GraphFileError {
    /// The path cannot be resolved (it does not exist, or a directory on it cannot be read):
    /// the system's reason, as text so that the error compares.
    #[error("cannot open the graph file: {0}")]
    Open(String),
    /// The path is a directory or another non-file.
    #[error("not a regular file")]
    NotAFile,
    /// The file's name does not end in `.graph.json` after a name.
    #[error("a graph file is named NAME{GRAPH_SUFFIX} (as `frond take graph` writes it)")]
    Named,
    /// The file lies outside the takes directory the daemon reads graphs from.
    #[error(
        "the daemon reads graphs only from its takes directory {}: build the graph there \
         (`frond take graph TAKE`, the default) or copy the file into it",
        takes_dir.display()
    )]
    OutsideTakesDir {
        /// The takes directory.
        takes_dir: std::path::PathBuf,
    },
}

/// How a graph file's name ends.
const GRAPH_SUFFIX: &str = ".graph.json";

/// The graph name of a `--graph` argument: a NAME as it is, or a path (holding `/` or ending in
/// `.graph.json`) to a graph file that lies in `takes_dir`, whose name it then gives.
fn graph_name(arg: &str, takes_dir: &std::path::Path) -> Result<String, GraphFileError> {
    if !arg.contains('/') && !arg.ends_with(GRAPH_SUFFIX) {
        return Ok(arg.to_string());
    }
    let path = std::path::Path::new(arg);
    let file = std::fs::canonicalize(path).map_err(|e| GraphFileError::Open(e.to_string()))?;
    if !file.is_file() {
        return Err(GraphFileError::NotAFile);
    }
    let name = file
        .file_name()
        .and_then(|n| n.to_str())
        .and_then(|n| n.strip_suffix(GRAPH_SUFFIX))
        .filter(|n| !n.is_empty())
        .ok_or(GraphFileError::Named)?;
    let in_takes_dir = std::fs::canonicalize(takes_dir).is_ok_and(|d| file.parent() == Some(d.as_path()));
    if !in_takes_dir {
        return Err(GraphFileError::OutsideTakesDir { takes_dir: takes_dir.to_path_buf() });
    }
    Ok(name.to_string())
}

/// Runs one `frond graph` command.
pub(crate) fn run(g: &Global, cmd: GraphCommand) -> anyhow::Result<()> {
    match cmd {
        GraphCommand::Play { takes, graph, plants, seed } => {
            if !(1..=64).contains(&plants) {
                return crate::error::usage(format!("--plants must be 1..=64, got {plants}"));
            }
            let max = MAX_GRAPH_SOURCES.min(usize::from(plants));
            if takes.len() > max {
                return crate::error::usage(format!(
                    "{plants} plants walk at most {max} takes, got {}",
                    takes.len()
                ));
            }
            if !graph.is_empty() && graph.len() != takes.len() {
                return crate::error::usage(format!(
                    "give one --graph per take ({} takes, {} graphs), or none for each take's own",
                    takes.len(),
                    graph.len()
                ));
            }
            let takes_dir = frond_protocol::paths::takes_dir(g.takes_dir.clone());
            let mut sources = Vec::with_capacity(takes.len());
            for (i, take) in takes.iter().enumerate() {
                let graph = match graph.get(i) {
                    Some(arg) => match graph_name(arg, &takes_dir) {
                        Ok(name) => name,
                        Err(e) => return crate::error::usage(format!("--graph {arg:?}: {e}")),
                    },
                    None => take.clone(),
                };
                for (what, name) in [("take", take), ("--graph", &graph)] {
                    if let Err(e) = frond_protocol::paths::validate_take_name(name) {
                        return crate::error::usage(format!("{what}: {e}"));
                    }
                }
                sources.push(GraphSource { take: take.clone(), graph });
            }
            let sources_names: Vec<String> = sources.iter().map(|s| s.graph.clone()).collect();
            let mut c = Control::from_global(g)?;
            let spec = StageSpec::Graph { sources, plants, seed };
            c.expect_ok(&ControlRequest::StageStart { name: None, spec }).map_err(|e| {
                // The daemon names the graph it could not read; say how to make one.
                let text = format!("{e:#}");
                match sources_missing_graph(&text, &sources_names) {
                    Some(graph) => e.context(format!(
                        "graph {graph:?} does not exist: make it with `frond take graph {graph} --control top`"
                    )),
                    None => e,
                }
            })?;
            frond_binmain::outln!(
                "{plants} plants walking the graph{} of {}; direct them with `frond graph goal`",
                if takes.len() == 1 { "" } else { "s" },
                takes.join(", ")
            )?;
            Ok(())
        }
        GraphCommand::Goal { kind, value } => {
            let goal = match parse_goal(&kind, value.as_deref()) {
                Ok(goal) => goal,
                Err(e) => return crate::error::usage(e.to_string()),
            };
            let mut c = Control::from_global(g)?;
            c.expect_ok(&ControlRequest::StageInput {
                name: STAGE.into(),
                input: StageInput::GraphGoal(goal),
            })?;
            if let ControlReply::Status(s) = c.request(&ControlRequest::Status)? {
                for m in s.modes.iter().filter(|m| m.contains("graph walk")) {
                    frond_binmain::outln!("{m}")?;
                }
            }
            Ok(())
        }
        GraphCommand::Stop => {
            Control::from_global(g)?.expect_ok(&ControlRequest::StageStop { name: STAGE.into() })?;
            frond_binmain::outln!("graph walk stopped")?;
            Ok(())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn graph_arguments_are_names_or_files_in_the_takes_directory() {
        let takes = tempfile::tempdir().unwrap();
        let elsewhere = tempfile::tempdir().unwrap();
        for dir in [takes.path(), elsewhere.path()] {
            std::fs::write(dir.join("breeze.graph.json"), "{}").unwrap();
            std::fs::write(dir.join("breeze.json"), "{}").unwrap();
        }
        assert_eq!(graph_name("breeze", takes.path()), Ok("breeze".into()));
        let inside = takes.path().join("breeze.graph.json");
        assert_eq!(graph_name(inside.to_str().unwrap(), takes.path()), Ok("breeze".into()));
        let outside = elsewhere.path().join("breeze.graph.json");
        let e = graph_name(outside.to_str().unwrap(), takes.path()).unwrap_err().to_string();
        assert!(e.contains("only from its takes directory"), "{e}");
        let e = graph_name(takes.path().join("breeze.json").to_str().unwrap(), takes.path())
            .unwrap_err()
            .to_string();
        assert!(e.contains("NAME.graph.json"), "{e}");
        let e = graph_name(takes.path().join("gone.graph.json").to_str().unwrap(), takes.path())
            .unwrap_err()
            .to_string();
        assert!(e.contains("cannot open"), "{e}");
        let e = graph_name(takes.path().to_str().unwrap(), takes.path()).unwrap_err().to_string();
        assert!(e.contains("not a regular file"), "{e}");
    }

    #[test]
    fn goals_parse_and_bad_ones_say_why() {
        assert_eq!(parse_goal("dir", Some("-45")), Ok(GraphGoal::Dir { deg: -45.0 }));
        assert_eq!(parse_goal("pose", Some("frame=12")), Ok(GraphGoal::Frame { frame: 12 }));
        assert_eq!(parse_goal("hand", None), Ok(GraphGoal::Hand));
        assert_eq!(parse_goal("off", None), Ok(GraphGoal::Off));
        assert!(parse_goal("dir", Some("nan")).unwrap_err().to_string().contains("angle"));
        assert!(parse_goal("dir", None).unwrap_err().to_string().contains("needs a value"));
        assert!(
            parse_goal("pose", Some("1,2,3")).unwrap_err().to_string().contains("12 finite angles"),
            "{:?}",
            parse_goal("pose", Some("1,2,3"))
        );
        assert!(
            parse_goal("pose", Some("frame=x"))
                .unwrap_err()
                .to_string()
                .contains("frame=N needs a frame number")
        );
        let twelve = "1,2,3,4,5,6,7,8,9,10,11,-12";
        let want = [[1.0, 2.0, 3.0], [4.0, 5.0, 6.0], [7.0, 8.0, 9.0], [10.0, 11.0, -12.0]];
        assert_eq!(parse_goal("pose", Some(twelve)), Ok(GraphGoal::Pose { joints_deg: want }));
        assert!(
            parse_goal("pose", Some(&format!("{twelve},1"))).unwrap_err().to_string().contains("or more")
        );
        assert!(parse_goal("north", None).unwrap_err().to_string().contains("unknown goal"));
        assert!(parse_goal("off", Some("1")).unwrap_err().to_string().contains("takes no value"));
    }
}

/// The graph a daemon's refusal says it could not find (`cannot read graph "NAME" at PATH: No
/// such file...`), among `graphs`.
fn sources_missing_graph<'a>(text: &str, graphs: &'a [String]) -> Option<&'a str> {
    if !(text.contains("cannot read graph") && text.contains("No such file")) {
        return None;
    }
    graphs.iter().find(|g| text.contains(&format!("graph {g:?}"))).map(String::as_str)
}

#[cfg(test)]
mod missing_graph_tests {
    #[test]
    fn the_daemons_missing_graph_is_named() {
        let graphs = vec!["breeze".to_string(), "gale".to_string()];
        let text = "invalid: cannot read graph \"gale\" at /t/gale.graph.json: No such file or directory (os error 2)";
        assert_eq!(super::sources_missing_graph(text, &graphs), Some("gale"));
        assert_eq!(super::sources_missing_graph("invalid: graph \"gale\" is too large", &graphs), None);
    }
}
