//! Errors of the methods crate; each names the file, node, parameter or flag at fault.

use std::path::PathBuf;

/// Errors from building, opening or running a method.
#[derive(Debug, thiserror::Error)]
pub enum MethodError {
    /// I/O on a named file.
    // The I/O error is part of the message, not a `source`: with both, an error chain
    // printed whole (`{:#}`) said "No such file or directory" twice.
    #[error("{path}: {error}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        error: std::io::Error,
    },
    /// On-disk data that fails validation (bad magic, checksum mismatch, truncation).
    #[error("{path}: corrupt data: {msg}")]
    Corrupt {
        /// The file.
        path: PathBuf,
        /// What failed, naming the node/chunk.
        msg: String,
    },
    /// A remote file that could not be fetched (connection, status, length), with its URL.
    #[error("{url}: {msg}")]
    Remote {
        /// The URL asked.
        url: String,
        /// What went wrong.
        msg: String,
    },
    /// A method parameter that is unknown or has a bad value. The wording names no flag: the
    /// CLI says `--param`, a spec file or a suite its field (`src/args.rs`,
    /// `harness::reproduce`, `harness::check::suite`).
    #[error("method parameter: {0}")]
    Param(String),
    /// An unusable target (tolerance NaN/∞/negative, budget 0).
    #[error("invalid target: {0}")]
    Target(String),
    /// A chunk id the method does not have.
    #[error("no chunk {0}")]
    NoChunk(u64),
    /// A size limit that makes the request impossible (a model larger than GPU memory, more
    /// points than 32-bit indices address, a chunk beyond 4 GiB). Never a bug: a bug is
    /// [`MethodError::Bug`].
    #[error("{0}")]
    Limit(String),
    /// An internal invariant that failed, or a panic caught where a thread must not die (a
    /// chunk decoder on the loader thread): a bug in splatbench, never bad input. The message
    /// names the node, unit or chunk.
    #[error(
        "internal error (a bug in splatbench; please report it with the command that gave it): {0}"
    )]
    Bug(String),
    /// Errors from the scene layer.
    #[error(transparent)]
    Scene(#[from] scenes::SceneError),
    /// A name that is none of the known ones (a method in a manifest or a suite).
    #[error(transparent)]
    Unknown(#[from] UnknownName),
}

/// A name that is not one of a list (a method, a kernel): the error of the registry enums'
/// [`std::str::FromStr`]. It names no flag: the caller knows where the name came from.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown {what} '{name}' (known: {})", known.join(", "))]
pub struct UnknownName {
    /// What was looked up ("method", "kernel").
    pub what: &'static str,
    /// The name given.
    pub name: String,
    /// Every name known.
    pub known: Vec<&'static str>,
}

impl UnknownName {
    /// The one of `all` whose `name` is `s` (exact), else the error listing every name.
    pub fn lookup<T: Copy>(
        what: &'static str,
        all: &[T],
        name: impl Fn(T) -> &'static str,
        s: &str,
    ) -> Result<T, Self> {
        all.iter()
            .copied()
            .find(|&k| name(k) == s)
            .ok_or_else(|| Self {
                what,
                name: s.to_string(),
                known: all.iter().map(|&k| name(k)).collect(),
            })
    }
}

impl MethodError {
    /// Shorthand for [`MethodError::Io`].
    pub fn io(path: impl Into<PathBuf>, error: std::io::Error) -> Self {
        Self::Io {
            path: path.into(),
            error,
        }
    }
    /// Shorthand for [`MethodError::Corrupt`].
    pub fn corrupt(path: impl Into<PathBuf>, msg: impl Into<String>) -> Self {
        Self::Corrupt {
            path: path.into(),
            msg: msg.into(),
        }
    }
}
