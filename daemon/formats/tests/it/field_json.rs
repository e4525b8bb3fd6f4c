//! `field.json` and the loop analysis's JSON: a field reads back as written, a malformed file or
//! another version is refused with `field.json:` and the reason, and `--explain` prints the
//! transition frames as one JSON object.

use frond_formats::field_json::{FieldJson, TransitionsJson};
use frond_motion::field::{Field, FieldParams, make_field};
use frond_motion::looping::Transitions;

#[test]
fn json_round_trip_and_errors() {
    let p = FieldParams {
        rows: 3,
        cols: 6,
        cell_m: 0.5,
        speed_m_s: 2.0,
        direction_deg: 0.0,
        density: 0.5,
        seed: 3,
    };
    let f = make_field(&p, "t", 50, 30.0).unwrap();
    assert_eq!(Field::from_json(&f.to_json()).unwrap(), f);
    assert!(f.to_json().ends_with("}\n"), "pretty, with a trailing newline");
    assert!(Field::from_json("{}").unwrap_err().to_string().starts_with("field.json: missing field"));
    let mut g = f.clone();
    g.version = 9;
    assert!(Field::from_json(&g.to_json()).unwrap_err().to_string().contains("version 9"));
}

#[test]
fn explain_prints_the_pivot_and_the_transitions() {
    let t = Transitions { pivot: 10, transitions: vec![2, 4, 8, 10] };
    assert_eq!(t.explain_json(), r#"{"pivot":10,"transitions":[2,4,8,10]}"#);
}
