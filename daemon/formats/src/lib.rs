//! frond's file formats and file handling, for the daemon, `frond` and every exporter alike: the
//! bytes of rigs, takes, JSON Lines, BVH, USD, glTF meshes and motion graph files, and the few
//! careful file operations they need. The math these files carry is `frond_motion`, which does
//! no I/O; this crate turns its types into bytes and back.
//!
//! - [`rig_files`]: the rigs built into every binary, and rig, calibration, take and mesh files
//!   read safely (regular files only, size limits), and outputs written atomically;
//! - [`take`]: the take file codec (records, checksums, the resynchronising reader);
//!   [`layers`] reads and writes a whole layered take ([`layers::TakeBytes`]);
//!   [`take_repair`] keeps the readable records of a damaged take;
//! - [`jsonl`]: hand samples and poses as JSON Lines; [`import`] turns such a file into frames;
//! - [`bvh`] and [`usd`]: the exchange formats `frond take bvh` and `frond take usd` write;
//! - [`gltf_mesh`]: a rig's glTF/GLB mesh;
//! - [`graph_file`]: the motion graph file `NAME.graph.json`;
//! - [`rig_toml`]: the text of rig files, calibration files and the `[sim]` table of a `--sim`
//!   file;
//! - [`field_json`]: `field.json` and the loop analysis `frond take loop --explain` prints.
//!
//! Parsers are pure (bytes in, values out) so they can be fuzzed (`fuzz/`); only [`rig_files`]
//! touches the file system.

#![warn(missing_docs)]

pub mod bvh;
pub mod field_json;
pub mod gltf_mesh;
pub mod graph_file;
pub mod import;
pub mod jsonl;
pub mod layers;
pub mod rig_files;
pub mod rig_toml;
pub mod take;
pub mod take_repair;
pub mod usd;

pub use jsonl::{JsonlError, parse_hand_line, parse_pose_line, write_hand_line, write_pose_line};
pub use take::{TakeError, TakeRecord, scan_take, scan_take_salvaging};
