//! TetGen `.node` / `.ele` pairs. Numbering is 0- or 1-based, decided (as TetGen does) by the
//! first node id; ids must then be consecutive. `#` starts a comment anywhere on a line.
//! Quadratic (10-node) tets keep their four corners; the mid-edge nodes become unused and are
//! dropped.

use super::error::{MeshError, MeshErrorKind};
use super::lines::{parse_coord, parse_count, parse_int, tokens_at_least, LineCursor};
use super::RawMesh;

pub(crate) fn parse(node_path: &str, node_text: &str, ele_path: &str, ele_text: &str) -> Result<RawMesh, MeshError> {
    let mut raw = RawMesh::default();

    // .node header: <#points> <dimension (3)> <#attributes> <boundary markers (0 or 1)>
    let mut cur = LineCursor::new(node_path, node_text, Some('#'));
    let (line, content) = cur.expect_line("the .node header '<#points> 3 <#attrs> <#markers>'")?;
    let toks = tokens_at_least(node_path, line, content, 1, ".node header")?;
    let n_points = parse_count(node_path, line, toks[0])?;
    let dim = match toks.get(1) {
        Some(t) => parse_count(node_path, line, t)?,
        None => 3,
    };
    if dim != 3 {
        return Err(MeshError::at(
            node_path,
            line,
            MeshErrorKind::UnsupportedFormat(format!("dimension {dim}, expected 3")),
        ));
    }
    let mut first_id = 0i64;
    for p in 0..n_points {
        let (line, content) = cur.expect_line(&format!("{n_points} nodes (header), found only {p}"))?;
        let toks = tokens_at_least(node_path, line, content, 4, "node line '<id> x y z'")?;
        let id = parse_int(node_path, line, toks[0])?;
        if p == 0 {
            if id != 0 && id != 1 {
                return Err(MeshError::at(
                    node_path,
                    line,
                    MeshErrorKind::Syntax(format!("first node id is {id}; TetGen numbering starts at 0 or 1")),
                ));
            }
            first_id = id;
        } else if id != first_id + p as i64 {
            return Err(MeshError::at(
                node_path,
                line,
                MeshErrorKind::Syntax(format!(
                    "node id {id} out of sequence (expected {})",
                    first_id + p as i64
                )),
            ));
        }
        let mut x = [0.0; 3];
        for k in 0..3 {
            x[k] = parse_coord(node_path, line, toks[k + 1])?;
        }
        raw.nodes.push(x);
        raw.node_ids.push(id);
    }
    beyond_count(&mut cur, node_path, n_points, "nodes")?;

    // .ele header: <#tets> <nodes per tet (4 or 10)> <#attributes>
    let mut cur = LineCursor::new(ele_path, ele_text, Some('#'));
    let (line, content) = cur.expect_line("the .ele header '<#tets> <4|10> <#attrs>'")?;
    let toks = tokens_at_least(ele_path, line, content, 1, ".ele header")?;
    let n_tets = parse_count(ele_path, line, toks[0])?;
    let per_tet = match toks.get(1) {
        Some(t) => parse_count(ele_path, line, t)?,
        None => 4,
    };
    if per_tet != 4 && per_tet != 10 {
        return Err(MeshError::at(
            ele_path,
            line,
            MeshErrorKind::UnsupportedFormat(format!("{per_tet} nodes per tetrahedron (expected 4 or 10)")),
        ));
    }
    let n = n_points as i64;
    for t in 0..n_tets {
        let (line, content) = cur.expect_line(&format!("{n_tets} tets (header), found only {t}"))?;
        let toks = tokens_at_least(ele_path, line, content, 1 + per_tet, "tet line '<id> n0 n1 n2 n3'")?;
        parse_int(ele_path, line, toks[0])?;
        let mut tet = [0usize; 4];
        for k in 0..4 {
            let id = parse_int(ele_path, line, toks[k + 1])?;
            let i = id - first_id;
            if i < 0 || i >= n {
                return Err(MeshError::at(
                    ele_path,
                    line,
                    MeshErrorKind::IndexOutOfRange {
                        tet: t,
                        index: id.into(),
                        valid: format!(
                            "{first_id}..={} for {n_points} nodes in the .node file",
                            first_id + n - 1
                        ),
                    },
                ));
            }
            tet[k] = i as usize;
        }
        for tok in &toks[5..1 + per_tet] {
            parse_int(ele_path, line, tok)?;
        }
        raw.tets.push(tet);
        raw.tet_lines.push(line);
    }
    beyond_count(&mut cur, ele_path, n_tets, "tets")?;
    Ok(raw)
}

/// Refuse content after the `count` entries a header announced (TetGen reads only those, so a
/// file with more has a header that does not match it, and its extra entries would be dropped
/// without a word).
fn beyond_count(cur: &mut LineCursor<'_>, path: &str, count: usize, what: &str) -> Result<(), MeshError> {
    match cur.next_line() {
        None => Ok(()),
        Some((line, _)) => Err(MeshError::at(
            path,
            line,
            MeshErrorKind::Syntax(format!(
                "more lines than the header's {count} {what}: correct the count in the header, or remove what follows"
            )),
        )),
    }
}
