//! A running field in the `frond` namespace, whole (protocol 3; seed 000, Eq. 6-7 and section
//! 6.3): its definition, its plants' layout in chunks and every field frame, as the console
//! sends them to its page, so that a receiver evaluates every plant itself (the Blender add-on:
//! `blender/frond_receiver.py`, `frond_motion::field_eval` ported). The addresses are in the
//! [parent module](super) and the README.
//!
//! What goes out does not grow with the field, except the layout: [`LAYOUT_CHUNK_BYTES`] a
//! datagram, at most [`MAX_LAYOUT_CHUNKS`] of them, for at most [`MAX_OSC_FIELD_PLANTS`] plants.

use frond_protocol::field::{FIELD_FRAME_ENTRIES, FieldDefinition, FieldFrame, MAX_ANNOUNCED_PLANTS};
use frond_protocol::{ElementId, ElementTable};
use frond_sdk::field::LAYOUT_BYTES_PER_PLANT;
use rosc::{OscMessage, OscPacket, OscType};

use super::{ClockOffset, Datagrams, EncodeError, IMMEDIATELY, Timetags, timetag};

/// Layout bytes in one `/frond/field/<f>/layout` chunk (50 plants; the last chunk may be
/// shorter): with its address, type tags and integers it fits one datagram.
pub const LAYOUT_CHUNK_BYTES: usize = 1000;
/// The most plants of a field sent whole: a larger field is left out (its announced plants'
/// poses still go out). The console draws up to 100,000 plants too.
pub const MAX_OSC_FIELD_PLANTS: usize = 100_000;
/// The most chunks of one layout.
pub const MAX_LAYOUT_CHUNKS: usize = MAX_OSC_FIELD_PLANTS * LAYOUT_BYTES_PER_PLANT / LAYOUT_CHUNK_BYTES;
/// Bytes of one stream frame in a frame's entries blob: its index (u64) and 12 angles (f32),
/// little-endian.
pub const ENTRY_BYTES: usize = 8 + 12 * 4;
/// Longest source, rig or joint name sent, bytes (cut at a character boundary).
pub const MAX_FIELD_NAME_BYTES: usize = 255;

/// The layout key: CRC-32 (IEEE) of the layout bytes, as a receiver checks the chunks it put
/// together (Python's `zlib.crc32`).
pub fn layout_key(layout: &[u8]) -> u32 {
    crc32fast::hash(layout)
}

/// Chunks of a layout of `bytes` bytes.
pub fn layout_chunks(bytes: usize) -> usize {
    bytes.div_ceil(LAYOUT_CHUNK_BYTES)
}

fn cut(name: &str) -> &str {
    let mut end = name.len().min(MAX_FIELD_NAME_BYTES);
    while !name.is_char_boundary(end) {
        end -= 1;
    }
    &name[..end]
}

fn message(addr: String, args: Vec<OscType>) -> OscPacket {
    OscPacket::Message(OscMessage { addr, args })
}

fn args_mut(packet: &mut OscPacket) -> &mut [OscType] {
    match packet {
        OscPacket::Message(m) => &mut m.args,
        OscPacket::Bundle(_) => &mut [],
    }
}

/// Overwrites a blob argument with `bytes` (its buffer reused: no allocation once grown).
fn set_blob(arg: &mut OscType, bytes: impl IntoIterator<Item = u8>) {
    if let OscType::Blob(b) = arg {
        b.clear();
        b.extend(bytes);
    }
}

/// One field's templates: its frame and layout chunk messages, made when its definition
/// arrives so that encoding a frame or a chunk allocates nothing.
#[derive(Debug, Clone)]
struct FieldTemplates {
    id: ElementId,
    frame: OscPacket,
    chunk: OscPacket,
}

