//! `frond tap --from 'zenoh:frond/<stage>/*'`: every source a selector matches, in one stream
//! (issue 20, "a selector over several sources"). Each line is what `frond tap` prints for one
//! source, tagged with the source (`<stage>/<source>`): a `"source"` key first in JSON Lines, a
//! `stage1/glove-a: ` prefix in readable lines. Sources whose bridges join later are followed
//! from when they join; gaps, disconnects and reconnects are reported per source on stderr.

use std::collections::HashMap;
use std::time::{Duration, Instant};

use frond_protocol::{ElementId, ElementTable, PoseFlags};
use frond_sdk::zenoh_many::{StageEvent, StageSubscriber};
use frond_sdk::{Event, Subscriber, ZenohAddr};

use crate::tap::{Printer, pick_element};

/// How long to wait for the first source before saying none answers.
const FIRST_SOURCE_WAIT: Duration = Duration::from_secs(10);

/// What is known of one followed source.
struct Followed {
    names: Vec<String>,
    table: ElementTable,
    /// `--element` resolved in this source's table (`None`: every element).
    only: Option<ElementId>,
}

pub(crate) fn run(
    addr: &ZenohAddr,
    jsonl: bool,
    count: Option<u64>,
    include_held: bool,
    element: Option<&str>,
) -> anyhow::Result<()> {
    if count == Some(0) {
        return Ok(());
    }
    let stage = StageSubscriber::open(addr, Subscriber::options())?;
    let mut followed: HashMap<String, Followed> = HashMap::new();
    let started = Instant::now();
    let mut printer = Printer::new(jsonl, count);
    let mut printed = false;
    loop {
        let wait = if followed.is_empty() && !printed {
            let left = FIRST_SOURCE_WAIT.saturating_sub(started.elapsed());
            if left.is_zero() {
                anyhow::bail!("no frond-zenoh bridge answers {} within {FIRST_SOURCE_WAIT:?}", addr);
            }
            Some(left)
        } else {
            None
        };
        let Some(ev) = stage.next_event(wait)? else { continue };
        match ev {
            StageEvent::Joined { source, hello } => {
                let only = pick_element(element, &hello.elements).unwrap_or_else(|why| {
                    frond_binmain::errln!("frond tap: {source}: {why}; its poses are left out");
                    Some(ElementId::MAX)
                });
                frond_binmain::errln!(
                    "frond tap: following {source} (daemon {}, rig {})",
                    frond_protocol::printable(&hello.daemon_version),
                    frond_protocol::printable(&hello.rig_name)
                );
                followed.insert(source, Followed { names: hello.joint_names, table: hello.elements, only });
            }
            StageEvent::Lost { source, error } => {
                frond_binmain::errln!(
                    "frond tap: {source}: {error}; followed again when its bridge comes back"
                );
                followed.remove(&source);
            }
            // tap prints poses; a field's announced plants arrive as poses, evaluated.
            StageEvent::Field { .. } => {}
            StageEvent::Event { source, event } => {
                let Some(f) = followed.get_mut(&source) else { continue };
                match event {
                    Event::Pose(pose) => {
                        if (pose.flags.contains(PoseFlags::HELD) && !include_held)
                            || f.only.is_some_and(|id| id != pose.element)
                        {
                            continue;
                        }
                        if printer.print(&pose, &f.names, &f.table, Some(&source))? {
                            return Ok(());
                        }
                        printed = true;
                    }
                    Event::Gap { expected, got } => frond_binmain::errln!(
                        "frond tap: {source}: gap: {} frames missing (seq {expected}..{})",
                        got - expected,
                        got - 1
                    ),
                    Event::RigChanged(h) => {
                        frond_binmain::errln!(
                            "frond tap: {source}: rig changed to {}",
                            frond_protocol::printable(&h.rig_name)
                        );
                        f.names = h.joint_names;
                    }
                    Event::Reconnected(h) => {
                        frond_binmain::errln!(
                            "frond tap: {source}: reconnected (daemon {}, rig {})",
                            frond_protocol::printable(&h.daemon_version),
                            frond_protocol::printable(&h.rig_name)
                        );
                        f.names = h.joint_names;
                    }
                    Event::Elements(table) => {
                        if element.is_some_and(|e| e.parse::<ElementId>().is_err()) {
                            f.only = pick_element(element, &table).unwrap_or(Some(ElementId::MAX));
                        }
                        f.table = table;
                    }
                    Event::Disconnected => {
                        frond_binmain::errln!(
                            "frond tap: {source}: the daemon closed the stream; reconnecting"
                        )
                    }
                }
            }
        }
    }
}
