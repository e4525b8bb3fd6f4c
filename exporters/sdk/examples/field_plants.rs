//! Every plant of a running field, evaluated here (protocol 3; seed 000, Eq. 6-7 and section
//! 6.3): from this host's daemon or from a bridge over Zenoh, the same code.
//!
//! ```sh
//! cargo run --example field_plants                                  # this host's daemon
//! cargo run --example field_plants -- zenoh:frond/stage-a/studio-1  # another host's
//! ```
//!
//! The daemon publishes what defines a field (its layout and parameters, once) and frames of
//! its driving motion (60 a second, the same few hundred bytes whatever the plant count); the
//! SDK keeps each field, and one call, [`frond_sdk::field::LiveField::plant_pose`], gives any
//! plant's pose. Once a field's history has arrived (a subscriber that joins a running field
//! waits for its trickle), this prints, for each of the next `FIELD_FRAMES` field frames (1 by
//! default), one JSON line: the field, the frame's sequence number, its stream time and every
//! plant's four joints' pitch, yaw and roll in degrees, plant 0 first.

use std::collections::HashMap;
use std::io::Write;

use frond_sdk::{ElementId, Source, Subscriber};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // A socket directory (default: $FROND_SOCKET_DIR, else $XDG_RUNTIME_DIR/frond) or zenoh:KEY.
    let source: Source = match std::env::args().nth(1) {
        Some(arg) => arg.parse()?,
        None => Source::Socket(frond_protocol::paths::socket_dir(None)),
    };
    let want: usize = std::env::var("FIELD_FRAMES").ok().and_then(|n| n.parse().ok()).unwrap_or(1);
    let mut sub = Subscriber::open(&source, Subscriber::options())?;
    eprintln!("# waiting for a field on {source}");
    let mut last: HashMap<ElementId, u64> = HashMap::new();
    let (mut printed, mut out) = (0, std::io::stdout().lock());
    while printed < want {
        sub.next_event()?;
        for field in sub.fields().iter() {
            let id = field.definition().id;
            let Some(frame) = field.last_frame().filter(|f| last.get(&id) != Some(&f.seq)) else { continue };
            last.insert(id, frame.seq);
            if !field.history_complete() || printed == want {
                continue;
            }
            // Every plant at the stream time of the frame just applied.
            let tau = field.tau_s();
            let plants: Vec<_> = (0..field.plants()).map(|i| field.plant_pose(i, tau)).collect();
            let line = serde_json::json!({
                "field": id, "source": field.definition().source, "seq": frame.seq, "tau_s": tau,
                "plants": field.plants(), "joints_deg": plants,
            });
            writeln!(out, "{line}")?;
            out.flush()?;
            printed += 1;
        }
    }
    Ok(())
}
