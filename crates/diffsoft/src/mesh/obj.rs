//! Wavefront OBJ with tet lines: `v x y z [w]` and `t i0 i1 i2 i3` (0-based, as in the paper's
//! files). Surface statements (`f`, `vt`, `vn`, groups, materials, ...) are ignored.

use super::error::{MeshError, MeshErrorKind};
use super::lines::{parse_coord, parse_int, tokens_at_least, LineCursor};
use super::RawMesh;

/// OBJ statements that carry no tet data and are skipped.
const IGNORED: &[&str] = &[
    "vt",
    "vn",
    "vp",
    "f",
    "l",
    "p",
    "o",
    "g",
    "s",
    "mg",
    "usemtl",
    "mtllib",
    "usemap",
    "maplib",
    "cstype",
    "deg",
    "bmat",
    "step",
    "curv",
    "curv2",
    "surf",
    "parm",
    "trim",
    "hole",
    "scrv",
    "sp",
    "end",
    "con",
    "bevel",
    "c_interp",
    "d_interp",
    "lod",
    "shadow_obj",
    "trace_obj",
    "ctech",
    "stech",
    "call",
    "csh",
];

pub(crate) fn parse(path: &str, text: &str) -> Result<RawMesh, MeshError> {
    let mut cur = LineCursor::new(path, text, Some('#'));
    let mut raw = RawMesh::default();
    // Tets with their raw indices; checked once all vertices are known.
    let mut tets: Vec<(usize, [i64; 4])> = Vec::new();
    while let Some((line, content)) = cur.next_line() {
        let keyword = content.split_whitespace().next().unwrap_or("");
        match keyword {
            "v" => {
                let toks = tokens_at_least(path, line, content, 4, "vertex line 'v x y z'")?;
                let mut p = [0.0; 3];
                for k in 0..3 {
                    p[k] = parse_coord(path, line, toks[k + 1])?;
                }
                raw.node_ids.push(raw.nodes.len() as i64);
                raw.nodes.push(p);
            }
            "t" => {
                let toks = tokens_at_least(path, line, content, 5, "tet line 't i0 i1 i2 i3'")?;
                if toks.len() > 5 {
                    return Err(MeshError::at(
                        path,
                        line,
                        MeshErrorKind::Syntax(format!(
                            "tet line has {} indices, expected 4 ('{content}')",
                            toks.len() - 1
                        )),
                    ));
                }
                let mut idx = [0i64; 4];
                for k in 0..4 {
                    idx[k] = parse_int(path, line, toks[k + 1])?;
                }
                tets.push((line, idx));
            }
            k if IGNORED.contains(&k) => {}
            other => {
                return Err(MeshError::at(
                    path,
                    line,
                    MeshErrorKind::Syntax(format!("unknown OBJ statement '{other}'")),
                ))
            }
        }
    }
    let n = raw.nodes.len() as i64;
    for (t, (line, idx)) in tets.into_iter().enumerate() {
        let mut tet = [0usize; 4];
        for k in 0..4 {
            if idx[k] < 0 || idx[k] >= n {
                let hint = if idx[k] == n && !idx.contains(&0) {
                    " (tet indices in OBJ files are 0-based; is this file 1-based?)"
                } else {
                    ""
                };
                return Err(MeshError::at(
                    path,
                    line,
                    MeshErrorKind::IndexOutOfRange {
                        tet: t,
                        index: idx[k].into(),
                        valid: format!("0..={} for {n} vertices{hint}", n - 1),
                    },
                ));
            }
            tet[k] = idx[k] as usize;
        }
        raw.tets.push(tet);
        raw.tet_lines.push(line);
    }
    Ok(raw)
}
