//! A whole take in memory, with layers (seed 000, section 5.3): layer 0 is the global element
//! (the whole plant), layer `k + 1` a secondary element such as `leaf` or `petal`
//! (`TakeFrame::element`). Layer names live in the header record as an optional JSON list
//! `"elements": ["leaf", "petal"]` (name of layer 1, 2, ...); takes without it read as before and
//! their secondary layers are named after the rig element of the same index, or `element<k>`.
//!
//! [`assign_layers`] hands secondary layers to a rig's secondary element instances: by kind name
//! (a layer `leaf` or `leaf#2` animates leaves), at random among the layers of that kind when an
//! element has several similar instances.

use frond_protocol::ElementId;

use crate::clip::Clip;
use crate::rig::ElementSpec;
use crate::rng::SeededRng;
use crate::sample::{HandSample, PoseFrame};
pub use crate::take::{FLAG_HELD, FLAG_PLAYBACK};
use crate::take::{TakeFrame, TakeHeader};

/// Layer id of the global element.
pub const GLOBAL_LAYER: ElementId = ElementId::GLOBAL;

/// A take: header, secondary layer names, frames of every layer, markers.
#[derive(Debug, Clone, PartialEq)]
pub struct Take {
    /// Metadata.
    pub header: TakeHeader,
    /// Name of layer `k + 1` at index `k`; may be shorter than the number of layers.
    pub element_names: Vec<String>,
    /// All frames, every layer, in file order.
    pub frames: Vec<TakeFrame>,
    /// Markers as `(seq, label)`.
    pub markers: Vec<(u64, String)>,
}

impl Take {
    /// An empty take.
    pub fn new(header: TakeHeader) -> Self {
        Take { header, element_names: Vec::new(), frames: Vec::new(), markers: Vec::new() }
    }

    /// The layer the take's motion is read from: the global one when it has frames, else the
    /// lowest secondary layer (a take of `frond record layer` holds only its layer), see
    /// [`crate::take::main_element`]. `None` without frames.
    pub fn main_layer(&self) -> Option<ElementId> {
        crate::take::main_element(&self.frames)
    }

    /// The layer ids present, ascending.
    pub fn layer_ids(&self) -> Vec<ElementId> {
        let mut ids: Vec<ElementId> = self.frames.iter().map(|f| f.element).collect();
        ids.sort_unstable();
        ids.dedup();
        ids
    }

    /// A layer's name: `global` for 0, else its header name, else `element<k>`.
    pub fn layer_name(&self, id: ElementId) -> String {
        match id {
            GLOBAL_LAYER => "global".to_string(),
            k => self.element_names.get(k.index() - 1).cloned().unwrap_or_else(|| format!("element{k}")),
        }
    }

    /// The id of a layer given by name (`global`, a header name, `element<k>`) or number.
    pub fn layer_id(&self, name: &str) -> Option<ElementId> {
        if let Ok(k) = name.parse::<ElementId>() {
            return Some(k);
        }
        if name == "global" {
            return Some(GLOBAL_LAYER);
        }
        if let Some(k) = self.element_names.iter().position(|n| n == name) {
            return Some(ElementId::new(k as u16 + 1));
        }
        name.strip_prefix("element").and_then(|k| k.parse().ok())
    }

    /// The frames of one layer, held frames dropped unless `include_held`.
    pub fn layer(&self, id: ElementId, include_held: bool) -> Vec<TakeFrame> {
        self.frames
            .iter()
            .filter(|f| f.element == id && (include_held || f.flags & FLAG_HELD == 0))
            .copied()
            .collect()
    }

    /// One layer resampled to `fps` (held frames dropped), starting at 0.
    pub fn clip(&self, id: ElementId, fps: f64) -> Clip {
        let poses: Vec<PoseFrame> = self.layer(id, false).iter().map(|f| f.pose).collect();
        Clip::from_poses(&poses, fps)
    }

    /// Replaces a layer's frames (and names it, for a secondary layer). The new frames are put
    /// after the other layers' frames.
    pub fn set_layer(
        &mut self,
        id: ElementId,
        name: Option<&str>,
        frames: impl IntoIterator<Item = TakeFrame>,
    ) {
        self.frames.retain(|f| f.element != id);
        self.frames.extend(frames.into_iter().map(|mut f| {
            f.element = id;
            f
        }));
        if let (Some(name), false) = (name, id.is_global()) {
            let k = id.index() - 1;
            while self.element_names.len() <= k {
                let n = self.element_names.len() + 1;
                self.element_names.push(format!("element{n}"));
            }
            self.element_names[k] = name.to_string();
        }
    }

