//! Gmsh `.msh` ASCII, versions 2.2 and 4.1. Only tetrahedra are read (linear type 4; higher-order
//! tets 11, 29, 30, 31 keep their four corners); other elements are skipped and counted. Nodes no
//! tet uses are dropped (and counted) by the common validation pass.

use std::collections::HashMap;

use super::error::{MeshError, MeshErrorKind};
use super::lines::{parse_coord, parse_count, parse_int, tokens_at_least, LineCursor};
use super::{MeshFormat, RawMesh};

/// Number of nodes of a Gmsh tetrahedron element type, or `None` for other element types.
fn tet_nodes(element_type: i64) -> Option<usize> {
    match element_type {
        4 => Some(4),
        11 => Some(10),
        29 => Some(20),
        30 => Some(35),
        31 => Some(56),
        _ => None,
    }
}

#[derive(Clone, Copy, PartialEq)]
enum Version {
    V2,
    V41,
}

pub(crate) fn parse(path: &str, text: &str) -> Result<(RawMesh, MeshFormat), MeshError> {
    let mut cur = LineCursor::new(path, text, None);
    let mut version: Option<Version> = None;
    let mut raw = RawMesh::default();
    let mut tag_to_index: HashMap<i64, usize> = HashMap::new();
    let mut saw_nodes = false;
    let mut saw_elements = false;
    while let Some((line, content)) = cur.next_line() {
        if !content.starts_with('$') {
            return Err(MeshError::at(
                path,
                line,
                MeshErrorKind::Syntax(format!("expected a section header like $Nodes, found '{content}'")),
            ));
        }
        let section = &content[1..];
        match section {
            "MeshFormat" => {
                let (line, content) = cur.expect_line("the $MeshFormat line 'version file-type data-size'")?;
                let toks = tokens_at_least(path, line, content, 3, "$MeshFormat line")?;
                let v = toks[0];
                version = Some(match v {
                    "2" | "2.0" | "2.1" | "2.2" => Version::V2,
                    "4.1" => Version::V41,
                    other => {
                        return Err(MeshError::at(
                            path,
                            line,
                            MeshErrorKind::UnsupportedFormat(format!(
                                "Gmsh version {other} (supported: ASCII 2.2 and 4.1; re-export with -format msh22 or msh41)"
                            )),
                        ))
                    }
                });
                if toks[1] != "0" {
                    return Err(MeshError::at(
                        path,
                        line,
                        MeshErrorKind::UnsupportedFormat(
                            "binary Gmsh file (file-type 1); only ASCII is supported".into(),
                        ),
                    ));
                }
                expect_end(&mut cur, "MeshFormat")?;
            }
            "Nodes" => {
                let v = version.ok_or_else(|| {
                    MeshError::at(path, line, MeshErrorKind::Syntax("$Nodes before $MeshFormat".into()))
                })?;
                match v {
                    Version::V2 => read_nodes_v2(&mut cur, &mut raw, &mut tag_to_index)?,
                    Version::V41 => read_nodes_v41(&mut cur, &mut raw, &mut tag_to_index)?,
                }
                expect_end(&mut cur, "Nodes")?;
                saw_nodes = true;
            }
            "Elements" => {
                let v = version.ok_or_else(|| {
                    MeshError::at(path, line, MeshErrorKind::Syntax("$Elements before $MeshFormat".into()))
                })?;
                if !saw_nodes {
                    return Err(MeshError::at(
                        path,
                        line,
                        MeshErrorKind::Syntax("$Elements before $Nodes".into()),
                    ));
                }
                match v {
                    Version::V2 => read_elements_v2(&mut cur, &mut raw, &tag_to_index)?,
                    Version::V41 => read_elements_v41(&mut cur, &mut raw, &tag_to_index)?,
                }
                expect_end(&mut cur, "Elements")?;
                saw_elements = true;
            }
            other if other.starts_with("End") => {
                return Err(MeshError::at(
                    path,
                    line,
                    MeshErrorKind::Syntax(format!("unexpected ${other} without its opening section")),
                ))
            }
            other => skip_section(&mut cur, other)?,
        }
    }
    let format = match version {
        Some(Version::V2) => MeshFormat::Gmsh22,
        Some(Version::V41) => MeshFormat::Gmsh41,
        None => {
            return Err(MeshError::file(
                path,
                MeshErrorKind::Syntax("no $MeshFormat section: not a Gmsh file".into()),
            ))
        }
    };
    if !saw_nodes || !saw_elements {
        return Err(MeshError::at(
            path,
            cur.last_line.max(1),
            MeshErrorKind::Truncated(format!(
                "missing {} section",
                if !saw_nodes { "$Nodes" } else { "$Elements" }
            )),
        ));
    }
    Ok((raw, format))
}

