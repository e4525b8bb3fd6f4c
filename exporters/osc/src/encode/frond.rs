//! The `frond` OSC namespace (documented in the [parent module](super)).

use frond_protocol::convention::joint_quat;
use frond_protocol::{ElementId, ElementTable, Pose};
use rosc::{OscMessage, OscPacket, OscType};

use super::{ClockOffset, Datagrams, EncodeError, IMMEDIATELY, Timetags, set_f32, template, timetag};

/// Encoder of the `frond` namespace; holds the message templates so that encoding a frame does
/// not allocate.
#[derive(Debug, Clone)]
pub struct FrondEncoder {
    offset: ClockOffset,
    timetags: Timetags,
    pose: OscPacket,
    quats: [OscPacket; 4],
    status: OscPacket,
    /// Templates of `/frond/element/<e>/pose`, made when element `e` is first seen.
    elements: Vec<(ElementId, OscPacket)>,
}

/// Arguments of `/frond/pose`: int seq, double t, 12 floats.
fn pose_template(addr: String) -> OscPacket {
    template(addr, vec![OscType::Int(0), OscType::Double(0.0)], 12)
}

/// Writes seq, t and the 12 joint angles of `pose` into a pose template.
fn fill_pose(packet: &mut OscPacket, pose: &Pose) {
    if let OscPacket::Message(m) = packet {
        // Low 32 bits, as documented: OSC's `i` is 32-bit.
        m.args[0] = OscType::Int(pose.seq as u32 as i32);
        m.args[1] = OscType::Double(pose.hand.t);
    }
    for (j, joint) in pose.joints_deg.iter().enumerate() {
        for (k, &angle) in joint.iter().enumerate() {
            set_f32(packet, 2 + 3 * j + k, angle);
        }
    }
}

/// Longest name in the names bundle, bytes (a rig's joint names are at most 255).
pub const MAX_NAME_BYTES: usize = 255;

fn cut(name: &str) -> &str {
    let mut end = name.len().min(MAX_NAME_BYTES);
    while !name.is_char_boundary(end) {
        end -= 1;
    }
    &name[..end]
}

impl FrondEncoder {
    /// Frames' timetags from now on ([`Timetags::Publish`] unless set).
    pub fn set_timetags(&mut self, timetags: Timetags) {
        self.timetags = timetags;
    }

    /// An encoder whose timetags use `offset` (see [`ClockOffset`]).
    pub fn new(offset: ClockOffset) -> FrondEncoder {
        FrondEncoder {
            offset,
            timetags: Timetags::Publish,
            pose: pose_template("/frond/pose".into()),
            quats: std::array::from_fn(|i| template(format!("/frond/joint/{i}/quat"), Vec::new(), 4)),
            status: OscPacket::Message(rosc::OscMessage {
                addr: "/frond/status".into(),
                args: vec![OscType::Int(0)],
            }),
            elements: Vec::new(),
        }
    }

    /// Encodes the names bundle into `out` (replacing what it held), timetag "immediately": the
    /// main skeleton's `/frond/rig ,sssss` (rig name, then the 4 joint names, root first) and, per
    /// announced element `e` other than 0, `/frond/element/<e>/info ,sssssss` (element name, kind
    /// `hand|layer|playback|field-plant`, rig, its 4 joint names). Names longer than
    /// `MAX_NAME_BYTES` are cut at a character boundary. Allocates: the bridge sends it when the
    /// daemon's names change and once a second, never per frame.
    pub fn encode_names(
        &self,
        rig: &str,
        joint_names: &[String],
        table: &ElementTable,
        out: &mut Datagrams,
    ) -> Result<(), EncodeError> {
        out.begin(IMMEDIATELY);
        let s = |v: &str| OscType::String(cut(v).to_string());
        let joints = |names: &[String]| -> Vec<OscType> {
            (0..4).map(|j| s(names.get(j).map_or("", String::as_str))).collect()
        };
        let mut args = vec![s(rig)];
        args.extend(joints(joint_names));
        out.push(&OscPacket::Message(OscMessage { addr: "/frond/rig".into(), args }))?;
        for e in table.elements.iter().filter(|e| !e.id.is_global()) {
            let mut args = vec![s(&e.name), s(e.kind.as_str()), s(&e.rig)];
            args.extend(joints(table.joint_names(e.id).unwrap_or(&[])));
            let addr = format!("/frond/element/{}/info", e.id);
            out.push(&OscPacket::Message(OscMessage { addr, args }))?;
        }
        out.finish();
        Ok(())
    }

    /// Encodes one frame into `out` (replacing what it held).
    pub fn encode(&mut self, pose: &Pose, out: &mut Datagrams) -> Result<(), EncodeError> {
        out.begin(match self.timetags {
            Timetags::Publish => timetag(pose.host_monotonic_ns, self.offset),
            Timetags::Immediately => IMMEDIATELY,
        });
        if !pose.element.is_global() {
            let slot = match self.elements.iter().position(|(e, _)| *e == pose.element) {
                Some(i) => i,
                None => {
                    let addr = format!("/frond/element/{}/pose", pose.element);
                    self.elements.push((pose.element, pose_template(addr)));
                    self.elements.len() - 1
                }
            };
            let packet = &mut self.elements[slot].1;
            fill_pose(packet, pose);
            out.push(packet)?;
            out.finish();
            return Ok(());
        }
        fill_pose(&mut self.pose, pose);
        out.push(&self.pose)?;
        for (packet, angles) in self.quats.iter_mut().zip(pose.joints_deg) {
            for (k, c) in joint_quat(angles).into_iter().enumerate() {
                set_f32(packet, k, c);
            }
            out.push(packet)?;
        }
        if let OscPacket::Message(m) = &mut self.status {
            m.args[0] = OscType::Int(pose.flags.0 as i32);
        }
        out.push(&self.status)?;
        out.finish();
        Ok(())
    }
}
