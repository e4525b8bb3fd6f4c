//! The control side's view of the loop's stage slots: which stage runs where, under what name,
//! which element ids it uses, and the element table that follows from them. Only touched under
//! the daemon state's lock, never by the loop.

use frond_motion::Rig;
use frond_protocol::{ElementId, ElementInfo, ElementKind, ElementTable, StageStatus};

use super::error::{MAX_STAGE_NAME, MAX_STAGES, StageError};
use super::live::StageInfo;

/// Free element ids offered to a stage being built, at most.
const OFFERED_IDS: usize = 256;

/// The element a hand source drives, and the rig that maps it.
#[derive(Debug, Clone, PartialEq)]
pub struct HandElement {
    /// The element (`kind` hand or layer, `source` the hand's name).
    pub info: ElementInfo,
    /// Its rig.
    pub rig: frond_protocol::RigInfo,
}

impl HandElement {
    /// Hand `source` driving `rig`'s element `id` (0: the global element, named after the rig;
    /// else the secondary element `rig.elements[id - 1]`).
    pub fn new(source: &str, rig: &Rig, id: ElementId) -> Self {
        let (name, kind) = match id.layer_index().and_then(|k| rig.elements.get(k)) {
            Some(layer) => (layer.name.clone(), ElementKind::Layer),
            None => (rig.name.clone(), ElementKind::Hand),
        };
        HandElement {
            info: ElementInfo { id, name, kind, source: source.to_string(), rig: rig.name.clone() },
            rig: super::live::rig_info(rig),
        }
    }
}

/// A stage the loop runs, as the control side knows it.
pub struct Running {
    /// Its name.
    pub name: String,
    /// Its kind, status cell, elements and inputs.
    pub info: StageInfo,
}

impl Running {
    /// Stage `name` described by `info`.
    pub fn new(name: &str, info: StageInfo) -> Self {
        Running { name: name.to_string(), info }
    }
}

/// The stage slots and the element table's version.
pub struct StageRegistry {
    slots: Vec<Option<Running>>,
    table_version: u64,
}

impl Default for StageRegistry {
    fn default() -> Self {
        StageRegistry { slots: (0..MAX_STAGES).map(|_| None).collect(), table_version: 0 }
    }
}

/// Checks a stage name: 1..=32 letters, digits, `-` and `_`.
pub fn validate_stage_name(name: &str) -> Result<(), StageError> {
    if is_plain_name(name) { Ok(()) } else { Err(StageError::BadName(name.chars().take(40).collect())) }
}

/// Whether `name` is 1..=32 ASCII letters, digits, `-` and `_`: the rule for stage and hand
/// names, which appear in status, logs and the element table.
pub fn is_plain_name(name: &str) -> bool {
    !name.is_empty()
        && name.len() <= MAX_STAGE_NAME
        && name.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'-' || b == b'_')
}

impl StageRegistry {
    /// The slot of the stage named `name`.
    pub fn slot_of(&self, name: &str) -> Option<usize> {
        self.slots.iter().position(|s| s.as_ref().is_some_and(|r| r.name == name))
    }

    /// The stage named `name`.
    pub fn get(&self, name: &str) -> Option<&Running> {
        self.slots.iter().flatten().find(|r| r.name == name)
    }

    /// The slot a stage named `name` goes into: its own if it runs, else a free one.
    pub fn slot_for(&self, name: &str) -> Result<usize, StageError> {
        self.slot_of(name)
            .or_else(|| self.slots.iter().position(Option::is_none))
            .ok_or(StageError::SlotsFull)
    }

