//! A subscriber over Zenoh against a hand-made bridge (a plain Zenoh session holding the
//! source's token, answering its hello and putting poses), with samples on the poses key that
//! are not one frame of frond's protocol put in between, as anyone who may put on the key can;
//! and a field's tables (protocol 3) from a bridge that lies, or that a gap lost.

#![cfg(feature = "zenoh")]

mod common;

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use common::{hello_frame, pose_frame};
use frond_motion::field::{FieldParams, make_field};
use frond_motion::field_wire::layout_of;
use frond_protocol::field::{FieldDefinition, FieldFrame, FieldMessage, FieldTable};
use frond_protocol::{ElementId, MAX_FRAME_LEN, ServerMessage};
use frond_sdk::{Event, Source, Subscriber};
use zenoh::Wait;

/// A hand-made bridge publishing `frond/<name><pid>/glove`: its session and key, the address
/// a subscriber uses, and what it holds for the source (its token and its hello queryable).
struct HandMade {
    bridge: zenoh::Session,
    key: String,
    source: Source,
    _token: zenoh::liveliness::LivelinessToken,
    _hello: zenoh::query::Queryable<()>,
}

fn hand_made(name: &str) -> HandMade {
    let key = format!("frond/{name}{}/glove", std::process::id());
    let (bridge, endpoint) = common::hand_made_bridge();
    let _token = bridge.liveliness().declare_token(format!("{key}/alive")).wait().unwrap();
    let _hello = bridge
        .declare_queryable(format!("{key}/hello"))
        .callback(|query| {
            let _ = query.reply(query.key_expr().clone(), hello_frame(0)).wait();
        })
        .wait()
        .unwrap();
    let source = format!("zenoh:{key}?connect={endpoint}").parse().unwrap();
    HandMade { bridge, key, source, _token, _hello }
}

/// A field of `rows x cols` plants as a daemon defines it, with id `id`.
fn field_definition(id: u16, rows: usize, cols: usize) -> FieldDefinition {
    let params =
        FieldParams { rows, cols, cell_m: 0.2, speed_m_s: 1.5, direction_deg: 0.0, density: 1.0, seed: 2 };
    let field = make_field(&params, "sway", 60, 30.0).unwrap();
    FieldDefinition {
        id: ElementId::new(id),
        source: "field".into(),
        rig: "grass".into(),
        layout: layout_of(&field),
        plants: (rows * cols) as u32,
        stream_fps: 30.0,
        history_frames: 64,
        publish_hz: 60,
        plant_elements: vec![],
    }
}

/// A field table frame.
fn field_table(elements_version: u64, fields: Vec<FieldDefinition>) -> Vec<u8> {
    common::frame(&ServerMessage::Field(FieldMessage::Table(FieldTable { elements_version, fields })))
}