impl FieldTemplates {
    /// The templates of field `id`.
    fn new(id: ElementId) -> FieldTemplates {
        let frame = message(
            format!("/frond/field/{id}/frame"),
            vec![
                OscType::Long(0),
                OscType::Int(0),
                OscType::Double(0.0),
                OscType::Double(0.0),
                OscType::Double(0.0),
                OscType::Double(0.0),
                OscType::Double(0.0),
                OscType::Float(0.0),
                OscType::Double(0.0),
                OscType::Double(0.0),
                OscType::Double(0.0),
                OscType::Long(0),
                OscType::Blob(Vec::with_capacity(FIELD_FRAME_ENTRIES * ENTRY_BYTES)),
            ],
        );
        let chunk = message(
            format!("/frond/field/{id}/layout"),
            vec![
                OscType::Int(0),
                OscType::Int(0),
                OscType::Int(0),
                OscType::Blob(Vec::with_capacity(LAYOUT_CHUNK_BYTES)),
            ],
        );
        FieldTemplates { id, frame, chunk }
    }

    /// Appends `/frond/field/<f>/frame ,hidddddfdddhb` to `out`: the frame's sequence number,
    /// pose flags, hand time (s), stream time tau (s), the controls (direction deg, speed m/s,
    /// time step, scale, the three rigidity delays s), `produced` and the entries blob
    /// ([`ENTRY_BYTES`] each).
    fn push_frame(&mut self, f: &FieldFrame, out: &mut Datagrams) -> Result<(), EncodeError> {
        let a = args_mut(&mut self.frame);
        let c = &f.controls;
        a[0] = OscType::Long(f.seq as i64);
        a[1] = OscType::Int(f.flags.0 as i32);
        a[2] = OscType::Double(f.hand_t);
        a[3] = OscType::Double(f.tau_s);
        a[4] = OscType::Double(c.direction_deg);
        a[5] = OscType::Double(c.speed_m_s);
        a[6] = OscType::Double(c.time_step);
        a[7] = OscType::Float(c.scale);
        for k in 0..3 {
            a[8 + k] = OscType::Double(c.delays_s[k]);
        }
        a[11] = OscType::Long(f.produced as i64);
        let entries = f.entries.as_slice().iter().flat_map(|e| {
            let angles = e.joints_deg.as_flattened().iter().flat_map(|x| x.to_le_bytes());
            e.index.to_le_bytes().into_iter().chain(angles)
        });
        set_blob(&mut a[12], entries);
        out.push(&self.frame)
    }

    /// Appends chunk `index` of `layout` (`/frond/field/<f>/layout ,iiib`: key, index, count,
    /// bytes) to `out`.
    fn push_chunk(
        &mut self,
        layout: &[u8],
        key: u32,
        index: usize,
        out: &mut Datagrams,
    ) -> Result<(), EncodeError> {
        let count = layout_chunks(layout.len());
        let from = (index * LAYOUT_CHUNK_BYTES).min(layout.len());
        let to = (from + LAYOUT_CHUNK_BYTES).min(layout.len());
        let a = args_mut(&mut self.chunk);
        a[0] = OscType::Int(key as i32);
        a[1] = OscType::Int(index as i32);
        a[2] = OscType::Int(count as i32);
        set_blob(&mut a[3], layout[from..to].iter().copied());
        out.push(&self.chunk)
    }
}