    /// The time of the frame a marker points at, seconds from the first global frame.
    pub fn marker_time(&self, label: &str) -> Option<f64> {
        let (seq, _) = self.markers.iter().find(|(_, l)| l == label)?;
        let global = self.layer(GLOBAL_LAYER, true);
        let t0 = global.first()?.pose.t;
        let f = global.iter().find(|f| f.seq >= *seq)?;
        Some(f.pose.t - t0)
    }
}

/// Frames for a layer from a clip, `seq = k`, device time `t` in microseconds, with hand samples
/// when given (index `k`, else zero).
pub fn frames_from_clip(
    clip: &Clip,
    element: ElementId,
    flags: u32,
    hands: Option<&[HandSample]>,
) -> Vec<TakeFrame> {
    clip.frames
        .iter()
        .enumerate()
        .map(|(k, p)| TakeFrame {
            seq: k as u64,
            device_time_us: (p.t * 1e6).round().max(0.0) as u64,
            host_ns: 0,
            flags,
            element,
            pose: *p,
            hand: hands
                .and_then(|h| h.get(k))
                .copied()
                .unwrap_or(HandSample { t: p.t, ..Default::default() }),
        })
        .collect()
}

/// A secondary layer chosen for one element instance.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Assignment {
    /// Index into the rig's elements.
    pub element: usize,
    /// Instance number, `0..count`.
    pub instance: u32,
    /// The layer animating it, `None` when the take has no layer of that kind.
    pub layer: Option<ElementId>,
}

/// The kind of a layer name: the part before `#` (`leaf#2` is a `leaf`).
pub fn layer_kind(name: &str) -> &str {
    name.split('#').next().unwrap_or(name)
}

/// Assigns secondary layers (id, name) to every instance of the rig's elements (seed 000,
/// section 5.3): an instance of element `leaf` gets one of the layers of kind `leaf`, uniformly at
/// random with the seeded generator (similar elements share the authored animations randomly);
/// elements of a kind with no layer stay unanimated.
pub fn assign_layers(elements: &[ElementSpec], layers: &[(ElementId, String)], seed: u64) -> Vec<Assignment> {
    let mut rng = SeededRng::new(seed);
    let mut out = Vec::new();
    for (e, spec) in elements.iter().enumerate() {
        let candidates: Vec<ElementId> = layers
            .iter()
            .filter(|(id, n)| !id.is_global() && layer_kind(n) == spec.name)
            .map(|(id, _)| *id)
            .collect();
        for instance in 0..spec.count {
            let layer = match candidates.len() {
                0 => None,
                1 => Some(candidates[0]),
                n => Some(candidates[rng.below(n)]),
            };
            out.push(Assignment { element: e, instance, layer });
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flags_match_the_protocol() {
        assert_eq!(FLAG_HELD, frond_protocol::PoseFlags::HELD.0);
        assert_eq!(FLAG_PLAYBACK, frond_protocol::PoseFlags::PLAYBACK.0);
    }

    #[test]
    fn assignment_by_name_and_at_random_among_similar() {
        let el = |name: &str, count| ElementSpec {
            name: name.into(),
            attach_joint: 1,
            count,
            length_m: 0.1,
            tau: 2,
        };
        let elements = [el("leaf", 40), el("petal", 2), el("thorn", 1)];
        let layers = [(1, "leaf".to_string()), (2, "leaf#2".to_string()), (3, "petal".to_string())]
            .map(|(id, n)| (ElementId::new(id), n));
        let a = assign_layers(&elements, &layers, 9);
        assert_eq!(a.len(), 43);
        let leaves: Vec<u16> = a.iter().filter(|x| x.element == 0).map(|x| x.layer.unwrap().get()).collect();
        assert!(leaves.contains(&1) && leaves.contains(&2) && !leaves.contains(&3));
        assert!(a.iter().filter(|x| x.element == 1).all(|x| x.layer == Some(ElementId::new(3))));
        assert_eq!(a.last().unwrap().layer, None);
        assert_eq!(assign_layers(&elements, &layers, 9), a);
    }
}
