//! Layer recording (seed 000, section 5.3): while it runs, the hand's frames are published and
//! recorded as one of the rig's secondary elements (`leaf`, `petal`, ...).

use std::sync::Arc;

use frond_motion::{HandSample, PoseFrame, Rig};
use frond_protocol::control::StageKind;
use frond_protocol::{ElementId, ElementInfo, ElementKind};

use super::error::StageError;
use super::live::{BuiltStage, FixedReport, LiveStage, StageInfo, no_input};

/// Relabels the hand's frames as element `element`.
pub struct LayerStage {
    element: ElementId,
}

impl LayerStage {
    /// The hand becomes element `element`.
    pub fn new(element: ElementId) -> Self {
        LayerStage { element }
    }
}

impl LiveStage for LayerStage {
    fn on_hand(&mut self, _hand: &HandSample, _pose: &mut PoseFrame, element: &mut ElementId) {
        *element = self.element;
    }

    fn hand_element(&self) -> Option<ElementId> {
        Some(self.element)
    }
}

/// The element id of `rig`'s secondary element `layer` (`k + 1` for `rig.elements[k]`), or an
/// error naming the rig's elements.
pub fn layer_id(rig: &Rig, layer: &str) -> Result<ElementId, StageError> {
    let names: Vec<&str> = rig.elements.iter().map(|e| e.name.as_str()).collect();
    match names.iter().position(|n| *n == layer) {
        Some(i) => Ok(ElementId::new((i + 1) as u16)),
        None => Err(StageError::NoSuchLayer {
            rig: rig.name.clone(),
            layer: layer.to_string(),
            has: if names.is_empty() { "none".to_string() } else { names.join(", ") },
        }),
    }
}

/// The stage recording `layer` of `rig`, with `hand_source` naming the hand it relabels.
pub fn build(rig: &Rig, layer: &str, hand_source: &str) -> Result<BuiltStage, StageError> {
    let id = layer_id(rig, layer)?;
    Ok(BuiltStage {
        stage: Box::new(LayerStage::new(id)),
        info: StageInfo {
            kind: StageKind::Layer,
            report: Arc::new(FixedReport(format!("recording layer {layer}"))),
            elements: Vec::new(),
            hand_element: Some(ElementInfo {
                id,
                name: layer.to_string(),
                kind: ElementKind::Layer,
                source: hand_source.to_string(),
                rig: rig.name.clone(),
            }),
            accepts: no_input,
            rig: super::live::rig_info(rig),
            work: super::budget::TickWork::small("relabelled hand frames"),
        },
    })
}
