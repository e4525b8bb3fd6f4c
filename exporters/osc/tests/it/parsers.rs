//! The argument and rig-file parsers never panic on arbitrary input: they answer with a value or
//! an error naming the problem.

use frond_osc::{rig, sender};
use proptest::prelude::*;

/// A rig's text through the one rig loader, as `--rig` reads a file.
fn parse(text: &str) -> Result<rig::RigFile, rig::RigFileError> {
    let loaded = frond_formats::rig_files::rig_from_text(text.to_string(), "rig".into(), "rig", None)?;
    rig::from_loaded(&loaded)
}

proptest! {
    #[test]
    fn target_parser_never_panics(spec in "[a-z0-9:.\\[\\]]{0,24}") {
        // No DNS look-ups of random names: only specs that parse without resolving, or fail early.
        if spec.parse::<std::net::SocketAddr>().is_ok() || spec.parse::<std::net::IpAddr>().is_ok() || spec.contains(':') && spec.rsplit_once(':').is_some_and(|(_, p)| p.parse::<u16>().is_err()) {
            let _ = sender::parse_target(&spec, 9000);
        }
    }

    #[test]
    fn rig_parser_never_panics(text in "\\PC{0,200}") {
        let _ = parse(&text);
    }

    #[test]
    fn rig_parser_on_near_valid_rigs(heights in proptest::collection::vec(-1.0f64..1.0, 0..6), bones in 0usize..6) {
        let mut text = String::from("name = \"p\"\n");
        for (i, h) in heights.iter().enumerate() {
            text.push_str(&format!("[[joints]]\nname = \"j{i}\"\nheight_m = {h:?}\n"));
        }
        text.push_str(&format!("[vmc]\nbones = [{}]\n", (0..bones).map(|i| format!("\"b{i}\"")).collect::<Vec<_>>().join(",")));
        match parse(&text) {
            Ok(r) => {
                prop_assert_eq!(heights.len(), 4);
                prop_assert_eq!(bones, 4);
                prop_assert!(r.vmc.heights_m.windows(2).all(|w| w[1] > w[0]));
            }
            Err(e) => prop_assert!(!e.to_string().is_empty()),
        }
    }

    #[test]
    fn bone_names_parser_never_panics(spec in "\\PC{0,60}") {
        if let Ok(names) = rig::parse_bone_names(&spec) {
            prop_assert!(names.iter().all(|n| !n.is_empty()));
        }
    }
}
