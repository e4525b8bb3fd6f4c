//! Live modes of the realtime loop built from the motion toolkit (seed 000, sections 5.3, 6.2-6.4):
//! a looped global take on the stream while a secondary layer is authored, field playback with
//! key and swipe controls, and guided procedural motion. Everything here is built (and may
//! allocate) on the control thread, then moved into the loop, which only calls allocation-free
//! methods on it.

use frond_motion::clip::Clip;
use frond_motion::controls::{ControlKey, FieldControls, SwipeDetector, SwipeParams};
use frond_motion::field::{Field, FieldPlayer};
use frond_motion::guided::{GuidedLive, GuidedParams};
use frond_motion::layers::Take;
use frond_motion::looping::{LoopParams, Playback, PlaybackParams, find_transitions};

/// Frame rate takes are looped at (seed 000 records at 30 FPS).
pub const LOOP_FPS: f64 = 30.0;
/// Most field plants published per field frame.
pub const MAX_FIELD_PLANTS: usize = 64;
/// Field frames per second on the stream (the field itself is a 30 FPS animation).
pub const FIELD_PUBLISH_HZ: u32 = 60;

/// The global layer of `take_bytes` as a 30 FPS clip with its loop transitions.
fn looped_clip(take_bytes: &[u8]) -> Result<(Clip, frond_motion::looping::Transitions), String> {
    let take = Take::from_bytes(take_bytes).map_err(|e| e.to_string())?;
    let clip = take.clip(0, LOOP_FPS);
    if clip.len() < 8 {
        return Err(format!(
            "the take's global layer has {} frames at 30 FPS; at least 8 are needed to loop",
            clip.len()
        ));
    }
    // Small takes get a smaller comparison window so Eq. 5 still finds candidates.
    let mut params = LoopParams::default();
    params.window = params.window.min((clip.len() - 2) / 4);
    let transitions = find_transitions(&clip, &params).map_err(|e| e.to_string())?;
    Ok((clip, transitions))
}

/// A take looping on the pose stream.
pub struct LivePlayback {
    /// The cursor.
    pub playback: Playback,
    /// Host time of its start.
    pub t0_ns: u64,
    /// Take name, for status.
    pub name: String,
}

impl LivePlayback {
    /// Loads and prepares a take's global layer for looping.
    pub fn new(name: &str, take_bytes: &[u8], seed: u64, t0_ns: u64) -> Result<Self, String> {
        let (clip, transitions) = looped_clip(take_bytes)?;
        let playback = Playback::new(clip, &transitions, seed, PlaybackParams::default(), 0);
        Ok(LivePlayback { playback, t0_ns, name: name.to_string() })
    }
}

/// A field playing on the pose stream, with its live controls.
pub struct LiveField {
    /// The player.
    pub player: FieldPlayer,
    /// One pose per plant, filled each field frame.
    pub out: Vec<frond_motion::clip::Joints>,
    /// Plants published per field frame.
    pub publish: usize,
    /// Swipe gestures of the wrist steer the controls.
    pub swipe: SwipeDetector,
    /// Propagation speed a normal swipe gives, m/s.
    pub base_speed_m_s: f64,
    /// Host time of its start.
    pub t0_ns: u64,
    /// Next host time a field frame is due.
    pub next_ns: u64,
}

impl LiveField {
    /// Loads a field of a looped take.
    pub fn new(
        take_bytes: &[u8],
        field_json: &str,
        plants: usize,
        seed: u64,
        t0_ns: u64,
    ) -> Result<Self, String> {
        let field = Field::from_json(field_json).map_err(|e| e.to_string())?;
        let (clip, transitions) = looped_clip(take_bytes)?;
        let n = field.plants.len();
        if n == 0 {
            return Err("the field has no plants".into());
        }
        let controls =
            FieldControls { direction_deg: field.authored_direction_deg, ..FieldControls::default() };
        let base_speed_m_s = field.speed_m_s.max(0.05);
        let controls = FieldControls { speed_m_s: base_speed_m_s, ..controls };
        let player = FieldPlayer::new(field, clip, &transitions, seed, controls);
        Ok(LiveField {
            player,
            out: vec![[[0.0; 3]; 4]; n],
            publish: plants.clamp(1, MAX_FIELD_PLANTS).min(n),
            swipe: SwipeDetector::new(SwipeParams::default()),
            base_speed_m_s,
            t0_ns,
            next_ns: t0_ns,
        })
    }