fn expect_end(cur: &mut LineCursor<'_>, section: &str) -> Result<(), MeshError> {
    let (line, content) = cur.expect_line(&format!("$End{section}"))?;
    if content != format!("$End{section}") {
        return Err(MeshError::at(
            cur.path(),
            line,
            MeshErrorKind::Syntax(format!(
                "expected $End{section}, found '{content}' (more entries than the section header announces?)"
            )),
        ));
    }
    Ok(())
}

fn skip_section(cur: &mut LineCursor<'_>, section: &str) -> Result<(), MeshError> {
    let end = format!("$End{section}");
    loop {
        let (_, content) = cur.expect_line(&end)?;
        if content == end {
            return Ok(());
        }
    }
}

fn add_node(
    path: &str,
    line: usize,
    tag: i64,
    x: [f64; 3],
    raw: &mut RawMesh,
    tag_to_index: &mut HashMap<i64, usize>,
) -> Result<(), MeshError> {
    if tag_to_index.insert(tag, raw.nodes.len()).is_some() {
        return Err(MeshError::at(
            path,
            line,
            MeshErrorKind::Syntax(format!("node tag {tag} defined twice")),
        ));
    }
    raw.nodes.push(x);
    raw.node_ids.push(tag);
    Ok(())
}

fn read_nodes_v2(
    cur: &mut LineCursor<'_>,
    raw: &mut RawMesh,
    tag_to_index: &mut HashMap<i64, usize>,
) -> Result<(), MeshError> {
    let path = cur.path();
    let (line, content) = cur.expect_line("the number of nodes")?;
    let count = parse_count(path, line, content)?;
    for k in 0..count {
        let (line, content) = cur.expect_line(&format!("{count} nodes (header), found only {k}"))?;
        let toks = tokens_at_least(path, line, content, 4, "node line 'tag x y z'")?;
        let tag = parse_int(path, line, toks[0])?;
        let x = [
            parse_coord(path, line, toks[1])?,
            parse_coord(path, line, toks[2])?,
            parse_coord(path, line, toks[3])?,
        ];
        add_node(path, line, tag, x, raw, tag_to_index)?;
    }
    Ok(())
}

fn read_nodes_v41(
    cur: &mut LineCursor<'_>,
    raw: &mut RawMesh,
    tag_to_index: &mut HashMap<i64, usize>,
) -> Result<(), MeshError> {
    let path = cur.path();
    let (line, content) = cur.expect_line("the $Nodes header 'numEntityBlocks numNodes minTag maxTag'")?;
    let toks = tokens_at_least(path, line, content, 4, "$Nodes header")?;
    let blocks = parse_count(path, line, toks[0])?;
    let total = parse_count(path, line, toks[1])?;
    let header_line = line;
    let mut seen = 0usize;
    for b in 0..blocks {
        let (line, content) = cur.expect_line(&format!("{blocks} node blocks (header), found only {b}"))?;
        let toks = tokens_at_least(
            path,
            line,
            content,
            4,
            "node block header 'entityDim entityTag parametric numNodes'",
        )?;
        let dim = parse_count(path, line, toks[0])?;
        let parametric = parse_count(path, line, toks[2])?;
        let n = parse_count(path, line, toks[3])?;
        // Grown as tags are read, never sized from the declared count: a header may claim more
        // entries than the file holds (the loop stops with an error at the end of the file).
        let mut tags = Vec::new();
        for k in 0..n {
            let (line, content) = cur.expect_line(&format!("{n} node tags in block {b}, found only {k}"))?;
            tags.push((line, parse_int(path, line, content)?));
        }
        let needed = 3 + if parametric == 1 { dim } else { 0 };
        for (k, &(_, tag)) in tags.iter().enumerate() {
            let (line, content) = cur.expect_line(&format!("{n} node coordinates in block {b}, found only {k}"))?;
            let toks = tokens_at_least(path, line, content, needed, "node coordinate line 'x y z'")?;
            let x = [
                parse_coord(path, line, toks[0])?,
                parse_coord(path, line, toks[1])?,
                parse_coord(path, line, toks[2])?,
            ];
            add_node(path, line, tag, x, raw, tag_to_index)?;
        }
        seen = checked_total(path, line, seen, n, "nodes")?;
    }
    if seen != total {
        return Err(MeshError::at(
            path,
            header_line,
            MeshErrorKind::Syntax(format!("$Nodes header announces {total} nodes, blocks hold {seen}")),
        ));
    }
    Ok(())
}

