//! The input-validation error.

/// Physically meaningless or inconsistent input, found before anything runs. The message names
/// the body, element, vertex, bone or parameter it is about.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{message}")]
pub struct InputError {
    message: String,
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
        }
    }

    /// The message.
    pub fn message(&self) -> &str {
        &self.message
    }

    /// The same error with `context: ` in front of its message.
    pub fn context(self, context: &str) -> Self {
        Self {
            message: format!("{context}: {}", self.message),
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
