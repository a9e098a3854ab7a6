//! host-sim's error: a message and the exit code it maps to.
//!
//! Exit codes are part of the interface: 0 success, 1 a result that does not pass
//! (verification failed, not converged), 2 bad input (or an environment that prevents the
//! command: unreadable files, unwritable output).

use std::fmt;

/// Exit code for a result that does not pass.
pub const EXIT_FAILED: u8 = 1;
/// Exit code for bad input.
pub const EXIT_BAD_INPUT: u8 = 2;

/// An error with its exit code.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CliError {
    /// Process exit code.
    pub code: u8,
    /// One message naming what was wrong (file, key, value where known).
    pub message: String,
}

impl CliError {
    /// Bad input: exit code 2.
    pub fn input(message: impl Into<String>) -> Self {
        Self {
            code: EXIT_BAD_INPUT,
            message: message.into(),
        }
    }

    /// A result that does not pass: exit code 1.
    pub fn failed(message: impl Into<String>) -> Self {
        Self {
            code: EXIT_FAILED,
            message: message.into(),
        }
    }

    /// A broken internal invariant (a bug), reported as bad input so that nothing
    /// downstream trusts the output.
    pub fn internal(message: impl Into<String>) -> Self {
        Self::input(format!("internal error: {}", message.into()))
    }
}

impl fmt::Display for CliError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for CliError {}

/// Attaches what was being done to an error, as the [`CliError`] it maps to: `.or_input(||
/// format!("{path}: cannot read"))` gives `CliError::input("{path}: cannot read: {e}")`.
pub trait Context<T> {
    /// Bad input (exit code 2): `"{context}: {error}"`.
    fn or_input<C: fmt::Display>(self, context: impl FnOnce() -> C) -> Result<T, CliError>;
    /// A result that does not pass (exit code 1): `"{context}: {error}"`.
    fn or_failed<C: fmt::Display>(self, context: impl FnOnce() -> C) -> Result<T, CliError>;
    /// A broken internal invariant: `"internal error: {context}: {error}"`.
    fn or_internal<C: fmt::Display>(self, context: impl FnOnce() -> C) -> Result<T, CliError>;
}

impl<T, E: fmt::Display> Context<T> for Result<T, E> {
    fn or_input<C: fmt::Display>(self, context: impl FnOnce() -> C) -> Result<T, CliError> {
        self.map_err(|e| CliError::input(format!("{}: {e}", context())))
    }
    fn or_failed<C: fmt::Display>(self, context: impl FnOnce() -> C) -> Result<T, CliError> {
        self.map_err(|e| CliError::failed(format!("{}: {e}", context())))
    }
    fn or_internal<C: fmt::Display>(self, context: impl FnOnce() -> C) -> Result<T, CliError> {
        self.map_err(|e| CliError::internal(format!("{}: {e}", context())))
    }
}
