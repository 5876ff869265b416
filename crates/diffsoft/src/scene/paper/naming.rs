//! The names of a paper scene's bodies and actuators. A body is named by its file's stem; a
//! later mesh whose stem an earlier one took is named `<stem>_<k>` (`k` its place in
//! `"Meshes"`). An actuator keeps the scene's name (`pneumatic0`, `muscle3`) unless an earlier
//! mesh's actuator took it: then it is prefixed with its body's name (`box_1_pneumatic0`).
//! Each renaming is noted.

use std::path::Path;

use crate::actuator::ActuatorSpec;

/// The body and actuator names given so far, in `"Meshes"` order.
#[derive(Debug, Default)]
pub(super) struct Names {
    /// The bodies' names.
    bodies: Vec<String>,
    /// The actuators' names, over all bodies.
    actuators: Vec<String>,
}

impl Names {
    /// The name of the body of `"Meshes"[k]` (at `w`), read from `file`: its stem (`body`
    /// where it has none), or `<stem>_<k>` where an earlier mesh took the stem (`box.obj` and
    /// `sub/box.obj`, or one file twice), with a note in `notes`.
    pub(super) fn body(&mut self, notes: &mut Vec<String>, w: &str, k: usize, file: &str) -> String {
        let stem = Path::new(file)
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or("body")
            .to_string();
        let name = if self.bodies.contains(&stem) {
            let name = format!("{stem}_{k}");
            notes.push(format!(
                "{w}: body named '{name}' (the name '{stem}' of its file is taken by an earlier mesh)"
            ));
            name
        } else {
            stem
        };
        self.bodies.push(name.clone());
        name
    }

    /// Names the actuators of the body `body` (at `w`): each keeps its name unless an earlier
    /// mesh's actuator took it, when it becomes `<body>_<name>`, with a note in `notes`.
    pub(super) fn actuators(&mut self, notes: &mut Vec<String>, w: &str, body: &str, actuators: &mut [ActuatorSpec]) {
        for a in actuators {
            if self.actuators.contains(&a.name) {
                let renamed = format!("{body}_{}", a.name);
                notes.push(format!(
                    "{w}: actuator '{}' named '{renamed}' (an earlier mesh has an actuator '{}')",
                    a.name, a.name
                ));
                a.name = renamed;
            }
            self.actuators.push(a.name.clone());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::base::Schedule;

    fn pneumatic(name: &str) -> ActuatorSpec {
        ActuatorSpec::pneumatic(name, &[0], 1.0, Schedule::constant(1.0))
    }

    #[test]
    fn bodies_of_one_stem_are_told_apart_by_their_place() {
        let mut names = Names::default();
        let mut notes = Vec::new();
        assert_eq!(names.body(&mut notes, "Meshes[0]", 0, "box.obj"), "box");
        assert_eq!(names.body(&mut notes, "Meshes[1]", 1, "sub/box.obj"), "box_1");
        assert_eq!(names.body(&mut notes, "Meshes[2]", 2, "ball.obj"), "ball");
        assert_eq!(names.body(&mut notes, "Meshes[3]", 3, "box.obj"), "box_3");
        assert_eq!(
            notes,
            [
                "Meshes[1]: body named 'box_1' (the name 'box' of its file is taken by an earlier mesh)",
                "Meshes[3]: body named 'box_3' (the name 'box' of its file is taken by an earlier mesh)",
            ]
        );
    }

    #[test]
    fn a_later_mesh_s_actuators_of_a_taken_name_are_prefixed() {
        let mut names = Names::default();
        let mut notes = Vec::new();
        let mut first = vec![pneumatic("pneumatic0"), pneumatic("pneumatic1")];
        names.actuators(&mut notes, "Meshes[0]", "box", &mut first);
        assert!(notes.is_empty());
        let mut second = vec![pneumatic("pneumatic0"), pneumatic("muscle0")];
        names.actuators(&mut notes, "Meshes[1]", "box_1", &mut second);
        let second: Vec<&str> = second.iter().map(|a| a.name.as_str()).collect();
        assert_eq!(second, ["box_1_pneumatic0", "muscle0"]);
        assert_eq!(
            notes,
            ["Meshes[1]: actuator 'pneumatic0' named 'box_1_pneumatic0' (an earlier mesh has an actuator 'pneumatic0')"]
        );
    }
}