    /// The element ids the stages in slots other than `slot` use, with the stage's name.
    fn ids_besides(&self, slot: usize) -> impl Iterator<Item = (ElementId, &str)> + '_ {
        self.slots
            .iter()
            .enumerate()
            .filter(move |(i, _)| *i != slot)
            .flat_map(|(_, r)| r.iter())
            .flat_map(|r| r.info.element_ids().map(move |id| (id, r.name.as_str())))
    }

    /// Element ids no stage uses except the one in `slot` (which is being replaced), lowest first,
    /// from [`ElementId::FIRST_STAGE`] (above the rig's layers).
    pub fn free_ids(&self, slot: usize) -> Vec<ElementId> {
        let used: Vec<ElementId> = self.ids_besides(slot).map(|(id, _)| id).collect();
        ElementId::stage_ids().filter(|id| !used.contains(id)).take(OFFERED_IDS).collect()
    }

    /// An element id `info` would use that a stage in another slot than `slot` already uses
    /// (ids are unique in the table), with that stage's name.
    pub fn collision(&self, slot: usize, info: &StageInfo) -> Option<(ElementId, String)> {
        let mine: Vec<ElementId> = info.element_ids().collect();
        self.ids_besides(slot).find(|(id, _)| mine.contains(id)).map(|(id, name)| (id, name.to_string()))
    }

    /// Records what runs in `slot` and returns what ran there.
    pub fn replace(&mut self, slot: usize, running: Option<Running>) -> Option<Running> {
        std::mem::replace(&mut self.slots[slot], running)
    }

    /// The running stages, in slot order.
    pub fn iter(&self) -> impl Iterator<Item = &Running> + '_ {
        self.slots.iter().flatten()
    }

    /// The next element table (version bumped): the elements the hand sources drive (`hands`,
    /// each with the rig it is mapped by; a layer being recorded relabels hand `primary`), the
    /// running stages' own elements, and every rig they use, the daemon's `rig` first.
    pub fn next_table(&mut self, rig: &Rig, hands: &[HandElement], primary: usize) -> ElementTable {
        self.table_version += 1;
        let mut elements: Vec<ElementInfo> = Vec::new();
        for r in self.iter() {
            elements.extend(r.info.elements.iter().cloned());
        }
        let relabel = self.iter().find_map(|r| r.info.hand_element.clone());
        for (i, hand) in hands.iter().enumerate() {
            let info = match &relabel {
                Some(layer) if i == primary => layer.clone(),
                _ => hand.info.clone(),
            };
            // A stage that publishes a hand's own id (a take looping as the global element while
            // the hand is not on a layer) describes it; the hand's frames there carry no
            // `playback`.
            if !elements.iter().any(|e| e.id == info.id) {
                elements.push(info);
            }
        }
        elements.sort_by_key(|e| e.id);
        // The rig in force, every hand's own rig, and every rig a running stage was built on.
        let mut rigs = vec![super::live::rig_info(rig)];
        let others = hands.iter().map(|h| &h.rig).chain(self.iter().map(|r| &r.info.rig));
        for other in others {
            if !rigs.iter().any(|known| known.name == other.name) {
                rigs.push(other.clone());
            }
        }
        ElementTable { version: self.table_version, rigs, elements }
    }

    /// Status of every stage.
    pub fn status(&self) -> Vec<StageStatus> {
        self.iter()
            .map(|r| StageStatus {
                name: r.name.clone(),
                kind: r.info.kind.to_string(),
                state: r.info.report.describe(),
                elements: r.info.elements.iter().map(|e| e.id).collect(),
                dropped_work: r.info.report.dropped_work(),
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use frond_protocol::RigInfo;

    use super::*;
    use crate::stage::{FixedReport, no_input};
    use frond_formats::rig_toml::RigText;
    use frond_protocol::control::StageKind;

    /// Stage id `k` from the first one.
    fn stage_id(k: u16) -> ElementId {
        ElementId::new(ElementId::FIRST_STAGE.get() + k)
    }

    fn built(kind: StageKind, ids: &[u16], hand: Option<u16>) -> StageInfo {
        let info = |id: u16, kind: ElementKind| ElementInfo {
            id: ElementId::new(id),
            name: format!("e{id}"),
            kind,
            source: "s".into(),
            rig: "grass".into(),
        };
        StageInfo {
            kind,
            report: Arc::new(FixedReport(kind.to_string())),
            elements: ids.iter().map(|&id| info(id, ElementKind::FieldPlant)).collect(),
            hand_element: hand.map(|id| info(id, ElementKind::Layer)),
            accepts: no_input,
            rig: RigInfo { name: "grass".into(), joint_names: vec!["root".into(); 4] },
            work: crate::stage::budget::TickWork::small("frames"),
        }
    }

    fn grass() -> Rig {
        Rig::from_toml_str(include_str!("../../../../rig-files/plants/grass.toml")).unwrap()
    }

    #[test]
    fn names_are_checked() {
        assert!(validate_stage_name("field").is_ok());
        assert!(validate_stage_name("plants_2-b").is_ok());
        for bad in ["", "a b", "../x", &"x".repeat(33)] {
            assert!(validate_stage_name(bad).is_err(), "{bad:?}");
        }
    }

    #[test]
    fn slots_are_reused_by_name_and_run_out() {
        let mut r = StageRegistry::default();
        let a = built(StageKind::Field, &[], None);
        let slot = r.slot_for("a").unwrap();
        r.replace(slot, Some(Running::new("a", a.clone())));
        assert_eq!(r.slot_for("a").unwrap(), slot, "same name, same slot");
        for i in 1..MAX_STAGES {
            let s = r.slot_for(&format!("s{i}")).unwrap();
            assert_ne!(s, slot);
            r.replace(s, Some(Running::new(&format!("s{i}"), a.clone())));
        }
        assert!(r.slot_for("one-more").unwrap_err().to_string().contains("stop one"));
        assert!(r.slot_for("a").is_ok(), "a running name can still be replaced");
    }

    #[test]
    fn free_ids_skip_other_stages_but_not_the_one_replaced() {
        let mut r = StageRegistry::default();
        r.replace(
            0,
            Some(Running::new("f", built(StageKind::Field, &[stage_id(0).get(), stage_id(1).get()], None))),
        );
        assert_eq!(r.free_ids(1)[..2], [stage_id(2), stage_id(3)]);
        assert_eq!(r.free_ids(0)[0], ElementId::FIRST_STAGE, "replacing slot 0 frees its ids");
    }

    #[test]
    fn a_stage_may_not_publish_an_id_another_stage_publishes() {
        let mut r = StageRegistry::default();
        r.replace(0, Some(Running::new("a", built(StageKind::Playback, &[0], None))));
        assert_eq!(
            r.collision(1, &built(StageKind::Playback, &[0], None)),
            Some((ElementId::GLOBAL, "a".to_string()))
        );
        assert_eq!(r.collision(0, &built(StageKind::Playback, &[0], None)), None, "replacing itself is fine");
        assert_eq!(r.collision(1, &built(StageKind::Field, &[40], None)), None);
        assert_eq!(
            r.collision(1, &built(StageKind::Layer, &[], Some(0))),
            Some((ElementId::GLOBAL, "a".to_string()))
        );
    }

    #[test]
    fn the_table_names_the_hand_layers_and_stage_elements() {
        let rig = grass();
        let mut r = StageRegistry::default();
        let hands = [HandElement::new("hand", &rig, ElementId::GLOBAL)];
        let t = r.next_table(&rig, &hands, 0);
        assert_eq!(t.version, 1);
        assert_eq!(t.elements.len(), 1);
        assert_eq!((t.elements[0].id, t.elements[0].kind), (ElementId::GLOBAL, ElementKind::Hand));
        assert_eq!(t.joint_names(ElementId::GLOBAL).unwrap().len(), 4);
        // A layer moves the hand to its id; a field adds its plants.
        r.replace(0, Some(Running::new("layer", built(StageKind::Layer, &[], Some(1)))));
        r.replace(1, Some(Running::new("field", built(StageKind::Field, &[40, 41], None))));
        let t = r.next_table(&rig, &hands, 0);
        assert_eq!(t.version, 2);
        let ids: Vec<(u16, ElementKind)> = t.elements.iter().map(|e| (e.id.get(), e.kind)).collect();
        assert_eq!(
            ids,
            [(1, ElementKind::Layer), (40, ElementKind::FieldPlant), (41, ElementKind::FieldPlant)]
        );
        assert_eq!(r.status().len(), 2);
    }

    #[test]
    fn two_hands_are_two_elements_and_a_layer_relabels_only_the_primary() {
        let flower = Rig::from_toml_str(include_str!("../../../../rig-files/plants/flower.toml")).unwrap();
        let mut r = StageRegistry::default();
        let hands = [
            HandElement::new("left", &flower, ElementId::GLOBAL),
            HandElement::new("right", &flower, ElementId::new(1)),
        ];
        let t = r.next_table(&flower, &hands, 0);
        let got: Vec<(u16, &str, ElementKind, &str)> =
            t.elements.iter().map(|e| (e.id.get(), e.name.as_str(), e.kind, e.source.as_str())).collect();
        assert_eq!(got, [(0, "flower", ElementKind::Hand, "left"), (1, "leaf", ElementKind::Layer, "right")]);
        assert_eq!(t.rigs.len(), 1, "one rig, named once");
        // A stage relabelling the primary hand onto a field-plant-free id 2 leaves the right hand.
        r.replace(0, Some(Running::new("layer", built(StageKind::Layer, &[], Some(2)))));
        let t = r.next_table(&flower, &hands, 0);
        let ids: Vec<u16> = t.elements.iter().map(|e| e.id.get()).collect();
        assert_eq!(ids, [1, 2]);
        // A hand on a rig of its own brings that rig into the table.
        let hands = [
            HandElement::new("left", &flower, ElementId::GLOBAL),
            HandElement::new("right", &grass(), ElementId::new(1)),
        ];
        let t = r.next_table(&flower, &hands, 0);
        let rigs: Vec<&str> = t.rigs.iter().map(|r| r.name.as_str()).collect();
        assert_eq!(rigs, ["flower", "grass"]);
    }
}
