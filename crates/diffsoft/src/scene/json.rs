//! JSON with trailing commas (the paper's `fish.json` has one): commas that directly precede a
//! closing `}` or `]` (outside strings) are replaced by a space, so line and column numbers in
//! serde_json's messages still point into the original file.

/// Parse JSON, tolerating trailing commas.
pub fn parse_lenient(text: &str) -> Result<serde_json::Value, serde_json::Error> {
    serde_json::from_str(&strip_trailing_commas(text))
}

/// The text with trailing commas blanked out.
pub fn strip_trailing_commas(text: &str) -> String {
    let bytes = text.as_bytes();
    let mut out = bytes.to_vec();
    let mut in_string = false;
    let mut escaped = false;
    for i in 0..bytes.len() {
        let c = bytes[i];
        if in_string {
            if escaped {
                escaped = false;
            } else if c == b'\\' {
                escaped = true;
            } else if c == b'"' {
                in_string = false;
            }
            continue;
        }
        match c {
            b'"' => in_string = true,
            b',' => {
                let next = bytes[i + 1..].iter().find(|b| !b.is_ascii_whitespace());
                if matches!(next, Some(b'}') | Some(b']')) {
                    out[i] = b' ';
                }
            }
            _ => {}
        }
    }
    String::from_utf8(out).expect("only ASCII bytes were replaced")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trailing_commas_are_tolerated_and_strings_untouched() {
        let v = parse_lenient("{\"a\": [1, 2,], \"b\": \"x,}\",\n}").unwrap();
        assert_eq!(v["a"], serde_json::json!([1, 2]));
        assert_eq!(v["b"], "x,}");
        let e = parse_lenient("{\n\"a\": [1 2]\n}").unwrap_err();
        assert_eq!(e.line(), 2);
    }
}
