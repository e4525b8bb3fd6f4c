//! The page's evaluation of a field (`page/field.js`, protocol 3) in headless Chromium against
//! the SDK's (`frond_sdk::field`, the daemon's own code): ten thousand plants, every one within
//! 1e-4 degrees, fed the same definition and field frames.

use frond_motion::clip::Clip;
use frond_motion::controls::FieldControls;
use frond_motion::field::{FieldParams, make_field};
use frond_motion::field_player::FieldPlayer;
use frond_motion::field_wire::{FrameFiller, layout_of};
use frond_motion::looping::{LoopParams, find_transitions};
use frond_protocol::ElementId;
use frond_protocol::field::{FieldDefinition, FieldFrame, FieldTable};
use frond_sdk::field::LiveFields;
use frond_webdriver::{browser, start_session};
use serde_json::{Value, json};

const FIELD_JS: &str = include_str!("../../page/field.js");
const FIELD: ElementId = ElementId::new(40);

#[test]
fn the_page_evaluates_ten_thousand_plants_as_the_sdk_does() {
    let Some((chromium, driver)) = browser() else { return };
    // The daemon's side: a 100 x 100 field of a sway, its player and the frames it publishes.
    let clip = Clip::from_joints(
        (0..300).map(|k| {
            let t = k as f32 / 30.0;
            let s = (t * 1.7).sin() * 22.0 + (t * 4.9).sin() * 6.0;
            [[s, -s * 0.5, 1.0], [s * 0.5, s * 0.2, -2.0], [-s * 0.3, s, 0.5], [s * 0.2, 2.0, -s]]
        }),
        30.0,
    );
    let transitions = find_transitions(&clip, &LoopParams::default()).unwrap();
    let p = FieldParams {
        rows: 100,
        cols: 100,
        cell_m: 0.15,
        speed_m_s: 1.5,
        direction_deg: 20.0,
        density: 1.0,
        seed: 11,
    };
    let field = make_field(&p, "sway", 300, 30.0).unwrap();
    assert_eq!(field.plants.len(), 10_000);
    let controls = FieldControls {
        direction_deg: 200.0,
        speed_m_s: 2.1,
        time_step: 1.25,
        scale: 1.1,
        delays_s: [0.04, 0.1, 0.3],
    };
    let mut player = FieldPlayer::try_new(field.clone(), clip, &transitions, 2, controls).unwrap();
    let definition = FieldDefinition {
        id: FIELD,
        source: "field".into(),
        rig: "grass".into(),
        layout: layout_of(&field),
        plants: 10_000,
        stream_fps: 30.0,
        history_frames: player.history_capacity() as u32,
        publish_hz: 60,
        plant_elements: vec![FIELD],
    };
    // The SDK takes the definition and the frames as a subscriber would.
    let mut sdk = LiveFields::default();
    assert!(sdk.on_table(FieldTable { elements_version: 1, fields: vec![definition.clone()] }).is_empty());
    let mut filler = FrameFiller::default();
    let mut frames = Vec::new();
    for n in 0..120 {
        player.advance(n as f64 / 60.0);
        let mut f = FieldFrame { seq: n, field: FIELD, ..FieldFrame::default() };
        filler.fill(player.state(), &mut f);
        assert!(sdk.on_frame(&f).is_some());
        frames.push(f);
    }
    let live = sdk.get(FIELD).unwrap();
    assert!(live.history_complete(), "the trickle filled the history in 120 frames");
    let tau = live.tau_s();
    // The page's side: the same layout and frames, as the console hands them to the page.
    let layout = live.layout();
    let page_layout = json!({
        "positions": layout.plants.iter().flat_map(|q| q.position_m).collect::<Vec<f32>>(),
        "rows": layout.plants.iter().map(|q| q.row).collect::<Vec<_>>(),
        "startFrames": layout.plants.iter().map(|q| q.start_frame).collect::<Vec<_>>(),
        "rowCount": layout.rows,
        "authoredDirectionDeg": layout.authored_direction_deg,
        "fps": definition.stream_fps,
        "historyFrames": definition.history_frames,
    });
    let dir = tempfile::tempdir().unwrap();
    let d = start_session(&chromium, &driver, &dir.path().join("profile"), "640,480", "about:blank");
    let script = format!(
        "{FIELD_JS}\nconst L = {page_layout};\nconst frames = {frames};\n\
         const f = new frondField.FieldEval({{ ...L, positions: Float32Array.from(L.positions), \
         rows: Uint32Array.from(L.rows), startFrames: Uint32Array.from(L.startFrames) }});\n\
         for (const fr of frames) if (!f.applyFrame(fr)) return 'refused';\n\
         const out = new Float32Array(12 * f.n);\n\
         const done = f.evalAll({tau:?}, out);\n\
         return {{ done, tau: f.tau, out: Array.from(out) }};",
        frames = serde_json::to_string(&frames).unwrap(),
    );
    let got: Value = d.script(&script);
    assert_eq!(got["done"], json!(10_000), "every plant evaluated in the page");
    assert_eq!(got["tau"].as_f64(), Some(tau));
    let out = got["out"].as_array().unwrap();
    let (mut worst, mut spread) = (0.0f64, 0.0f64);
    for (i, page) in out.chunks(12).enumerate() {
        let want = live.plant_pose(i, tau).expect("the SDK evaluates every plant");
        for (g, w) in page.iter().zip(want.iter().flatten()) {
            let g = g.as_f64().unwrap();
            worst = worst.max((g - f64::from(*w)).abs());
            spread = spread.max(f64::from(*w).abs());
        }
    }
    assert!(worst < 1e-4, "the page and the SDK differ by {worst} degrees");
    assert!(spread > 5.0, "the plants bend ({spread} degrees at most): a real comparison");
}
