//! Reading the scene format's one-key objects (`{"indices": [...]}` or `{"box": {...}}`, a
//! joint's `{"rotational": {...}}`): serde's derived reader answers an object with two keys or
//! none with "expected value", which names neither the keys nor what to give. These readers
//! take the first key as the kind, read its value in place (so an error inside it keeps its
//! path, line and column) and refuse a second key or an empty object by name.

use serde::de::{Deserializer, Error as _, MapAccess, Visitor};
use serde::Deserialize;

use super::format::{JointFile, TetSelector, VertexSelector};

/// The kind an object of `what` names by its first key, one of `kinds`.
fn kind<'de, A: MapAccess<'de>>(map: &mut A, what: &str, kinds: &'static [&'static str]) -> Result<String, A::Error> {
    match map.next_key::<String>()? {
        None => Err(A::Error::custom(format!(
            "{what} is an empty object: give one of {}",
            listed(kinds)
        ))),
        Some(k) if kinds.contains(&k.as_str()) => Ok(k),
        Some(k) => Err(A::Error::unknown_variant(&k, kinds)),
    }
}

/// Refuse a second key after the kind `first` of an object of `what`.
fn only<'de, A: MapAccess<'de>>(
    map: &mut A,
    what: &str,
    first: &str,
    kinds: &'static [&'static str],
) -> Result<(), A::Error> {
    match map.next_key::<String>()? {
        None => Ok(()),
        Some(k) => Err(A::Error::custom(format!(
            "{what} gives both \"{first}\" and \"{k}\": give exactly one of {}",
            listed(kinds)
        ))),
    }
}

fn listed(kinds: &[&str]) -> String {
    kinds.iter().map(|k| format!("\"{k}\"")).collect::<Vec<_>>().join(", ")
}

/// An object that must be empty (`"all": {}`, `"free": {}`).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Empty {}

/// An axis-aligned box.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct BoxFields {
    min: [f64; 3],
    max: [f64; 3],
}

/// Vertex ids and how many of a tet's vertices must be among them.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SharedFields {
    indices: Vec<usize>,
    min_shared: usize,
}

/// A rotational joint.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RotationalFields {
    position: [f64; 3],
    axis: [f64; 3],
    #[serde(default)]
    angle: f64,
    #[serde(default)]
    limits: Option<[f64; 2]>,
}

/// A prismatic joint.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PrismaticFields {
    axis: [f64; 3],
    #[serde(default)]
    extension: f64,
    #[serde(default)]
    limits: Option<[f64; 2]>,
}

/// A type read from a one-key object: what it is called in messages, its kinds, and how each
/// kind's value is read.
trait OneKey: Sized {
    const WHAT: &'static str;
    const KINDS: &'static [&'static str];
    /// Read the value of kind `kind` (one of `KINDS`) from `map`, positioned at it.
    fn read<'de, A: MapAccess<'de>>(kind: &str, map: &mut A) -> Result<Self, A::Error>;
}

struct OneKeyVisitor<T>(std::marker::PhantomData<T>);

impl<'de, T: OneKey> Visitor<'de> for OneKeyVisitor<T> {
    type Value = T;

    fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} (an object with one of {})", T::WHAT, listed(T::KINDS))
    }

    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<T, A::Error> {
        let k = kind(&mut map, T::WHAT, T::KINDS)?;
        let value = T::read(&k, &mut map)?;
        only(&mut map, T::WHAT, &k, T::KINDS)?;
        Ok(value)
    }
}

fn one_key<'de, D: Deserializer<'de>, T: OneKey>(d: D) -> Result<T, D::Error> {
    d.deserialize_map(OneKeyVisitor::<T>(std::marker::PhantomData))
}

impl OneKey for TetSelector {
    const WHAT: &'static str = "a tet selection";
    const KINDS: &'static [&'static str] = &["all", "indices", "box", "vertices"];
    fn read<'de, A: MapAccess<'de>>(kind: &str, map: &mut A) -> Result<Self, A::Error> {
        Ok(match kind {
            "all" => {
                let Empty {} = map.next_value()?;
                TetSelector::All {}
            }
            "indices" => TetSelector::Indices(map.next_value()?),
            "box" => {
                let BoxFields { min, max } = map.next_value()?;
                TetSelector::Box { min, max }
            }
            _ => {
                let SharedFields { indices, min_shared } = map.next_value()?;
                TetSelector::Vertices { indices, min_shared }
            }
        })
    }
}

impl OneKey for VertexSelector {
    const WHAT: &'static str = "a vertex selection";
    const KINDS: &'static [&'static str] = &["indices", "box"];
    fn read<'de, A: MapAccess<'de>>(kind: &str, map: &mut A) -> Result<Self, A::Error> {
        Ok(match kind {
            "indices" => VertexSelector::Indices(map.next_value()?),
            _ => {
                let BoxFields { min, max } = map.next_value()?;
                VertexSelector::Box { min, max }
            }
        })
    }
}

