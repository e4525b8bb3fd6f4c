//! The console draws a meadow of mixed rigs (issue 48; seed 000, Eq. 6-7 and section 6.3): ten
//! thousand plants from the virtual glove, five thousand grass and five thousand flowers, two
//! live fields of one grid (`frond field start --name`, the flowers' `--rig flower`), each plant
//! evaluated in the page (`page/field.js`) from the field frames the console passes on and drawn
//! instanced with its field's own rig (`page/meadow.js`). The page's angles are checked against
//! the SDK's (`frond_sdk::field`, the daemon's own code), evaluated here from the same field
//! frames; the draw calls against the rigs and the plant count; a third field, of shrubs, is
//! started from the page's takes panel, and one key from the page steers all three.

use std::collections::{HashMap, VecDeque};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use frond_sdk::Subscriber;
use frond_sdk::field::LiveField;
use frond_webdriver::{Driver, browser, poll, start_session};
use serde_json::Value;

use super::start_console;

/// The meadow's fields: stage name, rig, the layout's seed.
const FIELDS: [(&str, &str, u64); 2] = [("grass", "grass", 3), ("flowers", "flower", 4)];
/// Plants of each field (50 rows of 100).
const EACH: usize = 5_000;

/// For each field (by stage name), the SDK's field after each of its last field frames, by the
/// frame's sequence number.
type Kept = Arc<Mutex<HashMap<String, VecDeque<(u64, LiveField)>>>>;

/// Reads `sub` until `stop`, keeping a copy of each field after each of its last 240 frames.
fn keep_fields(mut sub: Subscriber, kept: Kept, stop: Arc<AtomicBool>) {
    let mut last: HashMap<String, u64> = HashMap::new();
    while !stop.load(Ordering::Relaxed) {
        if sub.next_event().is_err() {
            continue;
        }
        for (name, _, _) in FIELDS {
            let Some(field) = sub.fields().by_source(name) else { continue };
            let Some(seq) = field.last_frame().map(|f| f.seq) else { continue };
            if last.get(name) == Some(&seq) {
                continue;
            }
            last.insert(name.to_string(), seq);
            let mut k = kept.lock().unwrap();
            let k = k.entry(name.to_string()).or_default();
            if k.len() == 240 {
                k.pop_front();
            }
            k.push_back((seq, field.clone()));
        }
    }
}

