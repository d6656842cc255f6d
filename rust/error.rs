//! Typed errors of the numerical core.
//!
//! Every fallible operation returns [`Result`]; the Python binding maps each
//! variant to one Python exception type in a single place.

/// Errors raised by the lpvid core.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Error {
    /// An argument has the wrong size or an invalid value.
    #[error("{name}: {message}")]
    InvalidArgument {
        /// Name of the offending argument, as the user knows it.
        name: &'static str,
        /// What was expected and what was found.
        message: String,
    },
    /// `zI - A(p)` cannot be inverted at one (point, frequency) pair: a
    /// pole of the frozen model lies exactly on the evaluation point.
    #[error("zI - A(p) is singular at scheduling point {point}, frequency line {line}")]
    Singular {
        /// Index of the scheduling point.
        point: usize,
        /// Index of the frequency line.
        line: usize,
    },
    /// The frequency response is not finite at one (point, frequency) pair
    /// although `zI - A(p)` could be inverted: it overflowed the range of
    /// floating point (a pole very near the evaluation point, or huge
    /// entries).
    #[error(
        "the frequency response overflowed (is not finite) at scheduling point {point}, \
         frequency line {line}"
    )]
    Overflow {
        /// Index of the scheduling point.
        point: usize,
        /// Index of the frequency line.
        line: usize,
    },
    /// A frozen model on the scheduling range is unstable (or closer to the
    /// stability boundary than asked): a fit with stability kept refuses it.
    #[error("the frozen model at check point {point} is unstable (stability margin {margin:.3e})")]
    Unstable {
        /// Index of the check point.
        point: usize,
        /// Its stability margin (see `stable::margin`).
        margin: f64,
    },
    /// A linear-algebra or cone-solver failure that is not the user's input.
    #[error("numerical failure: {0}")]
    Numerical(String),
    /// The run was stopped by the caller (for example Ctrl-C in Python).
    #[error("interrupted")]
    Interrupted,
}

/// Result type of the lpvid core.
pub type Result<T> = std::result::Result<T, Error>;

/// Shorthand for an [`Error::InvalidArgument`].
pub(crate) fn invalid(name: &'static str, message: impl Into<String>) -> Error {
    Error::InvalidArgument {
        name,
        message: message.into(),
    }
}
