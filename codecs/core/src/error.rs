use std::fmt;

/// The one error type of the hdrcodec family.
///
/// Messages are written for a user: they say what was being read and what was wrong,
/// so that `hdrcodec` can print them as a one-line reason.
#[derive(Debug)]
#[non_exhaustive]
pub enum Error {
    /// The input ended before `what` was complete.
    Truncated {
        /// What was being read when the input ended.
        what: String,
    },
    /// The input is malformed: `what` says which part and how.
    Invalid {
        /// Which part is malformed, and how.
        what: String,
    },
    /// The input is well-formed but uses a feature this crate does not implement.
    Unsupported {
        /// The feature, named.
        what: String,
    },
    /// Decoding would exceed the caller's [`Limits`](crate::Limits).
    LimitExceeded {
        /// What would have been allocated, and the limit.
        what: String,
    },
    /// An I/O error from the operating system.
    Io(std::io::Error),
}

/// `Result` with the family's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// The input ended while reading `what`.
    pub fn truncated(what: impl Into<String>) -> Self {
        Error::Truncated { what: what.into() }
    }
    /// The input is malformed.
    pub fn invalid(what: impl Into<String>) -> Self {
        Error::Invalid { what: what.into() }
    }
    /// A feature of the input is not implemented.
    pub fn unsupported(what: impl Into<String>) -> Self {
        Error::Unsupported { what: what.into() }
    }
    /// A limit would be exceeded.
    pub fn limit(what: impl Into<String>) -> Self {
        Error::LimitExceeded { what: what.into() }
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Truncated { what } => write!(f, "truncated input: the data ends inside {what}"),
            Error::Invalid { what } => write!(f, "invalid input: {what}"),
            Error::Unsupported { what } => write!(f, "unsupported: {what}"),
            Error::LimitExceeded { what } => write!(f, "limit exceeded: {what}"),
            Error::Io(e) => write!(f, "I/O error: {e}"),
        }
    }
}

impl std::error::Error for Error {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Error::Io(e) => Some(e),
            _ => None,
        }
    }
}

impl From<std::io::Error> for Error {
    fn from(e: std::io::Error) -> Self {
        if e.kind() == std::io::ErrorKind::UnexpectedEof {
            Error::truncated(e.to_string())
        } else {
            Error::Io(e)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_name_the_problem() {
        let e = Error::truncated("the RGBE scanline 7");
        assert_eq!(e.to_string(), "truncated input: the data ends inside the RGBE scanline 7");
        let e: Error = std::io::Error::new(std::io::ErrorKind::UnexpectedEof, "eof").into();
        assert!(matches!(e, Error::Truncated { .. }));
    }
}
