//! `frond-warp cage build` and `cage coords` (seed 004, sections 5.2-5.3): the cage tree of a
//! generated layer judged by shapely, mean value coordinates against a second implementation,
//! and clear errors for bad masks, options and cage files.

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::common;
use common::{run, s, stderr};

#[path = "../../../../tests/support/python.rs"]
mod python;

const W: usize = 160;
const H: usize = 120;

/// A plant of three overlapping discs (a crown with lobes) and a smaller plant apart from it.
fn matte() -> Vec<u8> {
    let discs = [(60.0, 60.0, 30.0), (85.0, 45.0, 24.0), (80.0, 80.0, 20.0), (138.0, 90.0, 14.0)];
    (0..W * H)
        .map(|i| {
            let (x, y) = ((i % W) as f64 + 0.5, (i / W) as f64 + 0.5);
            if discs.iter().any(|&(cx, cy, r)| (x - cx).hypot(y - cy) < r) { 255 } else { 0 }
        })
        .collect()
}

fn write_mask(dir: &Path, name: &str, matte: &[u8]) -> PathBuf {
    let p = dir.join(name);
    image::save_buffer(&p, matte, W as u32, H as u32, image::ColorType::L8).unwrap();
    p
}

#[test]
fn a_built_tree_passes_shapely_and_its_coordinates_match_floaters() {
    let t = tempfile::tempdir().unwrap();
    let m = matte();
    let mask = write_mask(t.path(), "mask.png", &m);
    let cage = t.path().join("cage.json");
    let o = run(&["cage", "build", "--layer", s(&mask), "-o", s(&cage)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("wrote 26 cages (2 crowns, 18 leaves, 3 levels deep)"), "{}", stderr(&o));
    let tree: serde_json::Value = serde_json::from_slice(&std::fs::read(&cage).unwrap()).unwrap();
    let crowns: Vec<&serde_json::Value> =
        tree["cages"].as_array().unwrap().iter().filter(|c| c["parent"].is_null()).collect();
    let crown = crowns.iter().find(|c| c["vertices"][0][0].as_f64().unwrap() < 120.0).unwrap();
    let id = crown["id"].as_u64().unwrap().to_string();
    let v = |k: usize, a: usize| crown["vertices"][k][a].as_f64().unwrap();
    // Inside, outside, at a vertex, on an edge's midpoint, a hair inside that edge.
    let (mx, my) = ((v(0, 0) + v(1, 0)) / 2.0, (v(0, 1) + v(1, 1)) / 2.0);
    let points = [
        "70,60".to_string(),
        "85,45".to_string(),
        "150,10".to_string(),
        format!("{},{}", v(5, 0), v(5, 1)),
        format!("{mx},{my}"),
        format!("{mx},{}", my + 1e-10),
    ];
    let mut args = vec!["cage", "coords", "--cage", s(&cage), "--id", &id];
    for p in &points {
        args.extend(["--at", p]);
    }
    let o = run(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    let coords = t.path().join("coords.json");
    std::fs::write(&coords, &o.stdout).unwrap();
    let rows: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(rows["points"][3]["weights"][5], 1.0, "at vertex 5 the weight is vertex 5's");
    assert_eq!(rows["points"].as_array().unwrap().len(), points.len());
    let raw = t.path().join("matte.raw");
    std::fs::write(&raw, &m).unwrap();
    let Some(py) = python::python_with("shapely, numpy") else {
        return python::skip(
            "shapely is not in tests/python/.venv (run exporters/warp/tests/install-python.sh)",
        );
    };
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/cage_check.py");
    python::python_check(&py, &script, &[s(&cage), s(&raw), &W.to_string(), &H.to_string(), s(&coords)]);
}

#[test]
fn an_rgba_layer_builds_on_its_alpha_and_options_shape_the_tree() {
    let t = tempfile::tempdir().unwrap();
    let shrub = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../rig-files/images/shrub.png");
    let o = run(&["cage", "build", "--layer", s(&shrub), "-o", "-"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let tree: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(tree["cages"].as_array().unwrap().len(), 13, "1 crown, 3 lobes, 9 inner lobes");
    let o = run(&[
        "cage",
        "build",
        "--layer",
        s(&shrub),
        "--levels",
        "2",
        "--lobes",
        "4",
        "--vertices",
        "32",
        "-o",
        "-",
    ]);
    let tree: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let cages = tree["cages"].as_array().unwrap();
    assert_eq!(cages.len(), 5);
    assert!(cages.iter().all(|c| c["vertices"].as_array().unwrap().len() == 32));
    let _ = t;
}

#[test]
fn bad_masks_options_and_cage_files_are_refused_by_name() {
    let t = tempfile::tempdir().unwrap();
    let empty = write_mask(t.path(), "empty.png", &vec![0; W * H]);
    let out = t.path().join("cage.json");
    let o = run(&["cage", "build", "--layer", s(&empty), "-o", s(&out)]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("marks no vegetation part of at least 16 pixels"), "{}", stderr(&o));
    assert!(!out.exists(), "nothing written on failure");
    let mask = write_mask(t.path(), "mask.png", &matte());
    let o = run(&[
        "cage",
        "build",
        "--layer",
        s(&mask),
        "--levels",
        "9",
        "--vertices",
        "3",
        "--lobes",
        "1",
        "-o",
        s(&out),
    ]);
    let e = stderr(&o);
    assert!(
        e.contains("--levels: 9 is outside 1..=5") && e.contains("--vertices: 3") && e.contains("--lobes: 1"),
        "{e}"
    );
    let fifo = t.path().join("fifo");
    assert!(Command::new("mkfifo").arg(&fifo).status().unwrap().success());
    let o = run(&["cage", "build", "--layer", s(&fifo), "-o", s(&out)]);
    assert!(stderr(&o).contains("not a regular file"), "{}", stderr(&o));

    // A hand-written cage file with mistakes: each is named by cage and vertex.
    let bad = t.path().join("bad.json");
    std::fs::write(
        &bad,
        r#"{"version":1,"size":[100,100],"cages":[
        {"id":1,"parent":null,"kind":"internal","vertices":[[10,10],[90,10],[90,90],[10,90]]},
        {"id":2,"parent":1,"kind":"leaf","vertices":[[20,20],[20,50],[50,50],[50,20]]},
        {"id":3,"parent":1,"kind":"leaf","vertices":[[60,20],[95,20],[80,50]]}]}"#,
    )
    .unwrap();
    let o = run(&["cage", "coords", "--cage", s(&bad), "--id", "1", "--at", "5,5"]);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(1));
    assert!(e.contains("cages[1] (id 2): vertices run clockwise"), "{e}");
    assert!(e.contains("cages[2] (id 3) vertex 1: [95, 20] lies outside its parent cage id 1"), "{e}");
    let o = run(&["cage", "coords", "--cage", s(&bad), "--id", "1", "--at", "5;5"]);
    assert!(stderr(&o).contains("cage file"), "the file is checked first: {}", stderr(&o));
    std::fs::write(&bad, "{\"version\":1,\"size\":[10,10],\"cages\":[{\"id\":0,\"parent\":null,\"kind\":\"leaf\",\"vertices\":[[1,1],[9,1],[5,9]]}]}").unwrap();
    let o = run(&["cage", "coords", "--cage", s(&bad), "--id", "7", "--at", "5,5"]);
    assert!(stderr(&o).contains("--id 7: no such cage (ids: 0)"), "{}", stderr(&o));
    let o = run(&["cage", "coords", "--cage", s(&bad), "--id", "0", "--at", "5,nan"]);
    assert!(stderr(&o).contains("--at \"5,nan\": expected X,Y"), "{}", stderr(&o));
    let o = run(&["cage", "coords", "--cage", s(&bad), "--id", "0", "--at", "-2,5"]);
    assert!(o.status.success(), "a point outside the cage has coordinates too: {}", stderr(&o));
}
