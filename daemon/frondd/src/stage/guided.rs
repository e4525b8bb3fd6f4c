//! Guided procedural motion on the live mapping (seed 000, Eq. 8): joints 1..3 follow the root
//! with delays set by the thumb's bend.

use frond_protocol::ElementId;
use std::sync::Arc;

use frond_motion::guided::{GuidedLive, GuidedParams};
use frond_motion::{HandSample, PoseFrame};
use frond_protocol::control::StageKind;

use super::error::{BuildError, StageError};
use super::live::{BuildContext, BuiltStage, FixedReport, LiveStage, StageInfo, no_input};

/// Eq. 8 applied to every hand pose.
pub struct GuidedStage {
    guided: GuidedLive,
}

impl GuidedStage {
    /// Guided motion for a loop at `rate_hz`.
    pub fn new(params: GuidedParams, rate_hz: u32) -> Self {
        GuidedStage { guided: GuidedLive::new(params, f64::from(rate_hz)) }
    }
}

impl LiveStage for GuidedStage {
    fn on_hand(&mut self, hand: &HandSample, pose: &mut PoseFrame, _element: &mut ElementId) {
        *pose = self.guided.apply(pose, hand);
    }
}

/// Parses `sigma=S1,S2,S3;sg=G1,G2,G3` into guided-motion parameters (seed 000, Eq. 8).
pub fn parse_guided(spec: &str, g3_range_deg: f32) -> Result<GuidedParams, StageError> {
    let bad = StageError::Guided;
    let mut sigma = None;
    let mut sg = None;
    for part in spec.split(';').map(str::trim).filter(|p| !p.is_empty()) {
        let (key, values) =
            part.split_once('=').ok_or_else(|| bad(format!("{part:?}: expected key=v1,v2,v3")))?;
        let v: Vec<f64> = values
            .split(',')
            .map(|x| x.trim().parse::<f64>().map_err(|_| bad(format!("{key}: {x:?} is not a number"))))
            .collect::<Result<_, _>>()?;
        let v: [f64; 3] =
            v.try_into().map_err(|v: Vec<f64>| bad(format!("{key}: needs 3 values, got {}", v.len())))?;
        match key.trim() {
            "sigma" => sigma = Some(v),
            "sg" => sg = Some(v),
            other => return Err(bad(format!("unknown guided-motion key {other:?}: use sigma and sg"))),
        }
    }
    let params = GuidedParams {
        sigma_s: sigma.ok_or_else(|| bad("guided motion needs sigma=S1,S2,S3 (seconds)".into()))?,
        s_g: sg.unwrap_or([1.0; 3]),
        g3_range_deg,
    };
    params.validate().map_err(|e| bad(e.to_string()))?;
    Ok(params)
}

fn built(params: GuidedParams, text: String, ctx: &BuildContext) -> BuiltStage {
    BuiltStage {
        stage: Box::new(GuidedStage::new(params, ctx.tick_rate_hz)),
        info: StageInfo {
            kind: StageKind::Guided,
            report: Arc::new(FixedReport(format!("guided motion {text}"))),
            elements: Vec::new(),
            hand_element: None,
            accepts: no_input,
            rig: super::live::rig_info(ctx.rig),
            work: super::budget::TickWork::small("guided hand frames"),
        },
    }
}

/// Builds guided motion from a spec text.
pub fn build(spec: &str, ctx: &BuildContext) -> Result<BuiltStage, BuildError> {
    let params = parse_guided(spec, ctx.g3_range_deg)
        .map_err(|e| BuildError::invalid(format!("guided motion {spec:?}: {e}")))?;
    Ok(built(params, spec.to_string(), ctx))
}

/// The rig's `[guided]` table as a stage, or `None` when it has none (or an invalid one, which
/// the rig's own validation already refused).
pub fn from_rig(ctx: &BuildContext) -> Option<BuiltStage> {
    let rig = ctx.rig;
    let g = rig.guided?;
    let params = GuidedParams { sigma_s: g.sigma_s, s_g: g.s_g, g3_range_deg: ctx.g3_range_deg };
    params.validate().ok()?;
    let text = format!(
        "sigma={},{},{};sg={},{},{} (rig {})",
        g.sigma_s[0], g.sigma_s[1], g.sigma_s[2], g.s_g[0], g.s_g[1], g.s_g[2], rig.name
    );
    Some(built(params, text, ctx))
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
        assert!(parse_guided("sg=1,1,1", 60.0).unwrap_err().to_string().contains("sigma"));
        assert!(parse_guided("sigma=1,2", 60.0).unwrap_err().to_string().contains("3 values"));
        assert!(parse_guided("sigma=a,1,1", 60.0).unwrap_err().to_string().contains("not a number"));
        assert!(parse_guided("sigma=-1,1,1", 60.0).is_err());
        assert!(parse_guided("tau=1,1,1", 60.0).unwrap_err().to_string().contains("unknown"));
    }
}
