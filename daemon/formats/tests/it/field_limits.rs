//! Issue 14: every quantity of `field.json` that sizes memory or a loop (rows, cols, plant
//! count, start frames, delays, the live history) is refused beyond its documented limit with
//! an error naming the field, before anything is allocated for it. The expected verdicts are
//! written out from the documented limits (one hour at 30 FPS, a million cells), not taken
//! from the constants under test.

use frond_formats::field_json::FieldJson;
use frond_motion::clip::Clip;
use frond_motion::controls::FieldControls;
use frond_motion::field::{Field, FieldError, FieldParams, make_field};
use frond_motion::field_player::FieldPlayer;
use frond_motion::looping::Transitions;
use proptest::prelude::*;

const CELLS: u128 = 1_000_000;
const FRAMES: u64 = 108_000;

/// A valid 2 x 3 field over a 300-frame take at 30 FPS.
fn base() -> Field {
    let p = FieldParams {
        rows: 2,
        cols: 3,
        cell_m: 0.5,
        speed_m_s: 2.0,
        direction_deg: 0.0,
        density: 1.0,
        seed: 1,
    };
    make_field(&p, "t", 300, 30.0).unwrap()
}

/// `field.json` of [`base`] with `edit` applied to its JSON value.
fn json_with(edit: impl FnOnce(&mut serde_json::Value)) -> String {
    let mut v: serde_json::Value = serde_json::from_str(&base().to_json()).unwrap();
    edit(&mut v);
    v.to_string()
}

fn names(e: &FieldError, field: &str) -> bool {
    matches!(e, FieldError::OutOfRange { field: f, .. } if f == field)
}

fn clip() -> Clip {
    Clip::from_joints((0..16).map(|k| [[k as f32, 0.0, 0.0]; 4]), 30.0)
}

#[test]
fn the_issue_s_absurd_fields_are_refused_naming_the_field() {
    let e = Field::from_json(&json_with(|v| v["rows"] = 1_000_000_000u64.into())).unwrap_err();
    assert!(names(&e, "rows"), "{e}");
    assert!(e.to_string().contains("rows is 1000000000"), "{e}");
    let e =
        Field::from_json(&json_with(|v| v["plants"][0]["start_frame"] = (1u64 << 63).into())).unwrap_err();
    assert!(names(&e, "plants[0].start_frame"), "{e}");
    // A plant outside the grid would index past the live field's per-row table.
    let e = Field::from_json(&json_with(|v| v["plants"][4]["row"] = 2.into())).unwrap_err();
    assert!(names(&e, "plants[4].row"), "{e}");
    // More plants than cells.
    let e = Field::from_json(&json_with(|v| {
        let p = v["plants"][0].clone();
        let plants = v["plants"].as_array_mut().unwrap();
        for i in 6..7 {
            let mut q = p.clone();
            q["id"] = i.into();
            plants.push(q);
        }
    }))
    .unwrap_err();
    assert!(names(&e, "plants"), "{e}");
    // A field made in code is checked too: the player refuses it before sizing its history.
    let mut f = base();
    f.plants[1].start_frame = usize::MAX;
    let t = Transitions { pivot: 14, transitions: vec![14] };
    let e = FieldPlayer::try_new(f, clip(), &t, 1, FieldControls::default()).unwrap_err();
    assert!(names(&e, "plants[1].start_frame"), "{e}");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn grid_size_is_bounded(rows in prop_oneof![0u64..2000, any::<u64>()], cols in prop_oneof![0u64..2000, any::<u64>()]) {
        let text = json_with(|v| { v["rows"] = rows.into(); v["cols"] = cols.into(); });
        // The base plants lie in rows 0..2, cols 0..3: a smaller grid is refused for them.
        let fits = rows >= 1 && cols >= 1 && (rows as u128) * (cols as u128) <= CELLS;
        let plants_inside = rows >= 2 && cols >= 3;
        match Field::from_json(&text) {
            Ok(f) => prop_assert!(fits && plants_inside, "accepted {} x {}", f.rows, f.cols),
            Err(e) => {
                prop_assert!(!(fits && plants_inside), "refused a valid {rows} x {cols}: {e}");
                let named = ["rows", "cols", "rows x cols", "plants"].iter().any(|n| names(&e, n))
                    || matches!(&e, FieldError::OutOfRange { field, .. } if field.ends_with(".row") || field.ends_with(".col"))
                    // Beyond usize on a 32-bit target serde refuses the number itself.
                    || matches!(&e, FieldError::Json(_));
                prop_assert!(named, "{e}");
                if !fits && rows >= 1 && cols >= 1 && rows as u128 <= CELLS && cols as u128 <= CELLS {
                    prop_assert!(names(&e, "rows x cols"), "{e}");
                }
            }
        }
    }

    #[test]
    fn start_frames_are_bounded_by_the_take_and_size_a_bounded_history(
        frames in prop_oneof![1u64..=FRAMES, 1u64..=u64::MAX],
        start in prop_oneof![0u64..=FRAMES, any::<u64>()],
        which in 0usize..6,
    ) {
        let text = json_with(|v| {
            v["frames"] = frames.into();
            for p in v["plants"].as_array_mut().unwrap() { p["start_frame"] = 0.into(); }
            v["plants"][which]["start_frame"] = start.into();
        });
        match Field::from_json(&text) {
            Ok(f) => {
                prop_assert!(frames <= FRAMES && start < frames);
                // The live history: 60 s + the start offset + 1 s at the take's 30 FPS, plus 2.
                let t = Transitions { pivot: 14, transitions: vec![14] };
                let player = FieldPlayer::try_new(f, clip(), &t, 1, FieldControls::default()).unwrap();
                let most = 61 * 30 + FRAMES as usize + 2 + 1;
                prop_assert!(player.history_capacity() <= most, "{}", player.history_capacity());
            }
            Err(e) => {
                prop_assert!(frames > FRAMES || start >= frames, "refused frames {frames} start {start}: {e}");
                let field = format!("plants[{which}].start_frame");
                prop_assert!(names(&e, "frames") || names(&e, &field) || matches!(e, FieldError::Json(_)), "{e}");
                if frames <= FRAMES {
                    prop_assert!(names(&e, &field), "{e}");
                }
            }
        }
    }

    #[test]
    fn delays_are_bounded(delay in prop_oneof![0.0f64..4000.0, any::<f64>()]) {
        let mut f = base();
        f.plants[2].delay_s = delay;
        let ok = delay.is_finite() && (0.0..=3600.0).contains(&delay);
        match f.check() {
            Ok(()) => prop_assert!(ok, "accepted delay {delay}"),
            Err(e) => {
                prop_assert!(!ok, "refused delay {delay}: {e}");
                prop_assert!(names(&e, "plants[2].delay_s"), "{e}");
            }
        }
    }

    #[test]
    fn made_fields_always_pass_their_own_check(rows in 1usize..40, cols in 1usize..40, frames in 1usize..5000, speed in 0.01f64..10.0) {
        let p = FieldParams { rows, cols, cell_m: 0.3, speed_m_s: speed, direction_deg: 10.0, density: 0.7, seed: 3 };
        let f = make_field(&p, "t", frames, 30.0).unwrap();
        prop_assert!(Field::from_json(&f.to_json()).is_ok());
    }
}
