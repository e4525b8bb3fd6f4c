//! A field (protocol 3) through the SDK: a fake daemon runs the daemon's own field code
//! (`FieldPlayer`, and the `FrameFiller` the daemon's field stage publishes with) and sends its
//! definition and field frames over the socket; the SDK's evaluation of the plants must agree
//! with the daemon's within 1e-4 degrees, and both with seed 000's Eq. 6-7 and section 6.3
//! computed here by hand from the driving motion.

use std::io::Write;

use frond_motion::clip::{Clip, Joints};
use frond_motion::controls::FieldControls;
use frond_motion::field::{Field, FieldParams, make_field};
use frond_motion::field_eval::FieldState;
use frond_motion::field_player::FieldPlayer;
use frond_motion::field_wire::{FrameFiller, layout_of};
use frond_motion::looping::{LoopParams, find_transitions};
use frond_protocol::field::{FieldDefinition, FieldFrame, FieldMessage, FieldTable};
use frond_protocol::{ElementId, ServerMessage};
use frond_sdk::{Event, PoseFlags};

use super::common::{frame, hello_frame};
use super::{quick, serve_once, tempdir};

const FIELD: ElementId = ElementId::new(40);
const ANNOUNCED: [ElementId; 2] = [ElementId::new(40), ElementId::new(41)];
const PUBLISH_HZ: f64 = 60.0;
const FRAMES: usize = 240;

fn sway() -> Clip {
    Clip::from_joints(
        (0..150).map(|k| {
            let t = k as f32 / 30.0;
            let s = (t * 2.3).sin() * 25.0 + (t * 6.1).cos() * 5.0;
            [[s, -s * 0.6, 2.0], [s * 0.5, s * 0.3, 0.0], [-s * 0.2, s, 1.0], [s * 0.1, 3.0, -s]]
        }),
        30.0,
    )
}

fn field() -> Field {
    let p = FieldParams {
        rows: 3,
        cols: 6,
        cell_m: 0.4,
        speed_m_s: 1.5,
        direction_deg: 0.0,
        density: 1.0,
        seed: 5,
    };
    make_field(&p, "sway", 150, 30.0).unwrap()
}

/// Controls away from every default, so each term of the equations shows.
fn controls() -> FieldControls {
    FieldControls {
        direction_deg: 30.0,
        speed_m_s: 1.3,
        time_step: 1.5,
        scale: 1.2,
        delays_s: [0.05, 0.1, 0.2],
    }
}

/// Seed 000, Eq. 6-7 and section 6.3, written out again from the paper (not with
/// `frond_motion::field_eval`): plant `b` at stream time `tau` reads the driving stream `F` at
/// `tau + start / fps - K (gamma_B + delta_i)` for joint `i`, with `gamma_B` the distance from the
/// row's upwind plant `A` along the force over `V_M`; then scale and bend rotation.
fn by_hand(
    f: &Field,
    stream: &dyn Fn(u64) -> Joints,
    oldest: u64,
    newest: u64,
    b: usize,
    tau: f64,
) -> Joints {
    let c = controls();
    let (fps, a) = (30.0, c.direction_deg.to_radians());
    let along =
        |i: usize| f.plants[i].position_m[0] as f64 * a.cos() - f.plants[i].position_m[1] as f64 * a.sin();
    let row = f.plants[b].row;
    let upwind =
        (0..f.plants.len()).filter(|&i| f.plants[i].row == row).map(along).fold(f64::INFINITY, f64::min);
    let gamma = (along(b) - upwind) / c.speed_m_s;
    let mut out = [[0.0f32; 3]; 4];
    for (i, joint) in out.iter_mut().enumerate() {
        let delta = if i == 0 { 0.0 } else { c.delays_s[i - 1] };
        let s = tau + f.plants[b].start_frame as f64 / fps - c.time_step * (gamma + delta);
        let x = (s * fps).clamp(oldest as f64, newest as f64);
        let k = x.floor();
        let (f0, f1) = (stream(k as u64)[i], stream((k as u64 + 1).min(newest))[i]);
        let v: Vec<f64> =
            (0..3).map(|c3| f0[c3] as f64 + (x - k) * (f1[c3] as f64 - f0[c3] as f64)).collect();
        let (p, y, r) = (v[0] * c.scale as f64, v[1] * c.scale as f64, v[2] * c.scale as f64);
        // The bend (pitch, yaw) turned by the force's heading (the take was authored towards +X).
        *joint = [(p * a.cos() + y * a.sin()) as f32, (y * a.cos() - p * a.sin()) as f32, r as f32];
    }
    out
}

fn assert_close(what: &str, got: &Joints, want: &Joints) {
    for (g, w) in got.iter().flatten().zip(want.iter().flatten()) {
        assert!((g - w).abs() < 1e-4, "{what}: {got:?} vs {want:?}");
    }
}

