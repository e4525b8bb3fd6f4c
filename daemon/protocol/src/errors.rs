//! Printing text that came from outside (a file, a peer) safely: [`printable`].
//!
//! (How an error is printed, its causes said once, is `frond_binmain::error_text`: it is about
//! any error, not the wire protocol.)

/// `text` with its control characters escaped (`\u{1b}`, `\n`), for printing a name that came
/// from a file or a peer (a take's header, a daemon's hello, a rig): an escape sequence or a
/// line break in it must not reach the terminal, forge a log line or break a table.
pub fn printable(text: &str) -> std::borrow::Cow<'_, str> {
    if text.chars().any(char::is_control) {
        text.chars()
            .map(|c| if c.is_control() { c.escape_debug().to_string() } else { c.to_string() })
            .collect()
    } else {
        text.into()
    }
}

#[cfg(test)]
mod printable_tests {
    #[test]
    fn control_characters_are_escaped_and_the_rest_kept() {
        assert_eq!(super::printable("grass"), "grass");
        assert_eq!(super::printable("a\u{1b}[31mRED\nline2"), "a\\u{1b}[31mRED\\nline2");
        assert_eq!(super::printable("pétale\t"), "pétale\\t");
    }
}
