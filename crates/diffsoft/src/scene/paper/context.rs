//! The importer's state while it reads one paper scene ([`Ctx`]: the scene's path, the notes
//! gathered so far, `--passive`, where the file names lead) and its readers of JSON values,
//! which report a malformed value as an error naming the scene and the key.

use std::path::Path;

use serde_json::Value;

use super::files::{file_candidates, FileSource, Files};
use crate::scene::SceneError;

/// The state of one import: where errors point, what the notes say so far.
pub(super) struct Ctx<'a> {
    /// The scene file being read (named by every error).
    pub(super) path: &'a Path,
    /// Notes on what was read, defaulted or ignored, in the order they arose.
    pub(super) notes: Vec<String>,
    /// `--passive`: features that cannot be simulated yet are noted and ignored, not refused.
    pub(super) passive: bool,
    /// Where the file names the scene gives lead: searched for beside the scene, or, for a
    /// scene rebuilt from the files it carried (a pickled scene), only to those.
    pub(super) files: Files<'a>,
}

impl<'a> Ctx<'a> {
    /// The scene's path as the errors show it.
    pub(super) fn shown(&self) -> String {
        self.path.display().to_string()
    }
    /// An invalid-scene error with `message`.
    pub(super) fn invalid(&self, message: String) -> SceneError {
        SceneError::Invalid {
            path: self.shown(),
            message,
        }
    }
    /// `what` uses `feature`, which cannot be simulated yet: an error, or a note under
    /// `--passive`.
    pub(super) fn unsupported(&mut self, what: &str, feature: &str) -> Result<(), SceneError> {
        if self.passive {
            self.notes
                .push(format!("{what}: {feature} not simulated yet; ignored (--passive)"));
            Ok(())
        } else {
            Err(SceneError::Unsupported {
                path: self.shown(),
                message: format!(
                    "{what} ({feature}) cannot be simulated yet; run with --passive to simulate the bodies without it"
                ),
            })
        }
    }
    /// Checks the keys of the object `obj` (at `where_`): `used` ones pass, `ignored` ones are
    /// noted with their reason, non-empty `unsupported` ones are refused (see
    /// [`Ctx::unsupported`]), any other is an error naming it.
    pub(super) fn check_keys(
        &mut self,
        where_: &str,
        obj: &Value,
        used: &[&str],
        ignored: &[(&str, &str)],
        unsupported: &[(&str, &str)],
    ) -> Result<(), SceneError> {
        let map = obj
            .as_object()
            .ok_or_else(|| self.invalid(format!("{where_} must be a JSON object")))?;
        for (k, v) in map {
            if used.contains(&k.as_str()) {
                continue;
            }
            if let Some((_, why)) = ignored.iter().find(|(name, _)| name == k) {
                self.notes.push(format!("{where_}: \"{k}\" ignored ({why})"));
            } else if let Some((_, feature)) = unsupported.iter().find(|(name, _)| name == k) {
                let empty = v.as_array().is_some_and(|a| a.is_empty());
                if !empty {
                    self.unsupported(&format!("{where_}: \"{k}\""), feature)?;
                }
            } else {
                return Err(self.invalid(format!("{where_}: unknown key \"{k}\"")));
            }
        }
        Ok(())
    }
    /// A number under `key` (`default` where absent); any other JSON type is an error.
    pub(super) fn number(&self, obj: &Value, key: &str, default: f64, where_: &str) -> Result<f64, SceneError> {
        match obj.get(key) {
            None => Ok(default),
            Some(v) => v
                .as_f64()
                .ok_or_else(|| self.invalid(format!("{where_}: \"{key}\" must be a number, got {v}"))),
        }
    }
    /// A boolean under `key` (`default` where absent); any other JSON type is an error (a
    /// string such as `"yes"` must not read as false).
    pub(super) fn flag(&self, obj: &Value, key: &str, default: bool, where_: &str) -> Result<bool, SceneError> {
        match obj.get(key) {
            None => Ok(default),
            Some(v) => v
                .as_bool()
                .ok_or_else(|| self.invalid(format!("{where_}: \"{key}\" must be true or false, got {}", excerpt(v)))),
        }
    }
    /// A list of vertex indices under `key`.
    pub(super) fn indices(&self, v: &Value, where_: &str, key: &str) -> Result<Vec<usize>, SceneError> {
        v.as_array()
            .and_then(|a| {
                a.iter()
                    .map(|x| x.as_u64().map(|u| u as usize))
                    .collect::<Option<Vec<_>>>()
            })
            .ok_or_else(|| self.invalid(format!("{where_}: \"{key}\" must be a list of vertex indices")))
    }
    /// A file the scene names: through the carried files of a rebuilt scene, else as
    /// [`find_file`](super::files::find_file) looks for it.
    pub(super) fn resolve(&self, file: &str) -> Result<FileSource<'a>, SceneError> {
        let not_carried = || {
            self.invalid(format!(
                "cannot find \"{file}\": this scene was rebuilt from the files it named when it was first read, and this name was not one of them"
            ))
        };
        match self.files {
            Files::Carried(carried) => carried.get(file).map(FileSource::Carried).ok_or_else(not_carried),
            Files::Paths(carried) => carried.get(file).cloned().map(FileSource::Disk).ok_or_else(not_carried),
            Files::Search => {
                let candidates = file_candidates(self.path, file);
                candidates
                    .iter()
                    .find(|p| p.is_file())
                    .cloned()
                    .map(FileSource::Disk)
                    .ok_or_else(|| {
                        let looked: Vec<String> = candidates.iter().map(|p| p.display().to_string()).collect();
                        self.invalid(format!("cannot find \"{file}\" (looked in {})", looked.join(", ")))
                    })
            }
        }
    }
}

/// A JSON value as the error messages show it: its text, cut at 80 characters.
pub(super) fn excerpt(v: &Value) -> String {
    let text = v.to_string();
    match text.char_indices().nth(80) {
        Some((cut, _)) => format!("{}...", &text[..cut]),
        None => text,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn excerpt_cuts_long_values_at_80_characters() {
        assert_eq!(excerpt(&serde_json::json!([1, 2])), "[1,2]");
        let long = Value::String("x".repeat(100));
        let shown = excerpt(&long);
        assert_eq!(shown.chars().count(), 83);
        assert!(shown.starts_with("\"xxx") && shown.ends_with("x..."));
    }

    #[test]
    fn readers_name_the_key_and_keep_defaults() {
        let cx = Ctx {
            path: Path::new("scene.json"),
            notes: Vec::new(),
            passive: false,
            files: Files::Search,
        };
        let obj = serde_json::json!({"a": 2.5, "b": "yes", "c": [0, 3]});
        assert_eq!(cx.number(&obj, "a", 1.0, "P").unwrap(), 2.5);
        assert_eq!(cx.number(&obj, "z", 1.0, "P").unwrap(), 1.0);
        assert!(cx
            .flag(&obj, "b", false, "P")
            .unwrap_err()
            .to_string()
            .contains("\"b\" must be true or false"));
        assert_eq!(cx.indices(&obj["c"], "P", "c").unwrap(), vec![0, 3]);
        assert!(cx.indices(&obj["a"], "P", "a").is_err());
    }
}