#[test]
fn samples_that_are_not_one_frame_are_skipped_and_counted_and_the_stream_goes_on() {
    let HandMade { bridge, key, source, .. } = &hand_made("odd");

    // Poses 0, 1, 2, ... every 2 ms; once the subscriber is in, after the pose 50 later, three
    // samples that are not one frame: text, a frame of another protocol version, a frame cut
    // short.
    let mut other_version = pose_frame(0);
    other_version[4] = other_version[4].wrapping_add(1);
    let cut = pose_frame(0)[..20].to_vec();
    let odd: Vec<Vec<u8>> = vec![b"not a frame".to_vec(), other_version, cut];
    let (stop, go) = (Arc::new(AtomicBool::new(false)), Arc::new(AtomicBool::new(false)));
    let odd_after = Arc::new(AtomicU64::new(u64::MAX));
    let putter = {
        let (session, key) = (bridge.clone(), key.clone());
        let (stop, go, odd_after) = (stop.clone(), go.clone(), odd_after.clone());
        std::thread::spawn(move || {
            let poses = session.declare_publisher(format!("{key}/poses")).wait().unwrap();
            let mut seq = 0;
            while !stop.load(Ordering::Relaxed) {
                poses.put(pose_frame(seq)).wait().unwrap();
                if go.load(Ordering::Relaxed) && odd_after.load(Ordering::Relaxed) == u64::MAX {
                    odd_after.store(seq + 50, Ordering::Relaxed);
                }
                if seq == odd_after.load(Ordering::Relaxed) {
                    for bytes in &odd {
                        poses.put(bytes.clone()).wait().unwrap();
                    }
                }
                seq += 1;
                std::thread::sleep(Duration::from_millis(2));
            }
        })
    };

    let mut sub = Subscriber::options().hello_timeout(Duration::from_secs(10)).subscribe(source).unwrap();
    go.store(true, Ordering::Relaxed);
    let deadline = Instant::now() + Duration::from_secs(30);
    let mut last = None;
    while last.is_none_or(|seq| seq < odd_after.load(Ordering::Relaxed).saturating_add(100)) {
        assert!(Instant::now() < deadline, "the poses after the odd samples never came (last {last:?})");
        match sub.next_event() {
            Ok(Event::Pose(p)) => last = Some(p.seq),
            Ok(Event::Gap { .. }) => {}
            other => panic!("a bad sample must not reach the caller or end the stream: {other:?}"),
        }
    }
    stop.store(true, Ordering::Relaxed);
    putter.join().unwrap();
    let stats = sub.stats();
    assert_eq!(stats.rejected, 3, "{stats:?}");
    assert_eq!((stats.disconnects, stats.reconnects), (0, 0), "{stats:?}");
}

/// A field (protocol 3) from a bridge that lies: its `fields` queryable and key carry a sample
/// larger than any frame, a table whose field claims a million plants on a grid of twelve cells
/// and one of more fields than a daemon runs; then a true table, and field frames numbered
/// among the poses. The lies are refused before anything is made of them (counted, logged at
/// most every 10 s), the stream goes on, and the true field is taken, numbered without a gap.
#[test]
fn a_lying_bridges_field_tables_are_refused_and_the_true_field_is_taken() {
    let HandMade { bridge, key, source, .. } = &hand_made("liar");
    let oversized = vec![0x5a_u8; MAX_FRAME_LEN + 4096];
    // A late joiner's question is answered by the oversized sample only.
    let _fields = {
        let oversized = oversized.clone();
        bridge
            .declare_queryable(format!("{key}/fields"))
            .callback(move |query| {
                let _ = query.reply(query.key_expr().clone(), oversized.clone()).wait();
            })
            .wait()
            .unwrap()
    };
    let definition = field_definition(40, 3, 4);
    let table = |fields| field_table(0, fields);
    let million = FieldDefinition { plants: 1_000_000, ..definition.clone() };
    let lies = [oversized, table(vec![million]), table(vec![definition.clone(); 9 * 8])];
    let truth = table(vec![definition.clone()]);

    // Poses every 2 ms; once the subscriber is in, the lies, the true table, and from then on a
    // field frame after every pose, taking 3 numbers (as a field with 2 announced plants does).
    let (stop, go) = (Arc::new(AtomicBool::new(false)), Arc::new(AtomicBool::new(false)));
    let putter = {
        let (session, key, stop, go) = (bridge.clone(), key.clone(), stop.clone(), go.clone());
        std::thread::spawn(move || {
            let poses = session.declare_publisher(format!("{key}/poses")).wait().unwrap();
            let fields = session.declare_publisher(format!("{key}/fields")).wait().unwrap();
            let (mut seq, mut told) = (0, false);
            while !stop.load(Ordering::Relaxed) {
                poses.put(pose_frame(seq)).wait().unwrap();
                seq += 1;
                if go.load(Ordering::Relaxed) && !told {
                    for lie in &lies {
                        fields.put(lie.clone()).wait().unwrap();
                    }
                    fields.put(truth.clone()).wait().unwrap();
                    told = true;
                } else if told {
                    let f = FieldFrame { seq, poses: 3, field: ElementId::new(40), ..FieldFrame::default() };
                    poses.put(common::frame(&ServerMessage::Field(FieldMessage::Frame(f)))).wait().unwrap();
                    seq += 3;
                }
                std::thread::sleep(Duration::from_millis(2));
            }
        })
    };

    let mut sub = Subscriber::options().hello_timeout(Duration::from_secs(10)).subscribe(source).unwrap();
    assert!(sub.fields().is_empty(), "nothing was made of the oversized answer");
    go.store(true, Ordering::Relaxed);
    let deadline = Instant::now() + Duration::from_secs(30);
    let mut after = 0;
    while after < 200 {
        assert!(Instant::now() < deadline, "the stream stopped after the lies ({after} poses)");
        match sub.next_event() {
            Ok(Event::Pose(_)) if !sub.fields().is_empty() => after += 1,
            Ok(Event::Pose(_) | Event::Gap { .. }) => {}
            other => panic!("a lie must not reach the caller or end the stream: {other:?}"),
        }
    }
    stop.store(true, Ordering::Relaxed);
    putter.join().unwrap();
    let fields: Vec<_> = sub.fields().iter().map(|f| (f.definition().clone(), f.plants())).collect();
    assert_eq!(fields, [(definition, 12)], "the true field, and only it");
    let stats = sub.stats();
    assert_eq!(stats.rejected, 2, "the oversized answer and sample: {stats:?}");
    // The field frames' numbers (each its own and 2 more) follow on from the poses': no gap.
    assert_eq!((stats.gaps, stats.disconnects), (0, 0), "{stats:?}");
}

