//! The input-validation error.

/// Physically meaningless or inconsistent input, found before anything runs. The message names
/// the body, element, vertex, bone or parameter it is about.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{message}")]
pub struct InputError {
    message: String,
    /// The input asks for more memory than the process has (Python: `OutOfMemoryError`, a
    /// `MemoryError`).
    out_of_memory: bool,
}

/// Refuse an empty (or blank) name of a `kind` (`"body"`, `"bone"`, ...): names address
/// bodies, bones and actuators in parameters, losses, `--activation` and logs, and an empty one
/// can be addressed by none of them.
pub(crate) fn check_name(kind: &str, name: &str) -> Result<(), InputError> {
    if name.trim().is_empty() {
        return Err(InputError::new(format!(
            "a {kind} has an empty name {name:?}: give it one (names address it in parameters, losses and logs)"
        )));
    }
    Ok(())
}

impl InputError {
    /// An error with this message.
    ///
    /// ```
    /// use diffsoft::InputError;
    ///
    /// let e = InputError::new("body 'box': no tets").context("scene.json");
    /// assert_eq!(e.message(), "scene.json: body 'box': no tets");
    /// assert_eq!(e.to_string(), e.message());
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn new(message: impl Into<String>) -> Self {
        Self {
            message: message.into(),
            out_of_memory: false,
        }
    }

    /// An input whose size does not fit in the process's memory (checked before allocating).
    ///
    /// ```
    /// use diffsoft::InputError;
    ///
    /// let e = InputError::out_of_memory("--steps 1e12: needs 40 TiB").context("grad");
    /// assert!(e.is_out_of_memory());
    /// assert!(!InputError::new("x").is_out_of_memory());
    /// ```
    pub fn out_of_memory(message: impl Into<String>) -> Self {
        Self {
            message: message.into(),
            out_of_memory: true,
        }
    }

    /// Whether the input was refused for its size ([`out_of_memory`](Self::out_of_memory)).
    pub fn is_out_of_memory(&self) -> bool {
        self.out_of_memory
    }

    /// The message.
    pub fn message(&self) -> &str {
        &self.message
    }

    /// The same error with `context: ` in front of its message.
    pub fn context(self, context: &str) -> Self {
        Self {
            message: format!("{context}: {}", self.message),
            out_of_memory: self.out_of_memory,
        }
    }
}

impl From<String> for InputError {
    fn from(message: String) -> Self {
        Self::new(message)
    }
}

impl From<&str> for InputError {
    fn from(message: &str) -> Self {
        Self::new(message)
    }
}

/// A number as an error message quotes it: plain in [1e-4, 1e6) (and 0), in exponent form
/// otherwise, so `1e300` is not printed as three hundred digits.
///
/// ```
/// use diffsoft::base::number;
///
/// assert_eq!(number(-1.0), "-1");
/// assert_eq!(number(-1e300), "-1e300");
/// ```
pub fn number(v: f64) -> String {
    if v == 0.0 || (1e-4..1e6).contains(&v.abs()) || !v.is_finite() {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn numbers_in_messages_stay_short() {
        use super::number;
        assert_eq!(number(2.0), "2");
        assert_eq!(number(-0.5), "-0.5");
        assert_eq!(number(1e300), "1e300");
        assert_eq!(number(-2.5e-9), "-2.5e-9");
        assert_eq!(number(f64::NAN), "NaN");
    }
}
