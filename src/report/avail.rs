//! A piece of a report, or why it is missing: the page shows every section it can and says why
//! the others are not there, so reading a folder never fails on one bad file.

use std::fmt::Write as _;

/// A piece of the report, or why it is missing.
#[derive(Clone, Debug, PartialEq)]
pub enum Avail<T> {
    Yes(T),
    No(String),
}

impl<T> Default for Avail<T> {
    fn default() -> Self {
        Avail::No("not looked for".into())
    }
}

impl<T> Avail<T> {
    pub fn is_available(&self) -> bool {
        matches!(self, Avail::Yes(_))
    }

    pub fn as_option(&self) -> Option<&T> {
        match self {
            Avail::Yes(t) => Some(t),
            Avail::No(_) => None,
        }
    }
}

/// An error with its causes, as one line of text (a section's reason for being missing).
pub fn error_chain(e: &dyn std::error::Error) -> String {
    let mut s = e.to_string();
    let mut src = e.source();
    while let Some(c) = src {
        let _ = write!(s, ": {c}");
        src = c.source();
    }
    s
}
