//! A layered take's bytes (seed 000, section 5.3): the header record carrying the secondary
//! layer names (`"elements": ["leaf", "petal"]`), and [`TakeBytes`], which reads and writes a
//! whole [`Take`] (`frond_motion::layers`) as a take file.

use frond_motion::layers::Take;
use frond_motion::take::TakeHeader;

use crate::take::{
    MAGIC, RECORD_HEAD_LEN, RecordAt, TakeError, TakeRecord, encode_file_start, encode_record,
    read_record_at, scan_take,
};

#[derive(serde::Deserialize)]
struct HeaderExtra {
    #[serde(default)]
    elements: Vec<String>,
}

/// Reads the `elements` list from a take's header record (empty when absent or unreadable).
pub fn header_element_names(bytes: &[u8]) -> Vec<String> {
    match read_record_at(bytes, MAGIC.len()) {
        Ok(RecordAt::Record { record: TakeRecord::Header(_), next }) => {
            let payload = &bytes[MAGIC.len() + RECORD_HEAD_LEN + 1..next];
            serde_json::from_slice::<HeaderExtra>(payload).map(|h| h.elements).unwrap_or_default()
        }
        _ => Vec::new(),
    }
}

/// Appends a take's header record carrying the secondary layer names (`elements`; layer `k + 1`
/// is `elements[k]`), so a recorder can write layered takes that [`TakeBytes::from_bytes`] names.
pub fn encode_header(h: &TakeHeader, elements: &[String], out: &mut Vec<u8>) {
    if elements.is_empty() {
        encode_record(&TakeRecord::Header(h.clone()), out);
        return;
    }
    // The header JSON plus "elements"; readers that do not know the field ignore it.
    let mut v = serde_json::to_value(h).unwrap_or_default();
    if let Some(m) = v.as_object_mut() {
        m.insert("elements".to_string(), serde_json::Value::from(elements.to_vec()));
    }
    let body = serde_json::to_vec(&v).unwrap_or_default();
    let start = out.len();
    out.extend_from_slice(&[0; 8]);
    out.push(1); // KIND_HEADER
    out.extend_from_slice(&body);
    let len = (out.len() - start - 8) as u32;
    let crc = crc32fast::hash(&out[start + 8..]);
    out[start..start + 4].copy_from_slice(&len.to_le_bytes());
    out[start + 4..start + 8].copy_from_slice(&crc.to_le_bytes());
}

/// A whole [`Take`] read from and written as a take file's bytes. A trait because [`Take`] lives
/// in `frond_motion`, which does no file formats: `use frond_formats::layers::TakeBytes` and call
/// `Take::from_bytes(..)`, `take.to_bytes()`.
pub trait TakeBytes: Sized {
    /// Reads a take file's bytes (a torn tail is ignored, as by every reader). A take without a
    /// header record is refused.
    fn from_bytes(bytes: &[u8]) -> Result<Self, TakeError>;

    /// [`TakeBytes::from_bytes`], also saying in words what the reader skipped in a damaged take
    /// ([`frond_motion::take::TakeScan::damage`]; `None` when the take is sound), for callers that
    /// work on the readable frames and must say so.
    fn from_bytes_noting_damage(bytes: &[u8]) -> Result<(Self, Option<String>), TakeError>;

    /// The complete file: magic, header (with `elements` when there are names), frames,
    /// markers, End.
    fn to_bytes(&self) -> Vec<u8>;
}

impl TakeBytes for Take {
    fn from_bytes(bytes: &[u8]) -> Result<Take, TakeError> {
        Ok(Self::from_bytes_noting_damage(bytes)?.0)
    }

    fn from_bytes_noting_damage(bytes: &[u8]) -> Result<(Take, Option<String>), TakeError> {
        let scan = scan_take(bytes)?;
        let damage = scan.damage();
        let header = scan.header.ok_or(TakeError::Structure {
            offset: MAGIC.len() as u64,
            reason: "the take has no header record".to_string(),
        })?;
        let take = Take {
            header,
            element_names: header_element_names(bytes),
            frames: scan.frames,
            markers: scan.markers,
        };
        Ok((take, damage))
    }

    fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(64 + self.frames.len() * 127);
        encode_file_start(&mut out);
        encode_header(&self.header, &self.element_names, &mut out);
        for f in &self.frames {
            encode_record(&TakeRecord::Frame(*f), &mut out);
        }
        for (seq, label) in &self.markers {
            encode_record(&TakeRecord::Marker { seq: *seq, label: label.clone() }, &mut out);
        }
        encode_record(&TakeRecord::End { frames: self.frames.len() as u64 }, &mut out);
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use frond_motion::sample::PoseFrame;
    use frond_motion::take::TakeFrame;
    use frond_protocol::ElementId;

    fn header() -> TakeHeader {
        TakeHeader {
            joint_names: vec!["a".into(), "b".into(), "c".into(), "d".into()],
            ..TakeHeader::offline("t", "flower", 30)
        }
    }

    fn frame(seq: u64, element: u16, v: f32) -> TakeFrame {
        TakeFrame {
            seq,
            element: ElementId::new(element),
            pose: PoseFrame { t: seq as f64 / 30.0, joints_deg: [[v; 3]; 4] },
            ..Default::default()
        }
    }

    #[test]
    fn layered_take_round_trips_with_names() {
        let mut t = Take::new(header());
        t.set_layer(ElementId::GLOBAL, None, (0..3).map(|k| frame(k, 0, k as f32)));
        t.set_layer(ElementId::new(2), Some("petal"), (0..2).map(|k| frame(k, 0, -(k as f32))));
        t.markers.push((1, "here".into()));
        assert_eq!(t.element_names, ["element1", "petal"]);
        let bytes = t.to_bytes();
        let back = Take::from_bytes(&bytes).unwrap();
        assert_eq!(back, t);
        assert_eq!(back.layer_ids(), [ElementId::GLOBAL, ElementId::new(2)]);
        assert_eq!(back.layer_name(ElementId::new(2)), "petal");
        assert_eq!(back.layer_id("petal"), Some(ElementId::new(2)));
        assert_eq!(back.layer_id("global"), Some(ElementId::GLOBAL));
        assert_eq!(back.layer_id("element1"), Some(ElementId::new(1)));
        assert_eq!(back.layer(ElementId::new(2), false).len(), 2);
        assert!((back.marker_time("here").unwrap() - 1.0 / 30.0).abs() < 1e-12);
        // The plain codec still reads it (the extra header field is ignored).
        let scan = scan_take(&bytes).unwrap();
        assert_eq!(scan.header.unwrap(), header());
        assert!(scan.ended);
    }

    #[test]
    fn old_takes_without_names_read() {
        let mut t = Take::new(header());
        t.set_layer(ElementId::new(1), None, [frame(0, 1, 1.0)]);
        t.element_names.clear();
        let back = Take::from_bytes(&t.to_bytes()).unwrap();
        assert!(back.element_names.is_empty());
        assert_eq!(back.layer_name(ElementId::new(1)), "element1");
        let mut no_header = Vec::new();
        encode_file_start(&mut no_header);
        assert!(Take::from_bytes(&no_header).unwrap_err().to_string().contains("no header record"));
    }
}
