//! A whole live field into Blender (issue 48: a subscriber that draws a field evaluates each
//! plant itself): `frond field start` plays a known take on a 20 x 20 field announcing only 2
//! plants; frond-osc sends the field whole (definition, layout in chunks, every field frame);
//! frond's add-on in Blender (bpy, headless) evaluates all 400 plants with its numpy port of
//! `frond_motion::field_eval` and drives each plant's armature of the GLB frond-gltf baked from
//! the same field file. For plants 0, 57 and 399 (two of them never announced) and several
//! updates, the add-on's angles equal the SDK's evaluation of the same field frame, played here
//! from what the daemon sent on its socket, within 1e-4 degrees, and the bones Blender computed
//! equal forward kinematics of them (`blender_meadow_check.py` checks the recorded actions).

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use crate::blender::{
    blender_fk, blender_tools, close, f64s, field_with_glb, os, run_frond, start_script, write_take,
};
use crate::support::field_socket::{played_to, record_field};
use crate::support::*;

#[test]
fn blender_addon_evaluates_every_plant_of_a_live_field() {
    evaluates_every_plant(false);
}

/// The same with only plant 0 imported: the add-on builds the 399 others from the layout it
/// received (`build_field`), each where Blender's importer had placed it (the script compares
/// every armature's and mesh's world matrix with the full import's), and drives them.
#[test]
fn blender_addon_builds_the_plants_of_a_live_field_from_one() {
    evaluates_every_plant(true);
}

fn evaluates_every_plant(build: bool) {
    let Some((frondd, py, gltf)) = blender_tools() else { return };
    let frond = frondd.with_file_name("frond");
    let daemon = start_daemon(&frondd);
    let tmp = tempfile::tempdir().unwrap();
    let rig = frond_formats::rig_files::load_rig("grass").unwrap().rig;
    let take = write_take(&daemon.takes_dir, "sway", "grass", 150, true);
    let run_frond = |args: &[&str]| run_frond(&frond, &daemon, args);
    let (field, glb) = field_with_glb(&frond, &gltf, &daemon, &take, tmp.path(), ["20", "20", "0.3"], "0.2");
    let field_s = field.to_str().unwrap();
    let out = tmp.path().join("meadow.jsonl");
    let plants = ["0", "57", "399"];
    let args = [
        "--plants",
        "400",
        "--report",
        "0,57,399",
        "--updates",
        "8",
        "--record",
        "5",
        "--timeout",
        "60",
        "--out",
    ];
    let mut args = os(&args);
    args.extend([out.as_os_str(), "--glb".as_ref(), glb.as_os_str()]);
    if build {
        args.push("--build".as_ref());
    }
    let (mut blender, port) = start_script(&py, "blender_meadow_check.py", &args, "port ");
    let stop = Arc::new(AtomicBool::new(false));
    let recorder = record_field(&daemon.socket_dir, Arc::clone(&stop));
    run_frond(&["field", "start", "--take", "sway", "--field", field_s, "--plants", "2"]);
    // The bend turned away from the authored direction: the add-on's rotation is exercised.
    run_frond(&["field", "key", "left"]);
    let osc = start_osc(&daemon.socket_dir, &["--target", &format!("127.0.0.1:{port}")]);
    wait_receiver(&mut blender);
    stop.store(true, Ordering::Relaxed);
    let messages = recorder.join().unwrap();
    stop_and_stderr(osc);

    let lines = read_jsonl(&out);
    let (timing, lines) = lines.split_last().expect("lines");
    eprintln!("the add-on per update at 400 plants: {}", timing["timing"]);
    assert_eq!(lines.len(), 8 * plants.len());
    let (mut worst, mut bent, mut turned) = (0.0f64, 0, 0);
    for line in lines {
        let (seq, plant) = (line["seq"].as_u64().unwrap(), line["plant"].as_u64().unwrap() as usize);
        let tau = line["tau"].as_f64().unwrap();
        let fields = played_to(&messages, seq, "the socket");
        let field = fields.by_source("field").expect("the field runs");
        assert_eq!(field.plants(), 400);
        assert_eq!(field.tau_s(), tau, "frame {seq}'s stream time");
        if field.state().controls().direction_deg != field.layout().authored_direction_deg {
            turned += 1;
        }
        let want = field.plant_pose(plant, tau).unwrap_or_else(|| panic!("plant {plant} at {seq} here"));
        let got = f64s(&line["angles"]);
        assert_eq!(got.len(), 12);
        for (w, g) in want.iter().flatten().zip(&got) {
            worst = worst.max((f64::from(*w) - g).abs());
        }
        assert!(worst <= 1e-4, "plant {plant} at {seq}: the add-on's {got:?}, the SDK's {want:?}");
        assert_eq!(line["armature"].as_str(), Some(format!("grass_{plant:03}").as_str()));
        let (heads, dirs) = blender_fk(want, &rig);
        for j in 0..4 {
            let what = format!("plant {plant} joint {j} at {seq}");
            close(&f64s(&line["heads"][j]), &heads[j], 1e-4, &format!("{what}: head"));
            close(&f64s(&line["dirs"][j]), &dirs[j], 1e-4, &format!("{what}: direction"));
        }
        if dirs[3][2] < 5f64.to_radians().cos() {
            bent += 1;
        }
    }
    eprintln!("the add-on's angles within {worst} degrees of the SDK's");
    assert!(
        bent >= lines.len() / 4,
        "only {bent} of {} plant poses bend: the check would not see much",
        lines.len()
    );
    assert!(turned > 0, "the field key never turned the bend: the add-on's rotation was not checked");
}
