//! How a paper scene's bodies meet: the top-level `"Friction coefficients"`, `"Self-collision"`
//! between bodies (thickness [`CLOTH_THICKNESS`]) and the static `"Obstacles"`, all only with
//! `"Handle collision"` as in the reference.

use serde_json::Value;

use super::context::{excerpt, Ctx};
use super::keys::OBSTACLE_KEYS;
use super::read;
use crate::base::number;
use crate::contact::pair::BodyCollision;
use crate::contact::{Obstacle, TriMeshObstacle};
use crate::scene::SceneError;

/// Distance kept between the surfaces of two bodies in the paper's scenes (m): a cloth's
/// thickness. The reference's own contact thickness is arcsim's 1e-4 m; its scene files'
/// "Self-collision tolerance" (5e-2) is not read.
pub const CLOTH_THICKNESS: f64 = 1e-3;

/// The friction of every contact and where it came from (for the notes).
#[derive(Debug, Clone, Copy)]
pub(super) struct Friction {
    /// The coefficient.
    pub(super) mu: f64,
    /// Where it came from, as the notes say it.
    pub(super) source: &'static str,
}

/// The top-level "Friction coefficients" (`[[mu, ...], ...]`): the first entry is the friction
/// of every contact, as in the reference; a note says so where the others differ. Absent: the
/// reference's default 0.1.
pub(super) fn friction(cx: &mut Ctx<'_>, v: Option<&Value>) -> Result<Friction, SceneError> {
    let Some(v) = v else {
        return Ok(Friction {
            mu: 0.1,
            source: "(the reference's default: the scene gives no \"Friction coefficients\")",
        });
    };
    let bad = |cx: &Ctx<'_>, what: String| {
        cx.invalid(format!(
            "\"Friction coefficients\" must be a list of lists of numbers, e.g. [[0.1]]; {what}, in {}",
            excerpt(v)
        ))
    };
    let rows = match v.as_array() {
        Some(rows) if !rows.is_empty() => rows,
        _ => return Err(bad(cx, "not a non-empty list".into())),
    };
    let mut values = Vec::new();
    for (i, row) in rows.iter().enumerate() {
        let row = match row.as_array() {
            Some(r) if !r.is_empty() => r,
            _ => return Err(bad(cx, format!("entry [{i}] is not a non-empty list"))),
        };
        for (j, x) in row.iter().enumerate() {
            let mu = x
                .as_f64()
                .ok_or_else(|| bad(cx, format!("entry [{i}][{j}] is not a number")))?;
            // Checked even where no contact reads it: a negative coefficient is a broken file.
            if !(mu.is_finite() && mu >= 0.0) {
                return Err(cx.invalid(format!(
                    "\"Friction coefficients\"[{i}][{j}] must be finite and >= 0, got {}",
                    number(mu)
                )));
            }
            values.push(mu);
        }
    }
    let mu = values[0];
    if values.iter().any(|&x| x != mu) {
        cx.notes.push(format!(
            "\"Friction coefficients\": only the first entry ({}) is read, as in the reference; the others are ignored",
            number(mu)
        ));
    }
    Ok(Friction {
        mu,
        source: "from \"Friction coefficients\"",
    })
}

/// `"Self-collision"` of `params`: contacts between the scene's `bodies` bodies (meshes and
/// cloths) where `"Handle collision"` (`collisions`) is on and there are two or more; noted
/// either way. Self-collision within a body is not simulated.
pub(super) fn body_collisions(
    cx: &mut Ctx<'_>,
    params: &Value,
    collisions: bool,
    bodies: usize,
    friction: Friction,
) -> Result<Option<BodyCollision>, SceneError> {
    let self_collision = cx.flag(params, "Self-collision", false, "Parameters[0]")?;
    let Friction { mu, source } = friction;
    if collisions && self_collision && bodies >= 2 {
        cx.notes.push(format!(
            "\"Self-collision\": the bodies collide with each other (vertex-face and edge-edge pairs, thickness {CLOTH_THICKNESS} m, friction {mu} {source}; the reference hard-codes 1 and its thickness is 1e-4 m); self-collision within a body is not simulated"
        ));
        return Ok(Some(BodyCollision {
            thickness: CLOTH_THICKNESS,
            friction: mu,
        }));
    } else if self_collision {
        cx.notes
            .push("\"Self-collision\": self-collision within a body is not simulated".into());
    }
    Ok(None)
}

/// The scene's `"Obstacles"` (`obs`, where given) as static triangle meshes at scale 1 and
/// thickness 1e-4, as in the reference; each is noted and ignored where `"Handle collision"`
/// (`collisions`) is off.
pub(super) fn obstacles(
    cx: &mut Ctx<'_>,
    obs: Option<&Value>,
    collisions: bool,
    friction: Friction,
) -> Result<Vec<Obstacle>, SceneError> {
    let Some(obs) = obs else {
        return Ok(Vec::new());
    };
    let Friction { mu, source } = friction;
    let obs = obs
        .as_array()
        .ok_or_else(|| cx.invalid(format!("\"Obstacles\" must be a list, got {}", excerpt(obs))))?;
    let mut out = Vec::new();
    for (k, oj) in obs.iter().enumerate() {
        let w = format!("Obstacles[{k}]");
        cx.check_keys(&w, oj, OBSTACLE_KEYS, &[], &[])?;
        if !collisions {
            cx.notes.push(format!(
                "{w}: \"Handle collision\" is off: obstacle ignored, as in the reference"
            ));
            continue;
        }
        let file = oj
            .get("Obj filename")
            .and_then(|f| f.as_str())
            .ok_or_else(|| cx.invalid(format!("{w}: \"Obj filename\" is required")))?;
        let s = read::surface(&cx.resolve(file)?)?;
        cx.notes.push(format!(
            "{w}: triangle mesh {file} at scale 1 and thickness 1e-4 as in the reference (its \"Scale\" and \"Collision tolerance\" are not read there); friction {mu} {source} (the reference hard-codes 1)"
        ));
        let shape = TriMeshObstacle::new(s.vertices, s.triangles).map_err(|e| cx.invalid(format!("{w}: {e}")))?;
        out.push(Obstacle::new(file, shape, mu, 1e-4));
    }
    Ok(out)
}