/// A field table put while a subscriber's link lost samples is asked for again after the gap,
/// as the element table is: here the bridge never puts the new table at all (the put was
/// lost), its `fields` queryable answers it, and the poses skip 20 numbers.
#[test]
fn a_field_table_lost_in_a_gap_is_asked_for_again() {
    let HandMade { bridge, key, source, .. } = &hand_made("lost");
    let table = |version, id| field_table(version, vec![field_definition(id, 2, 3)]);
    let (before, after) = (table(1, 40), table(2, 41));
    let changed = Arc::new(AtomicBool::new(false));
    let _fields = {
        let changed = changed.clone();
        bridge
            .declare_queryable(format!("{key}/fields"))
            .callback(move |query| {
                let answer = if changed.load(Ordering::Relaxed) { &after } else { &before };
                let _ = query.reply(query.key_expr().clone(), answer.clone()).wait();
            })
            .wait()
            .unwrap()
    };
    let (stop, go) = (Arc::new(AtomicBool::new(false)), Arc::new(AtomicBool::new(false)));
    let putter = {
        let (session, key, stop, go, changed) =
            (bridge.clone(), key.clone(), stop.clone(), go.clone(), changed.clone());
        std::thread::spawn(move || {
            let poses = session.declare_publisher(format!("{key}/poses")).wait().unwrap();
            let mut seq = 0;
            while !stop.load(Ordering::Relaxed) {
                poses.put(pose_frame(seq)).wait().unwrap();
                seq += 1;
                if go.load(Ordering::Relaxed) && !changed.load(Ordering::Relaxed) {
                    changed.store(true, Ordering::Relaxed);
                    seq += 20;
                }
                std::thread::sleep(Duration::from_millis(2));
            }
        })
    };

    let mut sub = Subscriber::options().hello_timeout(Duration::from_secs(10)).subscribe(source).unwrap();
    let ids = |sub: &Subscriber| sub.fields().iter().map(|f| f.definition().id).collect::<Vec<_>>();
    while ids(&sub).is_empty() {
        sub.next_event().unwrap();
    }
    assert_eq!(ids(&sub), [ElementId::new(40)], "the table asked for while joining");
    go.store(true, Ordering::Relaxed);
    let deadline = Instant::now() + Duration::from_secs(10);
    while ids(&sub) != [ElementId::new(41)] {
        assert!(Instant::now() < deadline, "the new table never came: {:?}, {:?}", ids(&sub), sub.stats());
        sub.next_event().unwrap();
    }
    stop.store(true, Ordering::Relaxed);
    putter.join().unwrap();
    assert!(sub.stats().gaps >= 1, "{:?}", sub.stats());
}
