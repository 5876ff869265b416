//! Text encodings the page needs: HTML escaping, percent-encoding of relative links and the
//! short display of numbers (the embedded plots' base64 is `diffsoft::output::base64`).

/// `text` with `& < > " '` replaced by entities: safe in element content and quoted attributes.
pub(crate) fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

/// A relative path (`/`-separated) as a URL path: every byte but the unreserved ones
/// (`A-Z a-z 0-9 - . _ ~`) and `/` percent-encoded, so that `#`, `?`, `%` and spaces in a file
/// name stay part of it.
pub(crate) fn url_path(path: &str) -> String {
    let mut out = String::with_capacity(path.len());
    for b in path.bytes() {
        if b.is_ascii_alphanumeric() || matches!(b, b'-' | b'.' | b'_' | b'~' | b'/') {
            out.push(char::from(b));
        } else {
            out.push_str(&format!("%{b:02X}"));
        }
    }
    out
}

/// A number as the table shows it: four significant digits, plain between 1e-3 and 1e4,
/// scientific otherwise (`2.459`, `0.0125`, `8.997e-14`, `5.273e4`); zero is `0`.
pub(crate) fn short_number(x: f64) -> String {
    if x == 0.0 {
        return "0".into();
    }
    if !x.is_finite() {
        return x.to_string();
    }
    let a = x.abs();
    if (1e-3..1e4).contains(&a) {
        // Digits after the point for four significant ones.
        let decimals = (3 - a.log10().floor() as i32).clamp(0, 6) as usize;
        let s = format!("{x:.decimals$}");
        let s = if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        };
        // Rounding up can reach the next decade (9999.5 -> 10000): scientific then.
        if s.trim_start_matches('-').len() <= 10 && s.trim_start_matches('-').parse::<f64>().is_ok_and(|v| v < 1e4) {
            return s;
        }
    }
    let s = format!("{x:.3e}");
    // `1.500e-3` -> `1.5e-3`
    match s.split_once('e') {
        Some((m, e)) if m.contains('.') => format!("{}e{e}", m.trim_end_matches('0').trim_end_matches('.')),
        _ => s,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn escapes_markup_and_quotes() {
        assert_eq!(
            escape(r#"<b a='1'>"x" & y</b>"#),
            "&lt;b a=&#39;1&#39;&gt;&quot;x&quot; &amp; y&lt;/b&gt;"
        );
        assert_eq!(escape("plain h*_19 <= 2"), "plain h*_19 &lt;= 2");
    }

    #[test]
    fn url_paths_keep_separators_and_encode_the_rest() {
        assert_eq!(url_path("sweeps/ball.json"), "sweeps/ball.json");
        assert_eq!(url_path("a b#c?d%e\"f.svg"), "a%20b%23c%3Fd%25e%22f.svg");
        assert_eq!(url_path("é.json"), "%C3%A9.json");
    }

    #[test]
    fn numbers_show_four_significant_digits() {
        for (x, shown) in [
            (0.0, "0"),
            (2.459157037369615, "2.459"),
            (2.0, "2"),
            (-0.0125, "-0.0125"),
            (0.001, "0.001"),
            (8.996710149251439e-14, "8.997e-14"),
            (52728.0, "5.273e4"),
            (9999.7, "1e4"),
            (1234.5678, "1235"),
            (1e-9, "1e-9"),
            (-3.0e20, "-3e20"),
        ] {
            assert_eq!(short_number(x), shown, "{x:e}");
        }
        // What is shown reads back within half a unit of the fourth digit.
        for x in [1.23456e-7, 0.09876543, 2.71234, 987.654, 123456.0] {
            let back: f64 = short_number(x).parse().unwrap();
            assert!(((back - x) / x).abs() <= 5e-4, "{x} -> {back}");
        }
    }
}
