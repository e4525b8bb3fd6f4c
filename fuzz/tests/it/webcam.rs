//! Fuzzes the webcam source's reader of the landmark helper's lines
//! (`frond_device::source::webcam::lines`): every line frond-hands prints goes through
//! `parse_line`, and a frame's chosen hand through `frame_sample`. Nothing may panic; a line
//! longer than its bound is refused; an accepted hand's angles are finite and in their ranges.

use frond_device::source::webcam::lines::{HelperLine, MAX_LINE_BYTES, frame_sample, parse_line};
use frond_fuzz::{Target, as_text, fuzz};
use frond_motion::hand_landmarks::Handedness;

/// A frame line as frond-hands prints it: a left hand held up, palm to the camera.
fn frame(side: &str) -> String {
    // World landmarks (metres, selfie view): wrist, thumb, then four straight fingers.
    let mut world = vec![
        0.0, 0.08, 0.0, -0.03, 0.06, -0.01, -0.05, 0.03, -0.015, -0.06, 0.0, -0.02, -0.065, -0.02, -0.02,
    ];
    for (f, x) in [-0.025f64, 0.0, 0.018, 0.035].iter().enumerate() {
        for j in 0..4 {
            world.extend([*x, -0.01 - 0.03 * j as f64 - 0.002 * f as f64, 0.0]);
        }
    }
    let list = |v: &[f64]| v.iter().map(|c| format!("{c}")).collect::<Vec<_>>().join(",");
    format!(
        r#"{{"v":1,"seq":7,"t_us":123456,"model_us":11000,"w":640,"h":480,"hands":[{{"side":"{side}","score":0.97,"world":[{}],"image":[{}]}}]}}"#,
        list(&world),
        list(&[0.5; 63])
    )
}

#[test]
fn fuzz_webcam_helper_lines() {
    let seeds: Vec<Vec<u8>> = [
        frame("left"),
        frame("right"),
        r#"{"v":1,"hello":"frond-hands","model":"mediapipe 0.10.21 hands","complexity":1}"#.into(),
        r#"{"v":1,"error":"cannot open camera /dev/video0"}"#.into(),
        r#"{"v":1,"seq":1,"t_us":1,"model_us":1,"w":640,"h":480,"hands":[]}"#.into(),
    ]
    .into_iter()
    .map(String::into_bytes)
    .collect();
    let dict = [
        b"\"hands\":[".to_vec(),
        b"\"side\":\"left\"".to_vec(),
        b"\"world\":[".to_vec(),
        b"1e308".to_vec(),
        b"-0.0".to_vec(),
        b"NaN".to_vec(),
        b"{\"v\":1,".to_vec(),
    ];
    let report = fuzz(Target::new("webcam-line").seeds(seeds).dict(dict).max_len(4096), |b| {
        let text = as_text(b);
        match parse_line(&text) {
            Err(e) => {
                assert!(!e.to_string().is_empty());
                "refused"
            }
            Ok(HelperLine::Frame(f)) => {
                assert!(text.len() <= MAX_LINE_BYTES);
                let mut label = "frame";
                for which in [Handedness::Left, Handedness::Right] {
                    if let Some(Ok(s)) = frame_sample(&f, which, 1.0) {
                        assert!(s.wrist_deg[..2].iter().all(|a| a.abs() < 90.0), "{s:?}");
                        assert!(s.wrist_deg[2].abs() <= 180.0, "{s:?}");
                        assert!(s.thumb_deg.iter().all(|a| (0.0..=180.0).contains(a)), "{s:?}");
                        label = "hand";
                    }
                }
                label
            }
            Ok(_) => "other",
        }
    });
    // Most mutations break the JSON; about 2 in 1000 still carry a hand.
    report.assert_reaches("hand", 1);
    report.assert_reaches("refused", 100);
}
