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
    /// A large array could not be allocated: the memory left (or the
    /// address-space limit) is smaller than what the run needs.
    #[error(
        "out of memory: could not allocate {} for {what}",
        human(*bytes)
    )]
    OutOfMemory {
        /// Size of the allocation that failed, in bytes.
        bytes: usize,
        /// What the array was for.
        what: &'static str,
    },
    /// A bug: the core panicked (the panic is caught at the boundary and
    /// reported with its message).
    #[error("internal error in the lpvid core (please report it): {0}")]
    Internal(String),
}

impl Error {
    /// Whether the error is about the machine rather than the model: out of
    /// memory, or an internal error. A fit never takes such an error for a
    /// rejected step: it stops and returns it.
    pub fn is_fatal(&self) -> bool {
        matches!(self, Error::OutOfMemory { .. } | Error::Internal(_))
    }
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

/// Run `f`, turning a panic into an error: [`Error::OutOfMemory`] when the
/// panic was a failed allocation (faer's constructors panic so), else
/// [`Error::Internal`] with the panic's message. The entry points of the
/// Python binding run the core through this, so that no panic reaches
/// Python.
pub fn catch_panic<T>(f: impl FnOnce() -> Result<T>) -> Result<T> {
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)) {
        Ok(r) => r,
        Err(payload) => Err(from_panic(payload.as_ref())),
    }
}

/// The error for a caught panic's payload.
fn from_panic(payload: &(dyn std::any::Any + Send)) -> Error {
    let message = payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "a panic without a message".to_string());
    if message.contains("AllocError") || message.contains("capacity overflow") {
        // faer: "... AllocError { layout: Layout { size: 28682688, align: 64 ... } }".
        let bytes = message
            .split("size: ")
            .nth(1)
            .and_then(|rest| rest.split(|c: char| !c.is_ascii_digit()).next())
            .and_then(|digits| digits.parse().ok())
            .unwrap_or(usize::MAX);
        return Error::OutOfMemory {
            bytes,
            what: "an array of the core",
        };
    }
    Error::Internal(message)
}

/// A size in bytes for people: `1.25 GB`, `340 MB`, `12 kB`.
pub fn human(bytes: usize) -> String {
    let b = bytes as f64;
    if b >= 1e9 {
        format!("{:.2} GB", b / 1e9)
    } else if b >= 1e6 {
        format!("{:.0} MB", b / 1e6)
    } else if b >= 1e3 {
        format!("{:.0} kB", b / 1e3)
    } else {
        format!("{bytes} bytes")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_panic_becomes_an_error() {
        let e = catch_panic::<()>(|| panic!("index 7 out of range")).unwrap_err();
        assert_eq!(e, Error::Internal("index 7 out of range".to_string()));
        assert!(e.is_fatal());
        let e = catch_panic::<()>(|| {
            let layout = 28682688usize;
            panic!("called `Result::unwrap()` on an `Err` value: AllocError {{ layout: Layout {{ size: {layout}, align: 64 }} }}")
        })
        .unwrap_err();
        assert!(
            matches!(
                e,
                Error::OutOfMemory {
                    bytes: 28682688,
                    ..
                }
            ),
            "{e:?}"
        );
        assert_eq!(catch_panic(|| Ok(3)), Ok(3));
    }
}
