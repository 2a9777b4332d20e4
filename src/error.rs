//! How a command fails, and the exit code each failure maps to.
//!
//! | code | meaning                                                        |
//! |------|----------------------------------------------------------------|
//! | 0    | success                                                        |
//! | 1    | `validate`: the backends disagree beyond tolerance             |
//! | 2    | bad input or usage: the message names the file, line and value |
//! | 3    | internal error (a bug: please report it)                       |
//! | 4    | the GPU failed: lost, out of memory, timed out, kernel refused  |
//! | 130  | interrupted (SIGINT/SIGTERM); temporary files are removed      |
//!
//! Errors travel as `anyhow::Error`; a failure that is the user's to fix is
//! wrapped in [`UserError`], a device fault in [`DeviceError`], and
//! [`exit_code`] reads the class back wherever in the chain it sits.

use std::fmt;

/// Exit code: the backends disagree (validate).
pub const EXIT_MISMATCH: u8 = 1;
/// Exit code: bad input or usage.
pub const EXIT_INPUT: u8 = 2;
/// Exit code: internal error.
pub const EXIT_INTERNAL: u8 = 3;
/// Exit code: the device failed.
pub const EXIT_DEVICE: u8 = 4;
/// Exit code: interrupted by a signal (128 + SIGINT).
pub const EXIT_INTERRUPTED: u8 = 130;

/// An error that is the user's to fix (exit code 2).
#[derive(Debug)]
pub struct UserError(pub anyhow::Error);

impl fmt::Display for UserError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:#}", self.0)
    }
}
impl std::error::Error for UserError {}

/// The GPU failed while working (exit code 4).
#[derive(Debug)]
pub struct DeviceError(pub anyhow::Error);

impl fmt::Display for DeviceError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:#}", self.0)
    }
}
impl std::error::Error for DeviceError {}

/// Marks `e` as the user's to fix.
pub fn user(e: impl Into<anyhow::Error>) -> anyhow::Error {
    anyhow::Error::new(UserError(e.into()))
}

/// Marks `e` as a device fault.
pub fn device(e: impl Into<anyhow::Error>) -> anyhow::Error {
    anyhow::Error::new(DeviceError(e.into()))
}

/// The exit code for a failed command.
pub fn exit_code(e: &anyhow::Error) -> u8 {
    for cause in e.chain() {
        if cause.is::<UserError>() {
            return EXIT_INPUT;
        }
        if cause.is::<DeviceError>() {
            return EXIT_DEVICE;
        }
    }
    EXIT_INTERNAL
}

#[cfg(test)]
mod tests {
    use super::*;
    use anyhow::{anyhow, Context};

    #[test]
    fn classes_survive_context() {
        let e: anyhow::Result<()> = Err(user(anyhow!("bad radius")));
        let e = e.context("while loading").unwrap_err();
        assert_eq!(exit_code(&e), EXIT_INPUT);
        assert_eq!(exit_code(&device(anyhow!("lost"))), EXIT_DEVICE);
        assert_eq!(exit_code(&anyhow!("bug")), EXIT_INTERNAL);
        assert_eq!(format!("{:#}", user(anyhow!("x"))), "x");
    }
}