/// `seen + n` for the running count of a section's blocks, an error (naming the block's line)
/// when the declared counts overflow.
fn checked_total(path: &str, line: usize, seen: usize, n: usize, what: &str) -> Result<usize, MeshError> {
    seen.checked_add(n).ok_or_else(|| {
        MeshError::at(
            path,
            line,
            MeshErrorKind::Syntax(format!("block counts of {what} overflow ({seen} + {n})")),
        )
    })
}

fn push_tet(
    path: &str,
    line: usize,
    node_tags: &[&str],
    raw: &mut RawMesh,
    tag_to_index: &HashMap<i64, usize>,
) -> Result<(), MeshError> {
    let t = raw.tets.len();
    let mut tet = [0usize; 4];
    for k in 0..4 {
        let tag = parse_int(path, line, node_tags[k])?;
        tet[k] = *tag_to_index.get(&tag).ok_or_else(|| {
            MeshError::at(
                path,
                line,
                MeshErrorKind::IndexOutOfRange {
                    tet: t,
                    index: tag.into(),
                    valid: "must be a node tag defined in $Nodes".into(),
                },
            )
        })?;
    }
    for tok in &node_tags[4..] {
        parse_int(path, line, tok)?;
    }
    raw.tets.push(tet);
    raw.tet_lines.push(line);
    Ok(())
}

fn read_elements_v2(
    cur: &mut LineCursor<'_>,
    raw: &mut RawMesh,
    tag_to_index: &HashMap<i64, usize>,
) -> Result<(), MeshError> {
    let path = cur.path();
    let (line, content) = cur.expect_line("the number of elements")?;
    let count = parse_count(path, line, content)?;
    for k in 0..count {
        let (line, content) = cur.expect_line(&format!("{count} elements (header), found only {k}"))?;
        let toks = tokens_at_least(path, line, content, 3, "element line 'id type ntags tags... nodes...'")?;
        let ty = parse_int(path, line, toks[1])?;
        let ntags = parse_count(path, line, toks[2])?;
        match tet_nodes(ty) {
            Some(nn) => {
                // `ntags` comes from the file: a count beyond the line's tokens is an error, not
                // wrapped arithmetic.
                let end = ntags.checked_add(3 + nn).ok_or_else(|| {
                    MeshError::at(
                        path,
                        line,
                        MeshErrorKind::Syntax(format!("element declares {ntags} tags, more than the line holds")),
                    )
                })?;
                let toks = tokens_at_least(path, line, content, end, "tetrahedron element line")?;
                push_tet(path, line, &toks[3 + ntags..end], raw, tag_to_index)?;
            }
            None => raw.skipped_elements += 1,
        }
    }
    Ok(())
}

fn read_elements_v41(
    cur: &mut LineCursor<'_>,
    raw: &mut RawMesh,
    tag_to_index: &HashMap<i64, usize>,
) -> Result<(), MeshError> {
    let path = cur.path();
    let (line, content) = cur.expect_line("the $Elements header 'numEntityBlocks numElements minTag maxTag'")?;
    let toks = tokens_at_least(path, line, content, 4, "$Elements header")?;
    let blocks = parse_count(path, line, toks[0])?;
    let total = parse_count(path, line, toks[1])?;
    let header_line = line;
    let mut seen = 0usize;
    for b in 0..blocks {
        let (line, content) = cur.expect_line(&format!("{blocks} element blocks (header), found only {b}"))?;
        let toks = tokens_at_least(
            path,
            line,
            content,
            4,
            "element block header 'entityDim entityTag type numElements'",
        )?;
        let ty = parse_int(path, line, toks[2])?;
        let n = parse_count(path, line, toks[3])?;
        for k in 0..n {
            let (line, content) = cur.expect_line(&format!("{n} elements in block {b}, found only {k}"))?;
            match tet_nodes(ty) {
                Some(nn) => {
                    let toks = tokens_at_least(
                        path,
                        line,
                        content,
                        1 + nn,
                        "tetrahedron element line 'tag n0 n1 n2 n3'",
                    )?;
                    push_tet(path, line, &toks[1..1 + nn], raw, tag_to_index)?;
                }
                None => raw.skipped_elements += 1,
            }
        }
        seen = checked_total(path, line, seen, n, "elements")?;
    }
    if seen != total {
        return Err(MeshError::at(
            path,
            header_line,
            MeshErrorKind::Syntax(format!(
                "$Elements header announces {total} elements, blocks hold {seen}"
            )),
        ));
    }
    Ok(())
}
