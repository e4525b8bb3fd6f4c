//! The `frond` OSC namespace (documented in the [parent module](super)).

use frond_protocol::Pose;
use frond_protocol::convention::joint_quat;
use rosc::{OscPacket, OscType};

use super::{ClockOffset, Datagrams, EncodeError, set_f32, template, timetag};

/// Encoder of the `frond` namespace; holds the message templates so that encoding a frame does
/// not allocate.
#[derive(Debug, Clone)]
pub struct FrondEncoder {
    offset: ClockOffset,
    pose: OscPacket,
    quats: [OscPacket; 4],
    status: OscPacket,
    /// Templates of `/frond/element/<e>/pose`, made when element `e` is first seen.
    elements: Vec<(u16, OscPacket)>,
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

impl FrondEncoder {
    /// An encoder whose timetags use `offset` (see [`ClockOffset`]).
    pub fn new(offset: ClockOffset) -> FrondEncoder {
        FrondEncoder {
            offset,
            pose: pose_template("/frond/pose".into()),
            quats: std::array::from_fn(|i| template(format!("/frond/joint/{i}/quat"), Vec::new(), 4)),
            status: OscPacket::Message(rosc::OscMessage {
                addr: "/frond/status".into(),
                args: vec![OscType::Int(0)],
            }),
            elements: Vec::new(),
        }
    }

    /// Encodes one frame into `out` (replacing what it held).
    pub fn encode(&mut self, pose: &Pose, out: &mut Datagrams) -> Result<(), EncodeError> {
        out.begin(timetag(pose.host_monotonic_ns, self.offset));
        if pose.element != 0 {
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
