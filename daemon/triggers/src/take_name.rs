//! A trigger's take name made into a frond take name.
//!
//! A stage master names takes freely (`Scene 12 / take 3`, `dance`, `Ünïcode`); frond's take
//! names follow one rule, [`frond_protocol::paths::validate_take_name`]: 1-128 bytes of ASCII
//! letters, digits, `-`, `_`, `.`, not starting with `.`, so a name can never escape the takes
//! directory. [`safe_take_name`] maps any name onto that rule and checks the result with the
//! same function every other take name passes, so the rule lives in one place.

use frond_protocol::paths::validate_take_name;

/// The longest take name (the rule's bound).
const MAX_TAKE_NAME: usize = 128;

/// `name` made a valid take name: every character outside the rule becomes `_`, runs of `_`
/// collapse, leading dots and underscores go, and the result is cut to 128 bytes. A name with
/// nothing left (empty, all punctuation) gives `fallback` (which must itself be valid, e.g.
/// `trigger-33360` from the packet id). `None` only if `fallback` is not valid either.
pub fn safe_take_name(name: &str, fallback: &str) -> Option<String> {
    let mut out = String::with_capacity(name.len().min(MAX_TAKE_NAME));
    for c in name.chars() {
        let c = if c.is_ascii_alphanumeric() || matches!(c, '-' | '.') { c } else { '_' };
        if c == '_' && (out.is_empty() || out.ends_with('_')) {
            continue;
        }
        if c == '.' && out.is_empty() {
            continue;
        }
        if out.len() == MAX_TAKE_NAME {
            break;
        }
        out.push(c);
    }
    while out.ends_with('_') {
        out.pop();
    }
    if validate_take_name(&out).is_ok() {
        return Some(out);
    }
    validate_take_name(fallback).is_ok().then(|| fallback.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_made_safe_by_the_take_name_rule() {
        let cases = [
            ("dance", "dance"),
            ("RemoteTriggerTest_take01", "RemoteTriggerTest_take01"),
            ("Scene 12 / take 3", "Scene_12_take_3"),
            ("../../etc/passwd", "etc_passwd"),
            (".hidden", "hidden"),
            ("Ünïcode tàke", "n_code_t_ke"),
            ("a\0b", "a_b"),
            ("D:\\Captures\\x", "D_Captures_x"),
        ];
        for (raw, safe) in cases {
            assert_eq!(safe_take_name(raw, "fallback").as_deref(), Some(safe), "{raw:?}");
        }
        assert_eq!(safe_take_name("", "trigger-1").as_deref(), Some("trigger-1"));
        assert_eq!(safe_take_name("/// ...", "trigger-1").as_deref(), Some("trigger-1"));
        assert_eq!(safe_take_name("", "../bad"), None);
        let long = safe_take_name(&"x".repeat(1000), "f").unwrap();
        assert_eq!(long.len(), 128);
    }
}
