//! A whole exporter in 40 lines: subscribe to frondd (on this host, or a bridge over Zenoh) and
//! print each pose as one line of text.
//!
//! ```sh
//! cargo run --example print_poses                          # this host's daemon
//! cargo run --example print_poses -- zenoh:frond/stage-a/studio-1   # another host's
//! ```
//!
//! Every pose carries its element (0 the main hand's plant; others a second hand, a layer, a
//! looped take, a field plant: see the hello's element table), its sequence number, the device and
//! host times, and four joints' pitch, yaw and roll in degrees (the protocol's rotation
//! convention). The SDK reconnects when the daemon restarts and reports frames it lost.

use frond_sdk::{Event, Source, Subscriber};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // A socket directory (default: $FROND_SOCKET_DIR, else $XDG_RUNTIME_DIR/frond) or zenoh:KEY.
    let source: Source = match std::env::args().nth(1) {
        Some(arg) => arg.parse()?,
        None => Source::Socket(frond_protocol::paths::socket_dir(None)),
    };
    let limit: u64 = std::env::var("POSES").ok().and_then(|n| n.parse().ok()).unwrap_or(u64::MAX);
    let mut sub = Subscriber::open(&source, Subscriber::options())?;
    let hello = sub.hello();
    println!("# rig {} at {} Hz, joints {:?}", hello.rig_name, hello.tick_rate_hz, hello.joint_names);
    for e in &sub.elements().elements {
        println!("# element {} {} ({})", e.id, e.name, e.kind.as_str());
    }
    while sub.stats().frames < limit {
        match sub.next_event()? {
            Event::Pose(p) => {
                let [root, j1, j2, tip] = p.joints_deg;
                println!("{} {} {} {root:?} {j1:?} {j2:?} {tip:?}", p.element, p.seq, p.device_time_us);
            }
            Event::Gap { expected, got } => println!("# lost {} frames", got - expected),
            Event::Elements(table) => println!("# {} elements now", table.elements.len()),
            Event::RigChanged(h) | Event::Reconnected(h) => println!("# rig {}", h.rig_name),
            Event::Disconnected => println!("# daemon gone; reconnecting"),
        }
    }
    Ok(())
}