/// Encodes what a field is, timetag "immediately", into `out` (replacing what it held): first
/// `/frond/fields ,i...` (the ids of every running field sent whole: a receiver forgets the
/// others), then per field `(definition, layout)`:
///
/// - `/frond/field/<f>/def ,ssiiididiiiiib`: source (the stage's name), rig, plants, rows,
///   cols, stream fps, history frames, authored direction (deg), publish rate (Hz), layout key
///   ([`layout_key`], as i32), layout bytes, chunk bytes ([`LAYOUT_CHUNK_BYTES`]), chunks, and
///   the announced plants' element ids (u16 little-endian each, plant order);
/// - `/frond/field/<f>/joints ,ssss`: the rig's four joint names, root first, from the element
///   table (empty when it does not list the rig).
///
/// Allocates: sent when the fields change and every couple of seconds, never per frame.
pub fn encode_definitions(
    fields: &[(&FieldDefinition, &[u8])],
    table: &ElementTable,
    out: &mut Datagrams,
) -> Result<(), EncodeError> {
    out.begin(IMMEDIATELY);
    let ids = fields.iter().map(|(d, _)| OscType::Int(i32::from(d.id.get()))).collect();
    out.push(&message("/frond/fields".into(), ids))?;
    let s = |v: &str| OscType::String(cut(v).to_string());
    let int = |v: usize| OscType::Int(i32::try_from(v).unwrap_or(i32::MAX));
    for (d, layout) in fields {
        let announced =
            d.plant_elements.iter().take(MAX_ANNOUNCED_PLANTS).flat_map(|e| e.get().to_le_bytes());
        let args = vec![
            s(&d.source),
            s(&d.rig),
            int(d.plants as usize),
            int(d.layout.rows as usize),
            int(d.layout.cols as usize),
            OscType::Double(d.stream_fps),
            int(d.history_frames as usize),
            OscType::Double(d.layout.authored_direction_deg),
            int(d.publish_hz as usize),
            OscType::Int(layout_key(layout) as i32),
            int(layout.len()),
            int(LAYOUT_CHUNK_BYTES),
            int(layout_chunks(layout.len())),
            OscType::Blob(announced.collect()),
        ];
        out.push(&message(format!("/frond/field/{}/def", d.id), args))?;
        let rig = table.rigs.iter().find(|r| r.name == d.rig);
        let joints =
            (0..4).map(|j| s(rig.and_then(|r| r.joint_names.get(j)).map_or("", String::as_str))).collect();
        out.push(&message(format!("/frond/field/{}/joints", d.id), joints))?;
    }
    out.finish();
    Ok(())
}

/// Encoder of field frames and layout chunks: one set of message templates per field sent whole,
/// made by [`FieldEncoder::set_fields`] when the fields change.
#[derive(Debug, Clone)]
pub struct FieldEncoder {
    offset: ClockOffset,
    timetags: Timetags,
    templates: Vec<FieldTemplates>,
}

impl FieldEncoder {
    /// An encoder whose timetags use `offset` (see [`ClockOffset`]).
    pub fn new(offset: ClockOffset) -> FieldEncoder {
        FieldEncoder { offset, timetags: Timetags::Publish, templates: Vec::new() }
    }

    /// Frames' timetags from now on ([`Timetags::Publish`] unless set).
    pub fn set_timetags(&mut self, timetags: Timetags) {
        self.timetags = timetags;
    }

    /// The fields whose frames are encoded from now on (templates made for new ids; allocates).
    pub fn set_fields(&mut self, ids: impl IntoIterator<Item = ElementId>) {
        let mut old = std::mem::take(&mut self.templates);
        for id in ids {
            match old.iter().position(|t| t.id == id) {
                Some(i) => self.templates.push(old.swap_remove(i)),
                None => self.templates.push(FieldTemplates::new(id)),
            }
        }
    }

    /// Encodes field frame `f` into `out` (replacing what it held), timetagged with its host
    /// time, and after it `chunks` of `layout` (`(layout, key, chunk indices)`), splitting into
    /// bundles as they fill. `Ok(false)` (and `out` empty) for a field not set.
    pub fn encode_frame(
        &mut self,
        f: &FieldFrame,
        chunks: Option<(&[u8], u32, std::ops::Range<usize>)>,
        out: &mut Datagrams,
    ) -> Result<bool, EncodeError> {
        out.begin(match self.timetags {
            Timetags::Publish => timetag(f.host_monotonic_ns, self.offset),
            Timetags::Immediately => IMMEDIATELY,
        });
        let Some(t) = self.templates.iter_mut().find(|t| t.id == f.field) else {
            out.finish();
            return Ok(false);
        };
        t.push_frame(f, out)?;
        if let Some((layout, key, range)) = chunks {
            for i in range {
                t.push_chunk(layout, key, i, out)?;
            }
        }
        out.finish();
        Ok(true)
    }
}
