//! A rig file's `[vmc]` and `[guided]` tables, `bend_range_deg` and names: parsed, written back
//! and validated with the messages a user sees.

use frond_formats::rig_toml::RigText;
use frond_motion::{GuidedSpec, Rig};

const BASE: &str = "name = \"g\"\n[[joints]]\nheight_m = 0.0\n[[joints]]\nheight_m = 0.1\n[[joints]]\nheight_m = 0.2\n[[joints]]\nheight_m = 0.3\n";

#[test]
fn vmc_table_names_the_bones_round_trips_and_is_validated() {
    let rig =
        Rig::from_toml_str(&format!("{BASE}[vmc]\nbones = [\"Hips\", \"Spine\", \"Chest\", \"Head\"]\n"))
            .unwrap();
    assert_eq!(rig.vmc_bones, Some(["Hips", "Spine", "Chest", "Head"].map(String::from)));
    assert_eq!(rig.joint_names(), ["joint0", "joint1", "joint2", "joint3"], "joint names unchanged");
    assert_eq!(Rig::from_toml_str(&rig.to_toml_string()).unwrap(), rig);
    assert_eq!(Rig::from_toml_str(BASE).unwrap().vmc_bones, None);
    let long = "x".repeat(256);
    let err = Rig::from_toml_str(&format!("{BASE}[vmc]\nbones = [\"a\", \"\", \"{long}\"]\n"))
        .unwrap_err()
        .to_string();
    assert!(err.contains("vmc.bones: expected 4 names, found 3"), "{err}");
    assert!(err.contains("vmc.bones[1]: must be 1 to 255 bytes"), "{err}");
    assert!(err.contains("vmc.bones[2]: must be 1 to 255 bytes"), "{err}");
    assert!(!err.contains("vmc.bones[0]"), "{err}");
    let err = Rig::from_toml_str(&format!("{BASE}[vmc]\nbone = []\n")).unwrap_err().to_string();
    assert!(err.contains("unknown field `bone`"), "{err}");
}

#[test]
fn names_are_printable_bounded_and_a_rig_name_is_no_path() {
    let with_name = |name: &str| BASE.replacen("name = \"g\"", &format!("name = {name:?}"), 1);
    let err = |text: &str| Rig::from_toml_str(text).unwrap_err().to_string();
    // TOML's "\u001b" and "\n" escapes: an ANSI colour and a line break in the name.
    let e = err(&BASE.replacen("name = \"g\"", "name = \"a\\u001b[31mRED\\nline2\"", 1));
    assert!(e.contains("name: contains the control character '\\u{1b}'; a name must be printable"), "{e}");
    for path_like in ["/dev/zero", "..", ".hidden", "shrub.toml"] {
        let e = err(&with_name(path_like));
        assert!(
            e.contains("name: contains '/', starts with '.' or ends in .toml; a rig name is a name"),
            "{e}"
        );
    }
    assert!(err(&with_name(&"r".repeat(65))).contains("name: is 65 bytes; the limit is 64"));
    assert_eq!(Rig::from_toml_str(&with_name(&"r".repeat(64))).unwrap().name.len(), 64);
    let e = err(&BASE.replacen("height_m = 0.1", "height_m = 0.1\nname = \"tab\\there\"", 1));
    assert!(e.contains("joints[1].name: contains the control character '\\t'"), "{e}");
    let e = err(&format!("{BASE}[vmc]\nbones = [\"a\", \"b\\n\", \"c\", \"d\"]\n"));
    assert!(e.contains("vmc.bones[1]: contains the control character '\\n'"), "{e}");
}

#[test]
fn guided_table_parses_round_trips_and_is_validated() {
    let rig = Rig::from_toml_str(&format!("{BASE}[guided]\nsigma_s = [0.1, 0.2, 0.3]\n")).unwrap();
    assert_eq!(rig.guided, Some(GuidedSpec { sigma_s: [0.1, 0.2, 0.3], s_g: [1.0; 3] }));
    assert_eq!(Rig::from_toml_str(&rig.to_toml_string()).unwrap().guided, rig.guided);
    assert_eq!(Rig::from_toml_str(BASE).unwrap().guided, None);
    let err =
        Rig::from_toml_str(&format!("{BASE}[guided]\nsigma_s = [0.1, -1, 99]\n")).unwrap_err().to_string();
    assert!(err.contains("guided.sigma_s[1]") && err.contains("guided.sigma_s[2]"), "{err}");
}

#[test]
fn bend_range_parses_round_trips_and_is_validated() {
    let rig = Rig::from_toml_str(&format!("bend_range_deg = [20.0, 15.5]\n{BASE}")).unwrap();
    assert_eq!(rig.bend_range_deg, Some([20.0, 15.5]));
    assert_eq!(rig.mapping().bend_range_deg, Some([20.0, 15.5]));
    assert_eq!(Rig::from_toml_str(&rig.to_toml_string()).unwrap(), rig);
    let none = Rig::from_toml_str(BASE).unwrap();
    assert_eq!(none.bend_range_deg, None);
    assert!(!none.to_toml_string().contains("bend_range_deg"));
    let err = Rig::from_toml_str(&format!("bend_range_deg = [0, 181]\n{BASE}")).unwrap_err().to_string();
    assert!(
        err.contains(
            "bend_range_deg[0]: the pitch bend range must be above 0 and at most 180 degrees, found 0"
        ),
        "{err}"
    );
    assert!(err.contains("bend_range_deg[1]: the yaw bend range") && err.contains("found 181"), "{err}");
    let err = Rig::from_toml_str(&format!("bend_range_deg = [nan, -3]\n{BASE}")).unwrap_err().to_string();
    assert!(err.contains("bend_range_deg[0]") && err.contains("found -3"), "{err}");
    let err = Rig::from_toml_str(&format!("bend_range_deg = [10]\n{BASE}")).unwrap_err().to_string();
    assert!(err.contains("bend_range_deg"), "{err}");
}
