//! The CLI's error: one line on stderr and an exit code.
//!
//! Bad input (an argument the model or the parser rejects) exits with 2, like clap's own
//! usage errors; a failure while doing the work (e.g. writing a file) exits with 1.

use std::fmt;

/// What went wrong, already phrased for the user.
#[derive(Debug)]
pub struct CliError {
    /// The argument at fault (`--beam-radius`), if any.
    pub arg: Option<String>,
    /// Why, in one line.
    pub reason: String,
    /// Process exit code.
    pub code: i32,
}

impl CliError {
    /// A bad argument: exit code 2.
    pub fn usage(arg: &str, reason: impl Into<String>) -> CliError {
        CliError {
            arg: Some(arg.to_string()),
            reason: reason.into(),
            code: 2,
        }
    }

    /// A failure while running: exit code 1.
    pub fn runtime(reason: impl Into<String>) -> CliError {
        CliError {
            arg: None,
            reason: reason.into(),
            code: 1,
        }
    }
}

impl fmt::Display for CliError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        // Keep it on one line whatever the reason says.
        let reason = self.reason.replace('\n', " ");
        match &self.arg {
            Some(a) => write!(f, "{a}: {reason}"),
            None => f.write_str(&reason),
        }
    }
}

impl std::error::Error for CliError {}

/// Result with [`CliError`].
pub type CliResult<T> = Result<T, CliError>;
