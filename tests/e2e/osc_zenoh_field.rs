//! A running field into Blender from a daemon on the stage (issue 48, "fields from
//! `--from zenoh:`"): a `frond-zenoh` bridge publishes the daemon, `frond-osc --from zenoh:...`
//! relays the field whole (definition, layout chunks, every field frame) over OSC, and the
//! Blender add-on's own receiver (`field_receiver_check.py`: `frond_receiver.Receiver`, numpy,
//! no Blender) puts it together and evaluates every plant. For plants 0, 57 and 399 of a 20 x 20
//! field announcing 2, at 8 field frames, its angles equal the SDK's evaluation of the same
//! field frame as the daemon's socket gave it, within 1e-4 degrees, with the field steered by a
//! key (its bend turned) before.

use std::io::BufRead;
use std::path::Path;
use std::process::{Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use frond_e2e::{Proc, bin, start_zenoh_bridge, wait_for};

use crate::field_socket::{played_to, record_field};
use crate::meadow::daemon_with_sway;
use crate::zenoh::free_port;
use crate::zenoh_meadow::start_field;

#[test]
fn the_addons_receiver_evaluates_a_field_frond_osc_relays_from_zenoh() {
    let Some(py) = crate::python::python_with("numpy") else {
        crate::python::skip("no numpy in tests/python/.venv (run exporters/osc/tests/install-python.sh)");
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let daemon = daemon_with_sway(dir.path(), Duration::from_secs(2));
    let port = free_port();
    let stage = format!("oscfield{}", std::process::id());
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let _bridge = start_zenoh_bridge(
        Command::new(bin("frond-zenoh")),
        &daemon,
        &stage,
        "glove",
        &["--listen", &endpoint],
    );

    // The add-on's receiver, listening before anything is sent.
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../exporters/osc/tests/field_receiver_check.py");
    let mut checker = Command::new(py)
        .arg(script)
        .args(["--report", "0,57,399", "--updates", "8", "--timeout", "60"])
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("start field_receiver_check.py");
    let mut out = std::io::BufReader::new(checker.stdout.take().unwrap());
    let mut first = String::new();
    out.read_line(&mut first).unwrap();
    let udp: u16 = first.trim().strip_prefix("port ").and_then(|p| p.parse().ok()).expect("port N");
    let mut checker = Proc { child: checker, name: "field_receiver_check.py".into() };

    let stop = Arc::new(AtomicBool::new(false));
    let recorder = record_field(&daemon.socket_dir, stop.clone());
    let from = format!("zenoh:frond/{stage}/glove?connect={endpoint}");
    let osc = Command::new(bin("frond-osc"))
        .args(["--from", &from, "--target", &format!("127.0.0.1:{udp}")])
        .stdout(Stdio::null())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("start frond-osc");
    let _osc = Proc { child: osc, name: "frond-osc".into() };
    start_field(&daemon, 20, 20, "2");
    // The bend turned away from the authored direction: the receiver's rotation is exercised.
    daemon.frond_ok(&["field", "key", "left"]);

    let done = wait_for(Duration::from_secs(70), || checker.child.try_wait().ok().flatten().is_some());
    assert!(done, "the add-on's receiver did not finish");
    assert!(checker.child.wait().unwrap().success(), "the add-on's receiver failed (its stderr above)");
    let lines: Vec<serde_json::Value> =
        out.lines().map_while(Result::ok).map(|l| serde_json::from_str(&l).unwrap()).collect();
    stop.store(true, Ordering::Relaxed);
    let messages = recorder.join().unwrap();

    assert_eq!(lines.len(), 8 * 3);
    let (mut worst, mut turned) = (0.0f64, 0);
    for line in &lines {
        let (seq, plant) = (line["seq"].as_u64().unwrap(), line["plant"].as_u64().unwrap() as usize);
        let tau = line["tau"].as_f64().unwrap();
        let fields = played_to(&messages, seq, "the daemon's socket");
        let field = fields.by_source("field").expect("the field runs");
        assert_eq!((field.plants(), line["plants"].as_u64()), (400, Some(400)));
        assert_eq!(field.tau_s(), tau, "frame {seq}'s stream time, relayed through Zenoh and OSC");
        if field.state().controls().direction_deg != field.layout().authored_direction_deg {
            turned += 1;
        }
        let want = field.plant_pose(plant, tau).unwrap_or_else(|| panic!("plant {plant} at {seq} here"));
        let got: Vec<f64> = line["angles"].as_array().unwrap().iter().map(|a| a.as_f64().unwrap()).collect();
        assert_eq!(got.len(), 12);
        for (w, g) in want.iter().flatten().zip(&got) {
            worst = worst.max((f64::from(*w) - g).abs());
        }
        assert!(worst <= 1e-4, "plant {plant} at {seq}: the add-on's {got:?}, the SDK's {want:?}");
    }
    assert!(turned > 0, "the field key never turned the bend: the rotation was not checked");
    eprintln!("the add-on's receiver within {worst} degrees of the SDK's, through Zenoh and OSC");
}
