//! A running field as the daemon sends it on its socket, kept by a test and played back: the
//! independent side of tests that check a field subscriber (the Blender add-on through
//! frond-osc, a remote reader through Zenoh) against the SDK's evaluation of the same frames.
//! Shared by path (`#[path]`) between the test crates that need it.

use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

use frond_protocol::field::FieldMessage;
use frond_sdk::field::LiveFields;
use frond_sdk::{Relayed, Subscriber};

/// The field's tables and frames as the daemon in `socket_dir` sends them, in order, until
/// `stop`.
pub fn record_field(socket_dir: &Path, stop: Arc<AtomicBool>) -> JoinHandle<Vec<FieldMessage>> {
    let mut sub = Subscriber::options()
        .read_timeout(Some(Duration::from_millis(200)))
        .connect(socket_dir)
        .expect("subscribe on the daemon's socket");
    std::thread::spawn(move || {
        let mut got = Vec::new();
        while !stop.load(Ordering::Relaxed) {
            if let Ok(Relayed::Field(msg)) = sub.next_relayed() {
                got.push(msg);
            }
        }
        got
    })
}

/// `messages` (as [`record_field`] kept them) played into fields of the SDK's, up to and with
/// the frame numbered `seq`; `who` names the check in a failure.
pub fn played_to(messages: &[FieldMessage], seq: u64, who: &str) -> LiveFields {
    let mut fields = LiveFields::keeping(0);
    for msg in messages {
        match msg {
            FieldMessage::Table(t) => assert!(fields.on_table(t.clone()).is_empty(), "{who}"),
            FieldMessage::Frame(f) => {
                fields.on_frame(f);
                if f.seq == seq {
                    return fields;
                }
            }
        }
    }
    panic!("{who}: frame {seq} never reached the daemon's socket subscriber")
}
