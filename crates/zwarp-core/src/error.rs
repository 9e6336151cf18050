//! The one error type of zwarp: every failure is a clear, one-line message.

use std::path::PathBuf;

/// Errors raised by zwarp stages. `Display` is a single line naming the file (if any) and the
/// problem, so the CLI can print it as-is and exit non-zero.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// An argument or buffer is invalid (mismatched sizes, NaN, zero-size image, near >= far...).
    #[error("invalid input: {0}")]
    Invalid(String),
    /// A file could not be parsed or holds invalid data.
    #[error("{path}: {msg}")]
    Parse {
        /// The offending file.
        path: PathBuf,
        /// What is wrong with it.
        msg: String,
    },
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The OS error.
        source: std::io::Error,
    },
    /// A feature or backend is not available here (e.g. no GPU adapter).
    #[error("unavailable: {0}")]
    Unavailable(String),
}

impl Error {
    /// Shorthand for [`Error::Invalid`].
    pub fn invalid(msg: impl Into<String>) -> Self {
        Error::Invalid(msg.into())
    }
    /// Shorthand for [`Error::Parse`].
    pub fn parse(path: impl Into<PathBuf>, msg: impl Into<String>) -> Self {
        Error::Parse { path: path.into(), msg: msg.into() }
    }
    /// Shorthand for [`Error::Io`].
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io { path: path.into(), source }
    }
}

/// `Result` with zwarp's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;
