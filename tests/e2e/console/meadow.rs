//! The console draws a meadow (issue 48; seed 000, Eq. 6-7 and section 6.3): ten thousand
//! plants of a live field from the virtual glove, each evaluated in the page (`page/field.js`)
//! from the field frames the console passes on, and drawn instanced (`page/meadow.js`). The
//! page's angles are checked against the SDK's (`frond_sdk::field`, the daemon's own code),
//! evaluated here from the same field frames; the draw calls against the plant count.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use frond_sdk::Subscriber;
use frond_sdk::field::LiveField;
use frond_webdriver::{browser, poll, start_session};
use serde_json::Value;

use super::start_console;

/// The SDK's field after each of the last field frames, by the frame's sequence number.
type Kept = Arc<Mutex<VecDeque<(u64, LiveField)>>>;

/// Reads `sub` until `stop`, keeping a copy of the field after each of its last 240 frames.
fn keep_fields(mut sub: Subscriber, kept: Kept, stop: Arc<AtomicBool>) {
    let mut last = None;
    while !stop.load(Ordering::Relaxed) {
        if sub.next_event().is_err() {
            continue;
        }
        let Some(field) = sub.fields().by_source("field") else { continue };
        let seq = field.last_frame().map(|f| f.seq);
        if seq.is_none() || seq == last {
            continue;
        }
        last = seq;
        let mut k = kept.lock().unwrap();
        if k.len() == 240 {
            k.pop_front();
        }
        k.push_back((seq.unwrap(), field.clone()));
    }
}

#[test]
fn the_console_draws_ten_thousand_plants_instanced_as_the_daemon_evaluates_them() {
    let Some((chromium, driver)) = browser() else { return };
    let dir = tempfile::tempdir().unwrap();
    let daemon = crate::meadow::daemon_with_sway(dir.path(), Duration::from_millis(1500));
    let meadow = crate::meadow::compact_field(&daemon, "sway", 100, 100);
    let field = meadow.to_str().unwrap();
    daemon.frond_ok(&["field", "start", "--take", "sway", "--field", field, "--plants", "4"]);

    let sub =
        Subscriber::options().read_timeout(Some(Duration::from_millis(200))).connect(&daemon.socket_dir);
    let (kept, stop) = (Kept::default(), Arc::new(AtomicBool::new(false)));
    let reader = {
        let (kept, stop) = (Arc::clone(&kept), Arc::clone(&stop));
        let sub = sub.unwrap();
        std::thread::spawn(move || keep_fields(sub, kept, stop))
    };
    let (_console, url, _) = start_console(&daemon, &["--listen", "127.0.0.1:0"]);
    let d = start_session(&chromium, &driver, &dir.path().join("profile"), "1280,720", &url);
    // The page has the field and, once the trickle has brought the whole history, evaluates
    // every plant.
    let id = poll("the meadow's 10,000 plants evaluated in the page", Duration::from_secs(30), || {
        let v = d.script(
            "const m = globalThis.frondMeadow; if (!m) return null; \
             for (const [id, f] of m.fields) if (f.n === 10000 && f.evaluated === 10000) return id; \
             return m.notes.length ? m.notes.join('; ') : null;",
        );
        match v {
            Value::Number(n) => n.as_u64(),
            Value::String(s) => panic!("the meadow says: {s}"),
            _ => None,
        }
    });

    // The page's evaluation of every plant against the SDK's after the same field frame, at
    // the page's stream time (a few tries: the SDK's copy may not be kept yet, or be gone).
    let (mut compared, mut worst, mut spread) = (0, 0.0f64, 0.0f64);
    for _ in 0..20 {
        let got = d.script(&format!(
            "const m = globalThis.frondMeadow, f = m.fields.get({id}); \
             return m.evaluated({id}, f.eval.tau);"
        ));
        let seq = got["seq"].as_u64().unwrap();
        let tau = got["tau"].as_f64().unwrap();
        let sdk = poll("the SDK after the page's frame", Duration::from_secs(5), || {
            let k = kept.lock().unwrap();
            match k.iter().find(|(s, _)| *s >= seq) {
                Some((s, f)) if *s == seq => Some(Some(f.clone())),
                Some(_) => Some(None), // the SDK passed it (a gap): try another frame
                None => None,
            }
        });
        let Some(sdk) = sdk else { continue };
        assert_eq!(got["done"], 10_000, "every plant evaluated in the page");
        let angles = got["angles"].as_array().unwrap();
        assert_eq!(angles.len(), 120_000);
        for (i, page) in angles.chunks(12).enumerate() {
            let want = sdk.plant_pose(i, tau).unwrap_or_else(|| panic!("the SDK cannot evaluate plant {i}"));
            for (g, w) in page.iter().zip(want.iter().flatten()) {
                let g = g.as_f64().unwrap();
                worst = worst.max((g - f64::from(*w)).abs());
                spread = spread.max(f64::from(*w).abs());
            }
        }
        compared += 1;
        if compared == 3 {
            break;
        }
        std::thread::sleep(Duration::from_millis(150));
    }
    stop.store(true, Ordering::Relaxed);
    reader.join().unwrap();
    assert!(compared >= 2, "only {compared} frames compared");
    assert!(worst < 1e-4, "the page and the SDK differ by {worst} degrees");
    assert!(spread > 2.0, "the plants bend ({spread} degrees at most): a real comparison");

    // Drawn instanced: the meadow costs a draw call per level of detail of the rig's one
    // primitive, not one per plant, and every plant is an instance of one of them.
    let calls = d.script("return globalThis.frondMeadow.drawCalls();");
    assert_eq!(calls["plants"], 10_000, "{calls}");
    assert!(calls["instances"].as_u64().unwrap() <= 10_000 / 16, "batches of plants: {calls}");
    let meadow_calls = calls["meadow"].as_u64().unwrap();
    assert!((1..=2).contains(&meadow_calls), "{calls}");
    assert!(calls["near"].as_u64().unwrap() > 0, "some plants near enough for the full mesh: {calls}");
    // And it shows: the meadow covers a good part of the view.
    let cover = d.script("return globalThis.frondMeadow.coverage();").as_f64().unwrap();
    assert!(cover > 0.05, "the meadow covers {cover} of the view");
    super::save_screenshot(&d, "meadow.png");
    // The shader skins as three.js does: a plant drawn by the meadow covers the pixels the rig's
    // SkinnedMesh posed with the same angles covers (each alone, close up), and not those of
    // the rig at rest.
    for i in [0, 5_050, 9_999] {
        let v = d.script(&format!("return globalThis.frondMeadow.silhouettes({id}, {i});"));
        let (meadow, skinned, both) =
            (v["meadow"].as_f64().unwrap(), v["skinned"].as_f64().unwrap(), v["both"].as_f64().unwrap());
        let overlap = both / (meadow + skinned - both);
        let (rest, both_rest) = (v["rest"].as_f64().unwrap(), v["both_rest"].as_f64().unwrap());
        let rest_overlap = both_rest / (meadow + rest - both_rest);
        eprintln!("plant {i}: overlap {overlap:.3} posed, {rest_overlap:.3} at rest ({v})");
        assert!(skinned > 200.0 && overlap > 0.9, "plant {i}: {v}");
        assert!(rest_overlap < overlap - 0.1, "plant {i}: at rest {rest_overlap}, posed {overlap}: {v}");
    }
}
