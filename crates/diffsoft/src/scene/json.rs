//! JSON with trailing commas (the paper's `fish.json` has one): commas that directly precede a
//! closing `}` or `]` (outside strings) are replaced by a space, so line and column numbers in
//! serde_json's messages still point into the original file. A key given twice in one object
//! with different values is an error at its second occurrence (a plain `serde_json::Value`
//! keeps the last silently, so a scene edited by appending a key would run with whichever came
//! last); repeated with the same value, it is read once.

use serde::de::{Deserialize, DeserializeOwned, Deserializer, Error as _, MapAccess, SeqAccess, Visitor};
use serde_json::Value;

/// `T` read from JSON text, an error naming where in the document it arose
/// (`bodies[0].material.youngs_modulus: invalid type: ... at line 14 column 31`): serde's own
/// message names only the line, and nothing at all for a document built in code.
pub fn typed_from_str<T: DeserializeOwned>(text: &str) -> Result<T, String> {
    let mut de = serde_json::Deserializer::from_str(text);
    let value = serde_path_to_error::deserialize(&mut de).map_err(located)?;
    // As `serde_json::from_str`: nothing but white space may follow the document.
    de.end().map_err(|e| e.to_string())?;
    Ok(value)
}

/// `T` read from a JSON document held in memory (a scene built as a Python dict), an error
/// naming where in the document it arose, as [`typed_from_str`].
pub fn typed_from_value<T: DeserializeOwned>(value: Value) -> Result<T, String> {
    serde_path_to_error::deserialize(value).map_err(located)
}

/// The error with its place in the document in front, where it has one.
fn located<E: std::fmt::Display>(e: serde_path_to_error::Error<E>) -> String {
    let path = e.path().to_string();
    if path.is_empty() || path == "." {
        e.inner().to_string()
    } else {
        format!("{path}: {}", e.inner())
    }
}

/// Parse JSON, tolerating trailing commas and refusing a key given twice in one object with
/// different values.
pub fn parse_lenient(text: &str) -> Result<Value, serde_json::Error> {
    serde_json::from_str::<Unique>(&strip_trailing_commas(text)).map(|u| u.0)
}

/// A JSON value whose objects give no key two different values.
struct Unique(Value);

impl<'de> Deserialize<'de> for Unique {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        d.deserialize_any(UniqueVisitor)
    }
}

struct UniqueVisitor;

impl<'de> Visitor<'de> for UniqueVisitor {
    type Value = Unique;

    fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("a JSON value")
    }
    fn visit_bool<E>(self, v: bool) -> Result<Unique, E> {
        Ok(Unique(Value::Bool(v)))
    }
    fn visit_i64<E>(self, v: i64) -> Result<Unique, E> {
        Ok(Unique(Value::from(v)))
    }
    fn visit_u64<E>(self, v: u64) -> Result<Unique, E> {
        Ok(Unique(Value::from(v)))
    }
    fn visit_f64<E>(self, v: f64) -> Result<Unique, E> {
        Ok(Unique(Value::from(v)))
    }
    fn visit_str<E>(self, v: &str) -> Result<Unique, E> {
        Ok(Unique(Value::from(v)))
    }
    fn visit_string<E>(self, v: String) -> Result<Unique, E> {
        Ok(Unique(Value::String(v)))
    }
    fn visit_unit<E>(self) -> Result<Unique, E> {
        Ok(Unique(Value::Null))
    }
    fn visit_none<E>(self) -> Result<Unique, E> {
        Ok(Unique(Value::Null))
    }
    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Unique, A::Error> {
        let mut out = Vec::new();
        while let Some(Unique(v)) = seq.next_element()? {
            out.push(v);
        }
        Ok(Unique(Value::Array(out)))
    }
    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Unique, A::Error> {
        let mut out = serde_json::Map::new();
        while let Some(key) = map.next_key::<String>()? {
            let Unique(v) = map.next_value()?;
            match out.get(&key) {
                // The paper's fish.json repeats `"Actuator type": 1`: the same value is harmless.
                Some(first) if *first == v => {}
                Some(first) => {
                    return Err(A::Error::custom(format!(
                        "key \"{key}\" is given twice in one object with different values ({first}, then {v}): which applies is ambiguous; remove one (the later one ends)"
                    )))
                }
                None => {
                    out.insert(key, v);
                }
            }
        }
        Ok(Unique(Value::Object(out)))
    }
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

    /// A key given twice in one object with different values is an error at its second
    /// occurrence, naming it and both values; with the same value (the paper's fish.json) it is
    /// read once; the same key in different objects, and every kind of value, parse as
    /// serde_json's own.
    #[test]
    fn a_key_given_twice_is_refused_where_it_repeats() {
        let e = parse_lenient("{\n\"E\": 2e5,\n\"m\": {\"E\": 1},\n\"E\": 5e3,\n\"z\": 0\n}").unwrap_err();
        assert_eq!(e.line(), 4, "{e}");
        assert!(
            e.to_string().ends_with("(the later one ends) at line 4 column 8"),
            "{e}"
        );
        assert!(
            e.to_string()
                .contains("key \"E\" is given twice in one object with different values (200000.0, then 5000.0)"),
            "{e}"
        );
        let v = parse_lenient("{\"t\": 1, \"E\": [1, 2], \"t\": 1}").unwrap();
        assert_eq!(v, serde_json::json!({"t": 1, "E": [1, 2]}));
        let text = r#"{"a": {"k": 1}, "b": {"k": [true, null, -3, 18446744073709551615, 1.5e-300, "s"]}}"#;
        assert_eq!(
            parse_lenient(text).unwrap(),
            serde_json::from_str::<Value>(text).unwrap()
        );
    }
}