    /// One-line description of the controls, for status.
    pub fn describe(controls: &FieldControls) -> String {
        format!(
            "direction {:.0} deg, propagation {:.2} m/s, motion speed x{:.2}, scale x{:.2}, rigidity delays {:?} s",
            controls.direction_deg, controls.speed_m_s, controls.time_step, controls.scale, controls.delays_s
        )
    }
}

/// Parses a field key name.
pub fn parse_key(key: &str) -> Result<ControlKey, String> {
    Ok(match key {
        "left" => ControlKey::Left,
        "right" => ControlKey::Right,
        "up" => ControlKey::Up,
        "down" => ControlKey::Down,
        "stronger" | "+" => ControlKey::Stronger,
        "weaker" | "-" => ControlKey::Weaker,
        other => {
            return Err(format!(
                "unknown field key {other:?}: use left, right, up, down, stronger (+), weaker (-)"
            ));
        }
    })
}

/// Parses `sigma=S1,S2,S3;sg=G1,G2,G3` into guided-motion parameters (seed 000, Eq. 8).
pub fn parse_guided(spec: &str, g3_range_deg: f32) -> Result<GuidedParams, String> {
    let mut sigma = None;
    let mut sg = None;
    for part in spec.split(';').map(str::trim).filter(|p| !p.is_empty()) {
        let (key, values) = part.split_once('=').ok_or_else(|| format!("{part:?}: expected key=v1,v2,v3"))?;
        let v: Vec<f64> = values
            .split(',')
            .map(|x| x.trim().parse::<f64>().map_err(|_| format!("{key}: {x:?} is not a number")))
            .collect::<Result<_, _>>()?;
        let v: [f64; 3] =
            v.try_into().map_err(|v: Vec<f64>| format!("{key}: needs 3 values, got {}", v.len()))?;
        match key.trim() {
            "sigma" => sigma = Some(v),
            "sg" => sg = Some(v),
            other => return Err(format!("unknown guided-motion key {other:?}: use sigma and sg")),
        }
    }
    let params = GuidedParams {
        sigma_s: sigma.ok_or("guided motion needs sigma=S1,S2,S3 (seconds)")?,
        s_g: sg.unwrap_or([1.0; 3]),
        g3_range_deg,
    };
    params.validate()?;
    Ok(params)
}

/// A rig's `[guided]` table as a live stage and its spec text (for status), or `None`.
pub fn rig_guided(
    rig: &frond_motion::Rig,
    g3_range_deg: f32,
    rate_hz: u32,
) -> Option<(Box<GuidedLive>, String)> {
    let g = rig.guided?;
    let params = GuidedParams { sigma_s: g.sigma_s, s_g: g.s_g, g3_range_deg };
    params.validate().ok()?;
    let text = format!(
        "sigma={},{},{};sg={},{},{} (rig {})",
        g.sigma_s[0], g.sigma_s[1], g.sigma_s[2], g.s_g[0], g.s_g[1], g.s_g[2], rig.name
    );
    Some((Box::new(guided(params, rate_hz)), text))
}

/// Guided motion for a loop at `rate_hz`.
pub fn guided(params: GuidedParams, rate_hz: u32) -> GuidedLive {
    GuidedLive::new(params, f64::from(rate_hz))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn guided_spec_parses_and_reports_problems() {
        let p = parse_guided("sigma=0.1,0.2,0.3;sg=1,2,3", 60.0).unwrap();
        assert_eq!(p.sigma_s, [0.1, 0.2, 0.3]);
        assert_eq!(p.s_g, [1.0, 2.0, 3.0]);
        assert_eq!(parse_guided("sigma=0.1,0.2,0.3", 60.0).unwrap().s_g, [1.0; 3]);
        assert!(parse_guided("sg=1,1,1", 60.0).unwrap_err().contains("sigma"));
        assert!(parse_guided("sigma=1,2", 60.0).unwrap_err().contains("3 values"));
        assert!(parse_guided("sigma=a,1,1", 60.0).unwrap_err().contains("not a number"));
        assert!(parse_guided("sigma=-1,1,1", 60.0).is_err());
        assert!(parse_guided("tau=1,1,1", 60.0).unwrap_err().contains("unknown"));
    }

    #[test]
    fn keys_parse() {
        assert_eq!(parse_key("left"), Ok(ControlKey::Left));
        assert_eq!(parse_key("+"), Ok(ControlKey::Stronger));
        assert!(parse_key("jump").is_err());
    }
}
