//! A paper scene's `"Parameters"`: its one object (keys checked) and the gravity it gives.
//! The solver's keys in it are read by [`settings`](crate::scene::paper::settings).

use nalgebra::Vector3;
use serde_json::Value;

use super::context::{excerpt, Ctx};
use super::keys::{PARAM_IGNORED, PARAM_USED};
use crate::scene::SceneError;

/// The object of the scene's `"Parameters"` (a list of exactly one), its keys checked; `None`
/// where the scene gives none (the reference's defaults apply, as a note says).
pub(super) fn object<'v>(cx: &mut Ctx<'_>, value: &'v Value) -> Result<Option<&'v Value>, SceneError> {
    let params = match value.get("Parameters") {
        None => {
            cx.notes.push(
                "no \"Parameters\": the reference's defaults applied (200 Hz, no gravity, collisions off)".into(),
            );
            return Ok(None);
        }
        Some(Value::Array(a)) if a.len() == 1 => &a[0],
        Some(p) => {
            return Err(cx.invalid(format!(
                "\"Parameters\" must be a list of exactly one object, got {}",
                excerpt(p)
            )))
        }
    };
    cx.check_keys("Parameters[0]", params, PARAM_USED, PARAM_IGNORED, &[])?;
    Ok(Some(params))
}

/// The gravity the bodies feel: `"Gravity"` `[x, y, z]` (none where absent), or none
/// `"Is underwater"` (noted: water drag is not simulated either).
pub(super) fn gravity(cx: &mut Ctx<'_>, params: &Value) -> Result<Vector3<f64>, SceneError> {
    let underwater = cx.number(params, "Is underwater", 0.0, "Parameters[0]")? != 0.0;
    let gravity = match params.get("Gravity") {
        None => Vector3::zeros(),
        Some(g) => {
            let a = g
                .as_array()
                .filter(|a| a.len() == 3)
                .ok_or_else(|| cx.invalid(format!("\"Gravity\" must be [x, y, z], got {g}")))?;
            let c: Vec<f64> = a.iter().filter_map(|x| x.as_f64()).collect();
            if c.len() != 3 {
                return Err(cx.invalid(format!("\"Gravity\" must hold three numbers, got {g}")));
            }
            Vector3::new(c[0], c[1], c[2])
        }
    };
    if underwater {
        cx.notes
            .push("\"Is underwater\": water drag is not simulated; gravity is off as in the reference".into());
        return Ok(Vector3::zeros());
    }
    Ok(gravity)
}