/// The daemon's side: its field player at each publish tick, the frames it publishes, and its
/// own evaluation of every plant at that tick.
fn daemon_run() -> (FieldDefinition, Vec<(FieldFrame, Vec<Joints>, FieldState)>) {
    let clip = sway();
    let t = find_transitions(&clip, &LoopParams::default()).unwrap();
    let f = field();
    let mut player = FieldPlayer::try_new(f.clone(), clip, &t, 3, controls()).unwrap();
    let definition = FieldDefinition {
        id: FIELD,
        source: "field".into(),
        rig: "grass".into(),
        layout: layout_of(&f),
        plants: f.plants.len() as u32,
        stream_fps: 30.0,
        history_frames: player.history_capacity() as u32,
        publish_hz: PUBLISH_HZ as u32,
        plant_elements: ANNOUNCED.to_vec(),
    };
    let (mut filler, mut out) = (FrameFiller::default(), vec![[[0.0; 3]; 4]; f.plants.len()]);
    let mut run = Vec::new();
    for n in 0..FRAMES {
        let t_s = n as f64 / PUBLISH_HZ;
        player.frame(t_s, &mut out);
        // Each frame's numbers are its two announced plants' poses'.
        let mut fr = FieldFrame {
            seq: 2 * n as u64,
            poses: 2,
            host_monotonic_ns: 1_000_000_000 + (t_s * 1e9) as u64,
            field: FIELD,
            flags: PoseFlags::PLAYBACK,
            ..FieldFrame::default()
        };
        filler.fill(player.state(), &mut fr);
        run.push((fr, out.clone(), player.state().clone()));
    }
    (definition, run)
}

#[test]
fn the_sdk_evaluates_plants_as_the_daemon_and_the_paper_do() {
    let (definition, run) = daemon_run();
    let f = field();
    let (_guard, dir) = tempdir();
    let table = FieldTable { elements_version: 0, fields: vec![definition.clone()] };
    let frames: Vec<FieldFrame> = run.iter().map(|r| r.0).collect();
    let server = serve_once(&dir, move |mut s| {
        let mut bytes = hello_frame(0);
        bytes.extend(frame(&ServerMessage::Field(FieldMessage::Table(table))));
        for fr in &frames {
            bytes.extend(frame(&ServerMessage::Field(FieldMessage::Frame(*fr))));
        }
        s.write_all(&bytes).unwrap();
    });
    let mut sub = quick().reconnect(false).connect(&dir).unwrap();
    let (mut n, mut compared, mut hand_checked, mut poses) = (0usize, 0usize, 0usize, 0usize);
    while let Ok(ev) = sub.next_event() {
        let Event::Pose(p) = ev else { continue };
        // The announced plants arrive as poses with their field frame's numbers, evaluated there.
        let k = p.seq as usize / 2;
        let plant = ANNOUNCED.iter().position(|&e| e == p.element).expect("an announced plant");
        assert_eq!(p.seq, 2 * k as u64 + plant as u64);
        assert!(p.flags.contains(PoseFlags::PLAYBACK));
        assert_close(&format!("pose of plant {plant} at frame {k}"), &p.joints_deg, &run[k].1[plant]);
        poses += 1;
        // Every plant, evaluated by the SDK where the daemon did (the last frame taken).
        if k < n {
            continue;
        }
        n = k + 1;
        let live = sub.fields().get(FIELD).expect("the field is known");
        assert_eq!(live.plants(), f.plants.len());
        let (_, daemon, state) = &run[k];
        for (b, want) in daemon.iter().enumerate() {
            if let Some(got) = live.plant_pose(b, live.tau_s()) {
                assert_close(&format!("plant {b} at frame {k}"), &got, want);
                compared += 1;
            }
        }
        // And by hand, for a few plants, from the daemon's driving stream.
        let h = state.history();
        let stream = |i: u64| *h.get(i).expect("held");
        if h.is_complete() {
            for b in [0, 7, f.plants.len() - 1] {
                let want = by_hand(&f, &stream, h.oldest(), h.produced() - 1, b, state.tau_s());
                assert_close(&format!("plant {b} by hand at frame {k}"), &daemon[b], &want);
                hand_checked += 1;
            }
        }
    }
    server.join().unwrap();
    // The history fills within a few frames; from then on every plant is compared.
    assert!(compared > (FRAMES - 20) * f.plants.len(), "{compared} plant poses compared");
    assert!(poses > (FRAMES - 20) * ANNOUNCED.len(), "{poses} poses of announced plants");
    assert!(hand_checked >= 3 * (FRAMES - 20), "{hand_checked} checked by hand");
}
