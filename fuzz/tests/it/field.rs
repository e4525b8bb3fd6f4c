//! Fuzzes `field.json` (issue 4's field of plants): `frond_motion::field::Field::from_json`.
//! An accepted field is internally consistent (plant ids are their indices, sources exist,
//! delays finite and >= 0) and its own `to_json` reads back.

use frond_formats::field_json::FieldJson;
use frond_fuzz::{Target, as_text, assert_message, fuzz};
use frond_motion::field::{Field, FieldError, FieldParams, make_field};

#[test]
fn fuzz_field_files() {
    let params = |rows, cols, density, seed| FieldParams {
        rows,
        cols,
        cell_m: 0.2,
        speed_m_s: 1.5,
        direction_deg: 30.0,
        density,
        seed,
    };
    let seeds: Vec<String> = [
        make_field(&params(1, 1, 1.0, 1), "sway", 90, 30.0),
        make_field(&params(2, 3, 1.0, 7), "sway-loop", 1800, 30.0),
        make_field(&params(3, 4, 0.5, 9), "t", 300, 24.0),
    ]
    .into_iter()
    .map(|f| f.expect("seed field").to_json())
    .collect();
    for s in &seeds {
        Field::from_json(s).expect("seed fields read back");
    }
    let dict = [
        "\"version\"",
        "\"take\"",
        "\"fps\"",
        "\"frames\"",
        "\"rows\"",
        "\"cols\"",
        "\"cell_m\"",
        "\"speed_m_s\"",
        "\"direction_deg\"",
        "\"authored_direction_deg\"",
        "\"density\"",
        "\"seed\"",
        "\"plants\"",
        "\"id\"",
        "\"row\"",
        "\"col\"",
        "\"position_m\"",
        "\"source\"",
        "\"delay_s\"",
        "\"start_frame\"",
        "\"scale\"",
        "{ \"id\": 0, \"row\": 0, \"col\": 0, \"position_m\": [0.1, 0.2], \"source\": 0, \"delay_s\": 0.0, \
         \"start_frame\": 3, \"scale\": 1.0 }",
    ];
    let report =
        fuzz(Target::new("field").seeds(&seeds).text().dict(dict).max_len(8192), |b| match Field::from_json(
            &as_text(b),
        ) {
            Ok(f) => {
                for (i, p) in f.plants.iter().enumerate() {
                    assert_eq!(p.id, i);
                    assert!(p.source < f.plants.len());
                    assert!(p.delay_s.is_finite() && p.delay_s >= 0.0);
                }
                // `position_m` / `scale` beyond f32 (1e39 reads as inf, corpus/field/
                // crash-22ef80b4111d7194) used to be accepted; `Field::check` refuses them now.
                assert!(
                    f.plants
                        .iter()
                        .all(|p| p.scale.is_finite() && p.position_m.iter().all(|v| v.is_finite()))
                );
                assert!(f.check().is_ok());
                let again = Field::from_json(&f.to_json()).expect("a field's own JSON reads back");
                assert_eq!(again.plants.len(), f.plants.len());
                "ok"
            }
            Err(e @ (FieldError::Json(_) | FieldError::Invalid(_) | FieldError::OutOfRange { .. })) => {
                assert_message(&e);
                "refused"
            }
        });
    report.assert_reaches("ok", 20);
    report.assert_reaches("refused", 100);
}
