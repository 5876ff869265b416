//! Triangle surfaces from OBJ `v` / `f` lines (obstacles, later cloth): polygons are
//! fan-triangulated; indices are 1-based or negative (relative), in the `v`, `v/vt`, `v//vn` or
//! `v/vt/vn` forms. Errors name the file and line.

use std::path::Path;

use nalgebra::Vector3;

use super::error::{MeshError, MeshErrorKind};
use super::lines::{parse_coord, parse_int, tokens_at_least, LineCursor};

/// A triangle surface.
#[derive(Debug, Clone, PartialEq)]
pub struct TriSurface {
    /// Vertex positions.
    pub vertices: Vec<Vector3<f64>>,
    /// Triangles (0-based).
    pub triangles: Vec<[usize; 3]>,
}

impl TriSurface {
    /// A copy scaled by `s` about the origin.
    ///
    /// ```
    /// use diffsoft::mesh::surface::parse_obj;
    ///
    /// let tri = parse_obj("tri.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")?;
    /// let big = tri.scaled(2.0);
    /// assert_eq!(big.vertices[1].x, 2.0);
    /// assert_eq!(big.triangles, tri.triangles);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn scaled(&self, s: f64) -> TriSurface {
        TriSurface {
            vertices: self.vertices.iter().map(|v| v * s).collect(),
            triangles: self.triangles.clone(),
        }
    }
}

/// Read an OBJ file's surface (`v` and `f` lines; everything else is ignored).
///
/// ```
/// use diffsoft::mesh::surface::load_obj;
///
/// let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../verification/paper/cloth_ball/flag2.obj");
/// let flag = load_obj(path)?;
/// assert!(!flag.triangles.is_empty());
/// assert!(flag.triangles.iter().flatten().all(|&i| i < flag.vertices.len()));
/// assert!(load_obj("no/such/file.obj").is_err());
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn load_obj(path: impl AsRef<Path>) -> Result<TriSurface, MeshError> {
    let path = path.as_ref();
    let shown = path.display().to_string();
    let text = crate::base::input_file::read_text(path)
        .map_err(|e| MeshError::file(&shown, MeshErrorKind::Io(e.to_string())))?;
    parse_obj(&shown, &text)
}

/// Parse OBJ surface text; `name` is used in messages.
///
/// ```
/// use diffsoft::mesh::surface::parse_obj;
///
/// // A quad is fan-triangulated; indices are 1-based.
/// let quad = parse_obj("quad.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n")?;
/// assert_eq!(quad.triangles, vec![[0, 1, 2], [0, 2, 3]]);
/// assert!(parse_obj("bad.obj", "v 0 0 0\nf 1 2 9\n").is_err());
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn parse_obj(name: &str, text: &str) -> Result<TriSurface, MeshError> {
    let mut cur = LineCursor::new(name, text, Some('#'));
    let mut vertices = Vec::new();
    // Each face with its line and the vertices read before it: a negative index counts back
    // from the last vertex above its line (the OBJ rule), not from the end of the file.
    let mut faces: Vec<(usize, i64, Vec<i64>)> = Vec::new();
    while let Some((line, content)) = cur.next_line() {
        let mut toks = content.split_whitespace();
        match toks.next() {
            Some("v") => {
                let t = tokens_at_least(name, line, content, 4, "vertex line 'v x y z'")?;
                vertices.push(Vector3::new(
                    parse_coord(name, line, t[1])?,
                    parse_coord(name, line, t[2])?,
                    parse_coord(name, line, t[3])?,
                ));
            }
            Some("f") => {
                let t = tokens_at_least(name, line, content, 4, "face line 'f a b c ...'")?;
                let mut idx = Vec::with_capacity(t.len() - 1);
                for tok in &t[1..] {
                    let first = tok.split('/').next().unwrap_or("");
                    idx.push(parse_int(name, line, first)?);
                }
                faces.push((line, vertices.len() as i64, idx));
            }
            _ => {}
        }
    }
    let n = vertices.len() as i64;
    let mut triangles = Vec::new();
    for (face, (line, above, idx)) in faces.into_iter().enumerate() {
        let mut resolved = Vec::with_capacity(idx.len());
        for i in idx {
            let r = if i > 0 { i - 1 } else { above + i };
            if i == 0 || r < 0 || r >= n {
                return Err(MeshError::at(
                    name,
                    line,
                    MeshErrorKind::Syntax(format!(
                        "face {face}: vertex index {i} out of range (1..={n}, or -1..=-{above} counting back from the {above} vertices above this line)"
                    )),
                ));
            }
            resolved.push(r as usize);
        }
        for k in 1..resolved.len() - 1 {
            triangles.push([resolved[0], resolved[k], resolved[k + 1]]);
        }
    }
    if triangles.is_empty() {
        return Err(MeshError::file(
            name,
            MeshErrorKind::Syntax("no faces ('f' lines)".into()),
        ));
    }
    Ok(TriSurface { vertices, triangles })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quads_are_fan_triangulated_and_indices_resolved() {
        let s = parse_obj(
            "q.obj",
            "v 0 0 0\nv 1 0 0\nv 1 0 1\nv 0 0 1\nvt 0 0\nf 1/1/1 2/1/1 3/1/1 4/1/1\nf -4 -3 -2\n",
        )
        .unwrap();
        assert_eq!(s.triangles, vec![[0, 1, 2], [0, 2, 3], [0, 1, 2]]);
        // Negative indices count back from the vertices above their own line, not from the
        // end of the file: here the first face is the first three vertices.
        let s = parse_obj("rel.obj", "v 0 0 0\nv 1 0 0\nv 1 0 1\nf -3 -2 -1\nv 0 0 1\nf -2 -1 1\n").unwrap();
        assert_eq!(s.triangles, vec![[0, 1, 2], [2, 3, 0]]);
        let e = parse_obj("rel.obj", "v 0 0 0\nv 1 0 0\nf -3 -2 -1\nv 1 0 1\n").unwrap_err();
        assert!(
            e.to_string().contains(
                "vertex index -3 out of range (1..=3, or -1..=-2 counting back from the 2 vertices above this line)"
            ),
            "{e}"
        );
        let e = parse_obj("q.obj", "v 0 0 0\nv 1 0 0\nv 1 0 1\nf 1 2 5\n").unwrap_err();
        assert_eq!(e.location.line, Some(4));
    }
}
