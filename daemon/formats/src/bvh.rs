//! BVH (Biovision Hierarchy), the motion-capture exchange format MotionBuilder, Maya and Blender
//! import: the plant's four joints as a chain, every frame's rotations in frond's convention.
//!
//! frond's joint rotation is `R = R_yaw(Z) R_pitch(X) R_roll(Y)` relative to the parent, stem
//! along +Y (`frond_protocol::convention`), right-handed, Y up: exactly BVH's own frame, and BVH
//! channels listed `Zrotation Xrotation Yrotation` compose in that order (the first listed is the
//! outermost). So each joint writes `yaw pitch roll` in degrees, unchanged. Lengths are metres
//! (times [`BvhPlant::scale`]); the root also has position channels (constant: where the plant
//! stands). Several plants (a field) are several `ROOT` hierarchies in one file, as BVH allows.
//! Pure: builds text into a reused `String`.

use std::fmt::Write;

use frond_motion::sample::JOINTS;

/// Joint angles of one frame: `[pitch, yaw, roll]` per joint, degrees.
pub type Joints = [[f32; 3]; JOINTS];

/// One plant's skeleton as BVH writes it.
#[derive(Debug, Clone, PartialEq)]
pub struct BvhPlant {
    /// Prefix of the joint names (the rig's name, or `grass_007` in a field); empty for none.
    pub prefix: String,
    /// The rig's joint names, root first.
    pub joint_names: [String; JOINTS],
    /// Rest heights of joints 0..3 and of the plant's top (the end site), metres, increasing.
    pub heights_m: [f64; JOINTS + 1],
    /// Where the plant stands, `[x, z]` metres on the ground.
    pub position_m: [f64; 2],
    /// Uniform size factor.
    pub scale: f64,
}

impl BvhPlant {
    fn joint_name(&self, j: usize) -> String {
        let name: String = self.joint_names[j]
            .chars()
            .map(|c| if c.is_ascii_alphanumeric() || c == '_' || c == '-' || c == '.' { c } else { '_' })
            .collect();
        if self.prefix.is_empty() { name } else { format!("{}_{name}", self.prefix) }
    }

    /// The root's offset: where joint 0 rests in the world.
    fn root_offset(&self) -> [f64; 3] {
        [self.position_m[0], self.heights_m[0] * self.scale, self.position_m[1]]
    }
}

/// Writes the `HIERARCHY` and the `MOTION` header of `plants` at `frame_time_s` seconds a frame
/// for `frames` frames into `out` (cleared first); frames follow with [`push_frame`].
pub fn begin(plants: &[BvhPlant], frames: usize, frame_time_s: f64, out: &mut String) {
    out.clear();
    out.push_str("HIERARCHY\n");
    for plant in plants {
        let [x, y, z] = plant.root_offset();
        let _ = writeln!(out, "ROOT {}\n{{", plant.joint_name(0));
        let _ = writeln!(out, "\tOFFSET {x:.6} {y:.6} {z:.6}");
        out.push_str("\tCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n");
        for j in 1..JOINTS {
            let tabs = "\t".repeat(j);
            let dy = (plant.heights_m[j] - plant.heights_m[j - 1]) * plant.scale;
            let _ = writeln!(out, "{tabs}JOINT {}\n{tabs}{{", plant.joint_name(j));
            let _ = writeln!(out, "{tabs}\tOFFSET 0.000000 {dy:.6} 0.000000");
            let _ = writeln!(out, "{tabs}\tCHANNELS 3 Zrotation Xrotation Yrotation");
        }
        let tabs = "\t".repeat(JOINTS);
        let dy = (plant.heights_m[JOINTS] - plant.heights_m[JOINTS - 1]) * plant.scale;
        let _ = writeln!(out, "{tabs}End Site\n{tabs}{{\n{tabs}\tOFFSET 0.000000 {dy:.6} 0.000000\n{tabs}}}");
        for j in (0..JOINTS).rev() {
            let _ = writeln!(out, "{}}}", "\t".repeat(j));
        }
    }
    let _ = writeln!(out, "MOTION\nFrames: {frames}\nFrame Time: {frame_time_s:.9}");
}

