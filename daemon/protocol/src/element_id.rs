//! [`ElementId`]: which element a pose belongs to.
//!
//! Defined once, here, because the id crosses the wire (every [`Pose::element`](crate::Pose::element),
//! every [`ElementInfo::id`](crate::ElementInfo::id), a status reply's hands and stages) and is
//! stored in takes. On the wire and on disk it is the bare `u16` it always was
//! (`#[serde(transparent)]`; take files write its two little-endian bytes), and it prints as the
//! bare number, so typing it changed no byte of any frame, file or output.
//!
//! The ranges (ARCHITECTURE.md, "Live stages"): [`ElementId::GLOBAL`] (0) is the plant's global
//! element, [`ElementId::FIRST_LAYER`]`..=`[`ElementId::LAST_LAYER`] (1..=32) the rig's secondary
//! layers in rig order, and the daemon hands its live stages ids from [`ElementId::FIRST_STAGE`]
//! (33) up. Subscribers still look ids up in the element table rather than guess from the ranges.

use std::fmt;
use std::num::ParseIntError;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

/// An element id: the element a [`Pose`](crate::Pose) or a take frame belongs to.
#[derive(Clone, Copy, Default, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(transparent)]
pub struct ElementId(u16);

impl ElementId {
    /// The plant's global element (a hand mapped onto the whole plant, a looped take).
    pub const GLOBAL: ElementId = ElementId(0);
    /// The rig's first secondary layer (`rig.elements[0]`).
    pub const FIRST_LAYER: ElementId = ElementId(1);
    /// The highest id a rig's secondary layer may have (a rig has at most 32 layers).
    pub const LAST_LAYER: ElementId = ElementId(32);
    /// The first id the daemon hands to a live stage's elements, just above the rig's layers.
    pub const FIRST_STAGE: ElementId = ElementId(Self::LAST_LAYER.0 + 1);
    /// The highest id.
    pub const MAX: ElementId = ElementId(u16::MAX);
    /// How many secondary layers a rig may have: the ids `FIRST_LAYER..=LAST_LAYER`.
    pub const RIG_LAYERS: usize = Self::LAST_LAYER.0 as usize;

    /// The id with this number.
    pub const fn new(n: u16) -> Self {
        ElementId(n)
    }

    /// Its number, as it travels on the wire and in take files.
    pub const fn get(self) -> u16 {
        self.0
    }

    /// Its number as an index (per-element arrays, tables indexed by id).
    pub const fn index(self) -> usize {
        self.0 as usize
    }

    /// Whether it is the plant's global element (0).
    pub const fn is_global(self) -> bool {
        self.0 == Self::GLOBAL.0
    }

    /// Whether it is one of a rig's secondary layers (1..=32).
    pub const fn is_rig_layer(self) -> bool {
        self.0 >= Self::FIRST_LAYER.0 && self.0 <= Self::LAST_LAYER.0
    }

    /// Whether it is in the range handed to live stages (33 and up).
    pub const fn is_stage(self) -> bool {
        self.0 >= Self::FIRST_STAGE.0
    }

    /// The id of a rig's secondary layer `k` (`rig.elements[k]`, from 0): `k + 1`, if the rig
    /// may have that many layers.
    pub const fn rig_layer(k: usize) -> Option<ElementId> {
        if k < Self::RIG_LAYERS { Some(ElementId(k as u16 + 1)) } else { None }
    }

    /// Which of the rig's secondary layers it is (`rig.elements[k]`), if it is one.
    pub const fn layer_index(self) -> Option<usize> {
        if self.is_rig_layer() { Some(self.0 as usize - 1) } else { None }
    }

    /// Every id a live stage may be given, lowest first.
    pub fn stage_ids() -> impl Iterator<Item = ElementId> {
        (Self::FIRST_STAGE.0..=Self::MAX.0).map(ElementId)
    }
}

impl From<u16> for ElementId {
    fn from(n: u16) -> Self {
        ElementId(n)
    }
}

impl From<ElementId> for u16 {
    fn from(id: ElementId) -> Self {
        id.0
    }
}

/// [`ElementId::index`]: for tables indexed by element id.
impl From<ElementId> for usize {
    fn from(id: ElementId) -> Self {
        id.index()
    }
}

/// The bare number, as every message and table has always printed an element id.
impl fmt::Display for ElementId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(&self.0, f)
    }
}

/// The bare number too: `{:?}` of an id (or of a list of ids) reads as it did when ids were
/// `u16`s, in logs and in messages that quote them.
impl fmt::Debug for ElementId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Debug::fmt(&self.0, f)
    }
}

/// Parses the bare number (`0`, `33`), with `u16`'s errors.
impl FromStr for ElementId {
    type Err = ParseIntError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        s.parse().map(ElementId)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_follow_the_architecture() {
        assert!(ElementId::GLOBAL.is_global() && !ElementId::GLOBAL.is_rig_layer());
        assert!(ElementId::new(1).is_rig_layer() && ElementId::new(32).is_rig_layer());
        assert!(!ElementId::new(33).is_rig_layer() && ElementId::new(33).is_stage());
        assert_eq!(ElementId::FIRST_STAGE.get(), 33);
        assert_eq!(ElementId::rig_layer(0), Some(ElementId::FIRST_LAYER));
        assert_eq!(ElementId::rig_layer(31), Some(ElementId::LAST_LAYER));
        assert_eq!(ElementId::rig_layer(32), None);
        assert_eq!(ElementId::new(5).layer_index(), Some(4));
        assert_eq!(ElementId::GLOBAL.layer_index(), None);
        assert_eq!(ElementId::FIRST_STAGE.layer_index(), None);
        assert_eq!(ElementId::stage_ids().next(), Some(ElementId::FIRST_STAGE));
        assert_eq!(ElementId::stage_ids().count(), usize::from(u16::MAX) - 32);
    }

    #[test]
    fn prints_and_parses_the_bare_number() {
        let id = ElementId::new(300);
        assert_eq!(id.to_string(), "300");
        assert_eq!(format!("{id:?} {:?} {id:>5}", [ElementId::GLOBAL]), "300 [0]   300");
        assert_eq!("300".parse::<ElementId>(), Ok(id));
        assert_eq!(
            "x".parse::<ElementId>().unwrap_err().to_string(),
            "x".parse::<u16>().unwrap_err().to_string()
        );
        assert!("65536".parse::<ElementId>().is_err());
    }

    #[test]
    fn encodes_as_the_bare_number() {
        for n in [0u16, 1, 127, 128, 255, 256, u16::MAX] {
            assert_eq!(rmp_serde::to_vec(&ElementId::new(n)).unwrap(), rmp_serde::to_vec(&n).unwrap());
            let back: ElementId = rmp_serde::from_slice(&rmp_serde::to_vec(&n).unwrap()).unwrap();
            assert_eq!(back, ElementId::new(n));
        }
    }
}
