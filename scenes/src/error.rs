//! The one error type of the scenes crate. Every variant names what went wrong and where
//! (file, element, field, index) so a user can fix their input.

use std::path::PathBuf;

/// Errors from building, reading or generating scenes.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// An I/O error on a named file.
    // The I/O error is part of the message, not a `source`: with both, an error chain
    // printed whole (`{:#}`) said "No such file or directory" twice.
    #[error("{path}: {error}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        error: std::io::Error,
    },
    /// A file whose contents do not follow its format.
    #[error("{path}: {msg}")]
    Format {
        /// The file.
        path: PathBuf,
        /// What is wrong, naming the element/field/line.
        msg: String,
    },
    /// A point cloud with invalid contents (NaN coordinates, mismatched columns, …).
    #[error("invalid point cloud: {0}")]
    InvalidCloud(String),
    /// A scene specification that cannot be understood.
    #[error("invalid scene '{spec}': {msg}")]
    Spec {
        /// The spec as given by the user.
        spec: String,
        /// What is wrong.
        msg: String,
    },
    /// A camera path or keyframe file that cannot be used.
    #[error("camera path: {0}")]
    Path(String),
}

impl SceneError {
    /// Shorthand for [`SceneError::Io`].
    pub fn io(path: impl Into<PathBuf>, error: std::io::Error) -> Self {
        Self::Io {
            path: path.into(),
            error,
        }
    }
    /// Shorthand for [`SceneError::Format`].
    pub fn format(path: impl Into<PathBuf>, msg: impl Into<String>) -> Self {
        Self::Format {
            path: path.into(),
            msg: msg.into(),
        }
    }
}

/// The message a panic carried (`panic!("…")` gives a `&str` or a `String`), or `None` for a
/// payload of another type: what the decoders' panic guards and the fuzzer report.
pub fn panic_message(payload: &(dyn std::any::Any + Send)) -> Option<String> {
    payload
        .downcast_ref::<&str>()
        .map(|s| (*s).to_owned())
        .or_else(|| payload.downcast_ref::<String>().cloned())
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_panics_message_is_read_from_either_string_type() {
        let quiet = std::panic::take_hook();
        std::panic::set_hook(Box::new(|_| {}));
        let literal = std::panic::catch_unwind(|| panic!("literal")).unwrap_err();
        let n = 3;
        let formatted = std::panic::catch_unwind(|| panic!("formatted {n}")).unwrap_err();
        let other = std::panic::catch_unwind(|| std::panic::panic_any(7u8)).unwrap_err();
        std::panic::set_hook(quiet);
        assert_eq!(super::panic_message(&*literal).as_deref(), Some("literal"));
        assert_eq!(
            super::panic_message(&*formatted).as_deref(),
            Some("formatted 3")
        );
        assert_eq!(super::panic_message(&*other), None);
    }
}