/// Appends one frame line: for each plant (in [`begin`]'s order) its root position and the
/// four joints' `yaw pitch roll`.
pub fn push_frame(plants: &[BvhPlant], poses: &[Joints], out: &mut String) {
    for (i, (plant, pose)) in plants.iter().zip(poses).enumerate() {
        let [x, y, z] = plant.root_offset();
        if i > 0 {
            out.push(' ');
        }
        let _ = write!(out, "{x:.6} {y:.6} {z:.6}");
        for [pitch, yaw, roll] in pose {
            let _ = write!(out, " {yaw:.6} {pitch:.6} {roll:.6}");
        }
    }
    out.push('\n');
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grass() -> BvhPlant {
        BvhPlant {
            prefix: String::new(),
            joint_names: ["root", "lower", "middle", "tip"].map(String::from),
            heights_m: [0.0, 0.08, 0.16, 0.24, 0.30],
            position_m: [0.0, 0.0],
            scale: 1.0,
        }
    }

    #[test]
    fn one_plant_writes_the_expected_bytes() {
        let mut out = String::new();
        let plants = [grass()];
        begin(&plants, 2, 1.0 / 30.0, &mut out);
        push_frame(&plants, &[[[0.0; 3]; 4]], &mut out);
        push_frame(&plants, &[[[10.0, -20.0, 5.0], [1.0, 2.0, 3.0], [0.0; 3], [0.0, 0.0, -90.0]]], &mut out);
        let want = "HIERARCHY
ROOT root
{
\tOFFSET 0.000000 0.000000 0.000000
\tCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
\tJOINT lower
\t{
\t\tOFFSET 0.000000 0.080000 0.000000
\t\tCHANNELS 3 Zrotation Xrotation Yrotation
\t\tJOINT middle
\t\t{
\t\t\tOFFSET 0.000000 0.080000 0.000000
\t\t\tCHANNELS 3 Zrotation Xrotation Yrotation
\t\t\tJOINT tip
\t\t\t{
\t\t\t\tOFFSET 0.000000 0.080000 0.000000
\t\t\t\tCHANNELS 3 Zrotation Xrotation Yrotation
\t\t\t\tEnd Site
\t\t\t\t{
\t\t\t\t\tOFFSET 0.000000 0.060000 0.000000
\t\t\t\t}
\t\t\t}
\t\t}
\t}
}
MOTION
Frames: 2
Frame Time: 0.033333333
0.000000 0.000000 0.000000 0.000000 0.000000 0.000000 0.000000 0.000000 0.000000 0.000000 0.000000 0.000000 0.000000 0.000000 0.000000
0.000000 0.000000 0.000000 -20.000000 10.000000 5.000000 2.000000 1.000000 3.000000 0.000000 0.000000 0.000000 0.000000 0.000000 -90.000000
";
        assert_eq!(out, want);
    }

    #[test]
    fn field_plants_are_placed_scaled_and_named_apart() {
        let mut b = grass();
        b.prefix = "grass_1".into();
        b.position_m = [1.5, -2.0];
        b.scale = 2.0;
        b.joint_names[3] = "tip top".into();
        let mut out = String::new();
        begin(&[grass(), b.clone()], 1, 0.5, &mut out);
        assert_eq!(out.matches("ROOT ").count(), 2);
        assert!(out.contains("ROOT grass_1_root\n{\n\tOFFSET 1.500000 0.000000 -2.000000\n"), "{out}");
        assert!(out.contains("JOINT grass_1_tip_top\n"), "{out}");
        assert!(out.contains("\tOFFSET 0.000000 0.160000 0.000000\n"), "segments scaled: {out}");
        out.clear();
        push_frame(&[grass(), b], &[[[0.0; 3]; 4], [[0.0; 3]; 4]], &mut out);
        assert_eq!(out.split(' ').count(), 30);
        assert!(out.contains(" 1.500000 0.000000 -2.000000 "));
    }
}
