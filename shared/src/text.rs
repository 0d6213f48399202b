//! Text in messages: what a message quotes of its input is short and printable.

/// The most characters of an input token a message quotes.
pub const EXCERPT: usize = 40;

/// `s` as a message quotes it: at most [`EXCERPT`] characters (then `...` and the length in
/// bytes), control characters such as NUL escaped.
pub fn excerpt(s: &str) -> String {
    let mut out = String::new();
    for (n, c) in s.chars().enumerate() {
        if n == EXCERPT {
            out.push_str(&format!("... ({} bytes)", s.len()));
            break;
        }
        if c.is_control() {
            out.extend(c.escape_default());
        } else {
            out.push(c);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn long_tokens_are_cut_and_control_characters_escaped() {
        assert_eq!(excerpt("1.5x"), "1.5x");
        assert_eq!(excerpt("a\0b\n"), "a\\u{0}b\\n");
        let long = "9".repeat(1_000_000);
        let e = excerpt(&long);
        assert!(e.len() < 70 && e.ends_with("(1000000 bytes)"), "{e}");
    }
}