impl OneKey for JointFile {
    const WHAT: &'static str = "a joint";
    const KINDS: &'static [&'static str] = &["free", "fixed", "rotational", "prismatic"];
    fn read<'de, A: MapAccess<'de>>(kind: &str, map: &mut A) -> Result<Self, A::Error> {
        Ok(match kind {
            "free" => {
                let Empty {} = map.next_value()?;
                JointFile::Free {}
            }
            "fixed" => {
                let Empty {} = map.next_value()?;
                JointFile::Fixed {}
            }
            "rotational" => {
                let RotationalFields {
                    position,
                    axis,
                    angle,
                    limits,
                } = map.next_value()?;
                JointFile::Rotational {
                    position,
                    axis,
                    angle,
                    limits,
                }
            }
            _ => {
                let PrismaticFields {
                    axis,
                    extension,
                    limits,
                } = map.next_value()?;
                JointFile::Prismatic {
                    axis,
                    extension,
                    limits,
                }
            }
        })
    }
}

impl<'de> Deserialize<'de> for TetSelector {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        one_key(d)
    }
}

impl<'de> Deserialize<'de> for VertexSelector {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        one_key(d)
    }
}

impl<'de> Deserialize<'de> for JointFile {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        one_key(d)
    }
}

#[cfg(test)]
mod tests {
    use super::super::json::{typed_from_str, typed_from_value};
    use super::*;

    /// Every kind reads as the format describes it; two keys, none, or an unknown one are
    /// refused naming the keys and the kinds; an error inside the value keeps its path, line and
    /// column; a document built in memory gets the same messages with the path.
    #[test]
    fn one_key_objects_name_what_is_wrong_with_them() {
        let v: VertexSelector = typed_from_str(r#"{"box": {"min": [0, 0, 0], "max": [1, 2, 3]}}"#).unwrap();
        assert!(matches!(
            v,
            VertexSelector::Box {
                max: [1.0, 2.0, 3.0],
                ..
            }
        ));
        let t: TetSelector = typed_from_str(r#"{"vertices": {"indices": [4, 5], "min_shared": 2}}"#).unwrap();
        assert!(matches!(t, TetSelector::Vertices { ref indices, min_shared: 2 } if indices == &[4, 5]));
        assert!(matches!(
            typed_from_str::<TetSelector>(r#"{"all": {}}"#).unwrap(),
            TetSelector::All {}
        ));
        let j: JointFile = typed_from_str(r#"{"rotational": {"position": [0, 0, 0], "axis": [0, 0, 1]}}"#).unwrap();
        assert!(matches!(
            j,
            JointFile::Rotational {
                angle: 0.0,
                limits: None,
                ..
            }
        ));
        let j: JointFile = typed_from_str(r#"{"prismatic": {"axis": [1, 0, 0], "limits": [0, 1]}}"#).unwrap();
        assert!(matches!(
            j,
            JointFile::Prismatic {
                limits: Some([0.0, 1.0]),
                ..
            }
        ));

        let e = typed_from_str::<VertexSelector>("{\"indices\": [1],\n \"box\": {}}").unwrap_err();
        assert!(
            e.starts_with(
                r#"a vertex selection gives both "indices" and "box": give exactly one of "indices", "box" at line 2"#
            ),
            "{e}"
        );
        let e = typed_from_str::<TetSelector>("{}").unwrap_err();
        assert!(
            e.starts_with(r#"a tet selection is an empty object: give one of "all", "indices", "box", "vertices""#),
            "{e}"
        );
        let e = typed_from_str::<JointFile>(r#"{"hinge": {}}"#).unwrap_err();
        assert!(
            e.starts_with("unknown variant `hinge`, expected one of `free`, `fixed`, `rotational`, `prismatic`"),
            "{e}"
        );
        let e = typed_from_str::<JointFile>(r#"{"free": {"axis": [0, 0, 1]}}"#).unwrap_err();
        assert!(e.starts_with("free.axis: unknown field `axis`"), "{e}");
        let e = typed_from_str::<TetSelector>("{\"box\": {\"min\": [0, 0],\n \"max\": [1, 1, 1]}}").unwrap_err();
        assert!(
            e.starts_with("box.min: invalid length 2, expected an array of length 3 at line 1"),
            "{e}"
        );
        let e = typed_from_value::<VertexSelector>(serde_json::json!({"indices": [0, 1.5]})).unwrap_err();
        assert_eq!(e, "indices[1]: invalid type: floating point `1.5`, expected usize");
        let e = typed_from_str::<VertexSelector>("[1, 2]").unwrap_err();
        assert!(
            e.contains(r#"expected a vertex selection (an object with one of "indices", "box")"#),
            "{e}"
        );
    }
}
