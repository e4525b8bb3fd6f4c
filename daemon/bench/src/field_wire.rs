//! Section 10: a live field's cost per publish tick and bytes on the wire at 1, 64, 10,000 and
//! 100,000 plants, protocol 3 (the field stage's work: advance the driving stream, fill one
//! field frame, encode it) against protocol 2's per-plant publishing measured in the same run
//! (evaluate every plant, encode one pose each), and the subscriber's evaluation per plant
//! (`frond_sdk::field`, the same `frond_motion::field_eval` the daemon's field runs); its part
//! `page` ([`crate::field_page`]) the console page drawing a live field, its part `page_hand`
//! ([`crate::field_hand`]) a hand sample to the first plant moving on that page.

use frond_motion::clip::{Clip, Joints};
use frond_motion::controls::FieldControls;
use frond_motion::field::{Field, FieldParams, make_field};
use frond_motion::field_player::FieldPlayer;
use frond_motion::field_wire::{FrameFiller, layout_of};
use frond_motion::looping::Transitions;
use frond_protocol::field::{FieldDefinition, FieldFrame, FieldMessage, FieldTable};
use frond_protocol::{ElementId, Pose, PoseFlags, ServerMessage, encode_frame};
use frond_sdk::field::LiveFields;
use frondd::clock::monotonic_ns;
use serde_json::json;

use crate::Options;
use crate::error::BenchError;
use crate::report::{Bound, Measurement, Section};

/// The section's title.
pub const TITLE: &str = "a live field per publish tick at 1 to 100,000 plants: protocol 3 vs per-plant poses";
/// Field frames per second (the daemon's `FIELD_PUBLISH_HZ`).
const PUBLISH_HZ: f64 = 60.0;
/// The plant counts measured, with their grids.
const SIZES: [(usize, usize); 4] = [(1, 1), (8, 8), (100, 100), (250, 400)];
const FIELD: ElementId = ElementId::new(40);

fn sway() -> (Clip, Transitions) {
    frond_motion::field_player::bench_sway()
}

fn field(rows: usize, cols: usize) -> Result<Field, BenchError> {
    let p =
        FieldParams { rows, cols, cell_m: 0.2, speed_m_s: 1.5, direction_deg: 30.0, density: 1.0, seed: 1 };
    Ok(make_field(&p, "bench", 300, 30.0)?)
}

/// Median nanoseconds of one call of `f` over `n` calls (each call one publish tick `k`).
fn per_tick_ns(n: u64, mut f: impl FnMut(u64)) -> f64 {
    let mut v: Vec<f64> = (0..n)
        .map(|k| {
            let start = monotonic_ns();
            f(k);
            (monotonic_ns() - start) as f64
        })
        .collect();
    crate::tick::median(&mut v)
}

/// One size's figures, and its field and player for the SDK's part.
struct SizeRun {
    /// Protocol 3: the field stage's work per publish tick, ns, and its frame's bytes.
    new_ns: f64,
    new_bytes: f64,
    /// Protocol 2: every plant evaluated and encoded as a pose, ns per tick, and bytes.
    old_ns: f64,
    old_bytes: f64,
    field: Field,
    player: FieldPlayer,
}

/// Measures one size.
fn measure(rows: usize, cols: usize, quick: bool) -> Result<SizeRun, BenchError> {
    let (clip, transitions) = sway();
    let f = field(rows, cols)?;
    let plants = f.plants.len();
    let mut new = FieldPlayer::try_new(f.clone(), clip.clone(), &transitions, 1, FieldControls::default())?;
    let (mut filler, mut frame, mut buf) =
        (FrameFiller::default(), FieldFrame::default(), Vec::with_capacity(4096));
    let ticks = if quick { 600 } else { 3000 };
    let mut new_bytes = 0usize;
    let new_ns = per_tick_ns(ticks, |k| {
        new.advance(k as f64 / PUBLISH_HZ);
        filler.fill(new.state(), &mut frame);
        buf.clear();
        encode_frame(&ServerMessage::Field(FieldMessage::Frame(frame)), &mut buf);
        new_bytes = new_bytes.max(buf.len());
    });
    let mut old = FieldPlayer::try_new(f.clone(), clip, &transitions, 1, FieldControls::default())?;
    let mut out: Vec<Joints> = vec![[[0.0; 3]; 4]; plants];
    let mut bytes = Vec::with_capacity(plants * 160);
    let old_ticks = ((if quick { 100_000 } else { 500_000 }) / plants as u64).clamp(3, ticks);
    let old_ns = per_tick_ns(old_ticks, |k| {
        old.frame(k as f64 / PUBLISH_HZ, &mut out);
        bytes.clear();
        for (i, j) in out.iter().enumerate() {
            let pose = Pose {
                seq: k * plants as u64 + i as u64,
                element: ElementId::new(40 + (i % 1000) as u16),
                joints_deg: *j,
                flags: PoseFlags::PLAYBACK,
                ..Pose::default()
            };
            encode_frame(&ServerMessage::Pose(pose), &mut bytes);
        }
    });
    Ok(SizeRun {
        new_ns,
        new_bytes: new_bytes as f64,
        old_ns,
        old_bytes: bytes.len() as f64,
        field: f,
        player: new,
    })
}