/// The page's evaluation of every plant of field `id` (stage `name`) against the SDK's after the
/// same field frame, at the page's stream time, for 3 frames (a few more tries: the SDK's copy
/// may not be kept yet, or be gone); the largest difference and the largest angle, degrees.
fn compare(d: &Driver, kept: &Kept, name: &str, id: u64) -> (f64, f64) {
    let (mut compared, mut worst, mut spread) = (0, 0.0f64, 0.0f64);
    for _ in 0..40 {
        let got = d.script(&format!(
            "const m = globalThis.frondMeadow, f = m.fields.get({id}); \
             return m.evaluated({id}, f.eval.tau);"
        ));
        let seq = got["seq"].as_u64().unwrap();
        let tau = got["tau"].as_f64().unwrap();
        if got["done"] != EACH {
            // The page lost stream frames (the console sends a slow page the newest): its
            // plants that need them keep their last pose until the trickle brings them again.
            eprintln!("{name}: the page evaluated {} plants at frame {seq}; another frame", got["done"]);
            continue;
        }
        let sdk = poll("the SDK after the page's frame", Duration::from_secs(5), || {
            let k = kept.lock().unwrap();
            match k.get(name).and_then(|k| k.iter().find(|(s, _)| *s >= seq)) {
                Some((s, f)) if *s == seq => Some(Some(f.clone())),
                Some(_) => Some(None), // the SDK passed it (a gap): try another frame
                None => None,
            }
        });
        let Some(sdk) = sdk else { continue };
        let angles = got["angles"].as_array().unwrap();
        assert_eq!(angles.len(), 12 * EACH);
        for (i, page) in angles.chunks(12).enumerate() {
            let want =
                sdk.plant_pose(i, tau).unwrap_or_else(|| panic!("the SDK cannot evaluate {name} plant {i}"));
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
    assert!(compared >= 2, "{name}: only {compared} frames compared");
    (worst, spread)
}

/// The ids of the page's fields by stage name, once each of `want` (name, plants) has every
/// plant evaluated; a note of the meadow's is a failure.
fn fields_evaluated(d: &Driver, want: &[(&str, usize)], within: Duration) -> HashMap<String, u64> {
    let want_js: Vec<String> = want.iter().map(|(n, p)| format!("['{n}', {p}]")).collect();
    let v = poll("the meadow's fields evaluated in the page", within, || {
        let v = d.script(&format!(
            "const m = globalThis.frondMeadow; if (!m) return null; \
             if (m.notes.length) return m.notes.join('; '); \
             const ids = {{}}; \
             for (const [name, n] of [{}]) for (const [id, f] of m.fields) \
               if (f.def.source === name && f.n === n && f.evaluated === n) ids[name] = id; \
             return Object.keys(ids).length === {} ? ids : null;",
            want_js.join(", "),
            want.len()
        ));
        match v {
            Value::Object(_) => Some(v),
            Value::String(s) => panic!("the meadow says: {s}"),
            _ => None,
        }
    });
    v.as_object().unwrap().iter().map(|(k, id)| (k.clone(), id.as_u64().unwrap())).collect()
}

/// The shader skins as three.js does: plant `i` of field `id` drawn by the meadow covers the
/// pixels its rig's SkinnedMesh posed with the same angles covers (each alone, close up), and
/// not those of the rig at rest.
fn skins_as_three_js(d: &Driver, id: u64, i: usize) {
    let v = d.script(&format!("return globalThis.frondMeadow.silhouettes({id}, {i});"));
    let (meadow, skinned, both) =
        (v["meadow"].as_f64().unwrap(), v["skinned"].as_f64().unwrap(), v["both"].as_f64().unwrap());
    let overlap = both / (meadow + skinned - both);
    let (rest, both_rest) = (v["rest"].as_f64().unwrap(), v["both_rest"].as_f64().unwrap());
    let rest_overlap = both_rest / (meadow + rest - both_rest);
    eprintln!("field {id} plant {i}: overlap {overlap:.3} posed, {rest_overlap:.3} at rest ({v})");
    assert!(skinned > 200.0 && overlap > 0.9, "field {id} plant {i}: {v}");
    assert!(
        rest_overlap < overlap - 0.1,
        "field {id} plant {i}: at rest {rest_overlap}, posed {overlap}: {v}"
    );
}

#[test]
fn the_console_draws_ten_thousand_plants_of_two_rigs_instanced_as_the_daemon_evaluates_them() {
    let Some((chromium, driver)) = browser() else { return };
    let dir = tempfile::tempdir().unwrap();
    let daemon = crate::meadow::daemon_with_sway(dir.path(), Duration::from_millis(1500));
    // The grass is the active rig (no --rig), the flowers name theirs.
    for (name, rig, seed) in FIELDS {
        let meadow = crate::meadow::compact_field_seeded(&daemon, "sway", 50, 100, seed);
        let mut args = vec!["field", "start", "--take", "sway", "--field", meadow.to_str().unwrap()];
        args.extend(["--plants", "4", "--name", name]);
        if rig != "grass" {
            args.extend(["--rig", rig]);
        }
        daemon.frond_ok(&args);
    }

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
    // The page has both fields and, once the trickle has brought the whole history, evaluates
    // every plant of each. Waited for and compared while the page does not draw (drawing 10,000
    // plants in software can take the page seconds a frame on a busy machine, and the SDK keeps
    // 4 s of frames): it then takes every field frame as it comes, and evaluates with the code
    // that animates; the drawing is checked after.
    let t0 = std::time::Instant::now();
    poll("the page's meadow", Duration::from_secs(20), || {
        d.script("const m = globalThis.frondMeadow; if (m) m.group.visible = false; return !!m;")
            .as_bool()
            .filter(|b| *b)
    });
    let ids = fields_evaluated(&d, &[("grass", EACH), ("flowers", EACH)], Duration::from_secs(40));
    eprintln!("both fields evaluated in the page after {:?}", t0.elapsed());
    d.script("globalThis.frondMeadow.animate = false;");
    for (name, _, _) in FIELDS {
        let (worst, spread) = compare(&d, &kept, name, ids[name]);
        assert!(worst < 1e-4, "{name}: the page and the SDK differ by {worst} degrees");
        assert!(spread > 2.0, "{name}: the plants bend ({spread} degrees at most): a real comparison");
    }
    eprintln!("compared after {:?}", t0.elapsed());
    d.script("const m = globalThis.frondMeadow; m.group.visible = true; m.animate = true;");

    // Drawn instanced, each field with its own rig: the meadow costs a draw call per level of
    // detail of each rig's primitives, not one per plant, and every plant is an instance of one.
    let calls = d.script("return globalThis.frondMeadow.drawCalls();");
    assert_eq!(calls["plants"], 2 * EACH, "{calls}");
    assert!(calls["instances"].as_u64().unwrap() <= 2 * EACH as u64 / 16, "batches of plants: {calls}");
    let mut drawn = 0;
    for (_, rig, _) in FIELDS {
        let r = &calls["rigs"][rig];
        assert_eq!(r["plants"], EACH, "{rig}: {calls}");
        assert_eq!(r["fields"], 1, "{rig}: {calls}");
        let levels = r["levels"].as_u64().unwrap();
        assert!((2..=8).contains(&levels), "{rig}: its primitives and the ribbon: {calls}");
        drawn += r["drawn"].as_u64().unwrap();
    }
    assert_eq!(calls["meadow"].as_u64().unwrap(), drawn, "a draw call per drawn level: {calls}");
    assert!((2..=16).contains(&drawn), "{calls}");
    assert!(calls["near"].as_u64().unwrap() > 0, "some plants near enough for the full mesh: {calls}");
    // And it shows: the meadow covers a good part of the view.
    let cover = d.script("return globalThis.frondMeadow.coverage();").as_f64().unwrap();
    assert!(cover > 0.05, "the meadow covers {cover} of the view");
    // The picture (the README's first): closer, where grass and flowers are told apart.
    d.script(
        "const m = globalThis.frondMeadow, p = [...m.fields.values()][0].positions; \
         let [x0, x1, z1] = [Infinity, -Infinity, -Infinity]; \
         for (let i = 0; i < p.length; i += 2) { x0 = Math.min(x0, p[i]); x1 = Math.max(x1, p[i]); z1 = Math.max(z1, p[i + 1]); } \
         m.camera.position.set((x0 + x1) / 2, 1.1, z1 + 2); \
         m.controls.target.set((x0 + x1) / 2, 0, z1 - 3); m.controls.update();",
    );
    std::thread::sleep(Duration::from_millis(500));
    d.script("return 0;"); // a frame drawn from there
    super::save_screenshot(&d, "meadow.png");
    eprintln!("drawn after {:?}", t0.elapsed());
    // Each plant alone, close up (the meadow itself not drawn meanwhile: the page is quicker).
    d.script("globalThis.frondMeadow.group.visible = false;");
    for (name, i) in [("grass", 0), ("grass", 2_525), ("flowers", 0), ("flowers", 4_999)] {
        skins_as_three_js(&d, ids[name], i);
    }
    eprintln!("silhouettes after {:?}", t0.elapsed());
    stop.store(true, Ordering::Relaxed);
    reader.join().unwrap();

    // A third rig from the page: the takes panel's Field button with shrubs chosen, a field of
    // its own (stage field-shrub) made with its rig; one key from the page steers every field
    // (still not drawing the meadow, so that the page takes the frames quickly: drawing was
    // checked above).
    let field_button = "#take-list tr[data-take=\"sway\"] .take-field";
    poll("the take's Field button and the shrub among the rigs", Duration::from_secs(10), || {
        let q = format!(
            "return !!document.querySelector('{field_button}') && \
             [...document.getElementById('field-rig').options].some((o) => o.value === 'shrub');"
        );
        d.script(&q).as_bool().filter(|b| *b)
    });
    d.script(&format!(
        "document.getElementById('field-rig').value = 'shrub'; document.querySelector('{field_button}').click();"
    ));
    let ids = fields_evaluated(&d, &[("field-shrub", 16)], Duration::from_secs(30));
    let shrub =
        d.script(&format!("return globalThis.frondMeadow.fields.get({}).rig.name;", ids["field-shrub"]));
    assert_eq!(shrub, "shrub");
    let post = |path: &str, body: &str| {
        d.script(&format!(
            "return fetch('{path}', {{method: 'POST', headers: {{'Content-Type': 'application/json'}}, \
             body: JSON.stringify({body})}}).then(async (r) => [r.status, await r.text()]);"
        ))
    };
    let refused = post("/api/field/start", "{take: 'sway', rig: '../../etc/passwd'}");
    assert_eq!(refused[0], 400, "{refused}");
    let keyed = post("/api/field/key", "{key: 'left'}");
    assert_eq!(keyed[0], 200, "{keyed}");
    let status: Value = serde_json::from_str(&daemon.frond_ok(&["status", "--json"])).unwrap();
    let fields: Vec<&Value> =
        status["stages"].as_array().unwrap().iter().filter(|s| s["kind"] == "field").collect();
    assert_eq!(fields.len(), 3, "{status}");
    for f in fields {
        assert!(f["state"].as_str().unwrap().contains("direction 180 deg"), "the key reached {f}");
    }
}
