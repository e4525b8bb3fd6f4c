//! The VMC protocol (documented in the [parent module](super)).

use frond_protocol::convention::joint_quat;
use frond_protocol::{Pose, PoseFlags};
use rosc::{OscMessage, OscPacket, OscType};

use super::{
    ClockOffset, Datagrams, EncodeError, IMMEDIATELY, Timetags, set_f32, template, timetag, unity_position,
    unity_quat,
};

/// Humanoid bone names (Unity `HumanBodyBones`) for receivers that only accept those: the stem
/// becomes the spine chain.
pub const HUMANOID_BONES: [&str; 4] = ["Hips", "Spine", "Chest", "Neck"];

/// Heights of the default rig (frond's `grass`), used when no rig file is given.
pub const DEFAULT_HEIGHTS_M: [f32; 4] = [0.0, 0.08, 0.16, 0.24];

/// What VMC needs to know about the rig: bone names and rest heights (frond frame, metres).
#[derive(Debug, Clone, PartialEq)]
pub struct VmcRig {
    /// Name sent for each joint, root first.
    pub bone_names: [String; 4],
    /// Rest height of each joint above the ground (strictly increasing in a valid rig).
    pub heights_m: [f32; 4],
}

impl Default for VmcRig {
    fn default() -> Self {
        VmcRig { bone_names: std::array::from_fn(|i| format!("joint{i}")), heights_m: DEFAULT_HEIGHTS_M }
    }
}

impl VmcRig {
    /// Local position of joint `i` relative to its parent (joint 0: relative to the root), frond
    /// frame: straight up the stem by the height difference.
    pub fn local_offset_m(&self, i: usize) -> [f32; 3] {
        let below = if i == 0 { 0.0 } else { self.heights_m[i - 1] };
        [0.0, self.heights_m[i] - below, 0.0]
    }
}

/// Encoder of VMC bundles; holds the message templates so that encoding a frame does not
/// allocate.
#[derive(Debug, Clone)]
pub struct VmcEncoder {
    offset: ClockOffset,
    timetags: Timetags,
    rig: VmcRig,
    root: OscPacket,
    bones: [OscPacket; 4],
    ok: OscPacket,
    time: OscPacket,
}

fn bone_template(name: &str) -> OscPacket {
    template("/VMC/Ext/Bone/Pos".into(), vec![OscType::String(name.into())], 7)
}

impl VmcEncoder {
    /// Frames' timetags from now on ([`Timetags::Publish`] unless set).
    pub fn set_timetags(&mut self, timetags: Timetags) {
        self.timetags = timetags;
    }

    /// An encoder for `rig` whose timetags use `offset`.
    pub fn new(offset: ClockOffset, rig: VmcRig) -> VmcEncoder {
        let mut root = template("/VMC/Ext/Root/Pos".into(), vec![OscType::String("root".into())], 7);
        set_f32(&mut root, 7, 1.0); // identity rotation: w = 1
        let mut enc = VmcEncoder {
            offset,
            timetags: Timetags::Publish,
            bones: std::array::from_fn(|i| bone_template(&rig.bone_names[i])),
            rig,
            root,
            ok: OscPacket::Message(OscMessage {
                addr: "/VMC/Ext/OK".into(),
                args: vec![OscType::Int(1), OscType::Int(3), OscType::Int(0), OscType::Int(1)],
            }),
            time: template("/VMC/Ext/T".into(), Vec::new(), 1),
        };
        enc.set_rig(enc.rig.clone());
        enc
    }

    /// The rig in use.
    pub fn rig(&self) -> &VmcRig {
        &self.rig
    }

    /// Replaces the rig (bone names and rest offsets), e.g. after the daemon's rig changed.
    pub fn set_rig(&mut self, rig: VmcRig) {
        for (i, bone) in self.bones.iter_mut().enumerate() {
            *bone = bone_template(&rig.bone_names[i]);
            let p = unity_position(rig.local_offset_m(i));
            for (k, c) in p.into_iter().enumerate() {
                set_f32(bone, 1 + k, c);
            }
        }
        self.rig = rig;
    }

    /// Encodes one frame into `out` (replacing what it held). Poses of secondary elements have no
    /// VMC bone and produce no datagram.
    pub fn encode(&mut self, pose: &Pose, out: &mut Datagrams) -> Result<(), EncodeError> {
        out.begin(match self.timetags {
            Timetags::Publish => timetag(pose.host_monotonic_ns, self.offset),
            Timetags::Immediately => IMMEDIATELY,
        });
        if !pose.element.is_global() {
            out.finish();
            return Ok(());
        }
        out.push(&self.root)?;
        for (bone, angles) in self.bones.iter_mut().zip(pose.joints_deg) {
            for (k, c) in unity_quat(joint_quat(angles)).into_iter().enumerate() {
                set_f32(bone, 4 + k, c);
            }
            out.push(bone)?;
        }
        if let OscPacket::Message(m) = &mut self.ok {
            let tracking = !pose.flags.contains(PoseFlags::DEVICE_LOST);
            m.args[3] = OscType::Int(i32::from(tracking));
        }
        out.push(&self.ok)?;
        set_f32(&mut self.time, 0, pose.hand.t as f32);
        out.push(&self.time)?;
        out.finish();
        Ok(())
    }
}