/// Section 10 (see the module docs).
pub fn field_wire(o: &Options) -> Result<Section, BenchError> {
    let mut ms = Vec::new();
    let mut rows = Vec::new();
    let mut first_ns = None;
    let mut big: Option<(Field, FieldPlayer)> = None;
    let mut sdk_plant_ns = None;
    for (r, c) in SIZES {
        let SizeRun { new_ns, new_bytes: new_b, old_ns, old_bytes: old_b, field: f, player } =
            measure(r, c, o.quick)?;
        let n = f.plants.len();
        let base = *first_ns.get_or_insert(new_ns);
        ms.push(Measurement::new(
            format!("tick_ns_{n}"),
            "ns",
            new_ns,
            format!("per-plant poses, {n} plants"),
            old_ns,
        ));
        ms.push(Measurement::new(
            format!("bytes_s_{n}"),
            "bytes",
            new_b * PUBLISH_HZ,
            format!("per-plant poses, {n} plants"),
            old_b * PUBLISH_HZ,
        ));
        ms.push(
            Measurement::new(format!("tick_ns_{n}_vs_1"), "ns", new_ns, "protocol 3, 1 plant", base)
                .with_target(
                    "the field's work per tick does not grow with its plants (within 2x of 1 plant)",
                    Bound::MaxRatio,
                    2.0,
                ),
        );
        rows.push(json!({ "plants": n, "protocol3_ns": new_ns, "protocol3_bytes": new_b, "per_plant_ns": old_ns, "per_plant_bytes": old_b }));
        if n == 10_000 {
            big = Some((f, player));
        }
    }
    // The subscriber's evaluation per plant, at 10,000 plants, against the daemon's own.
    if let Some((f, mut player)) = big {
        let definition = FieldDefinition {
            id: FIELD,
            source: "field".into(),
            rig: "grass".into(),
            layout: layout_of(&f),
            plants: f.plants.len() as u32,
            stream_fps: 30.0,
            history_frames: player.history_capacity() as u32,
            publish_hz: PUBLISH_HZ as u32,
            plant_elements: vec![FIELD],
        };
        let mut sdk = LiveFields::default();
        if let Some((_, e)) = sdk.on_table(FieldTable { elements_version: 1, fields: vec![definition] }).pop()
        {
            return Err(BenchError::Field(e));
        }
        let (mut filler, mut frame) =
            (FrameFiller::default(), FieldFrame { field: FIELD, ..FieldFrame::default() });
        for k in 0..400 {
            player.advance(k as f64 / PUBLISH_HZ);
            filler.fill(player.state(), &mut frame);
            sdk.on_frame(&frame);
        }
        let live = sdk
            .get(FIELD)
            .ok_or_else(|| BenchError::NoData("the SDK did not keep the bench's field".into()))?;
        let tau = live.tau_s();
        let n = f.plants.len() as u64;
        let sdk_ns = per_tick_ns(5, |_| {
            for i in 0..n as usize {
                std::hint::black_box(live.plant_pose(i, tau));
            }
        }) / n as f64;
        let mut out = vec![[[0.0; 3]; 4]; f.plants.len()];
        let daemon_ns = per_tick_ns(5, |_| player.frame(400.0 / PUBLISH_HZ, &mut out)) / n as f64;
        sdk_plant_ns = Some(sdk_ns);
        ms.push(Measurement::new(
            "sdk_plant_ns",
            "ns",
            sdk_ns,
            "the daemon's field code per plant",
            daemon_ns,
        ));
    }
    let mut section =
        Section::ok("field_wire", TITLE, ms, json!({ "sizes": rows, "publish_hz": PUBLISH_HZ }));
    // The console page drawing a field, against the same scene standing still.
    section.parts.push(crate::field_page::field_page(o, sdk_plant_ns));
    // A hand sample (a wrist swipe on the FUSE glove) to the first plant moving on that page.
    section.parts.push(crate::field_hand::field_hand(o));
    Ok(section)
}
