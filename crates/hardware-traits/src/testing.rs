//! Helpers for the fault tests of drivers: the checks every driver's error lines must pass.

use crate::{ErrorKind, Result};

/// Asserts that `r` is an error of `kind` whose message is one line starting with `prefix`
/// (the device name and address, e.g. `"gauge 1 at 127.0.0.1:55561: "`), and returns that
/// line.
///
/// # Panics
/// When `r` is `Ok`, the kind differs, the line does not start with `prefix` or holds a
/// newline (this is a test assertion).
#[track_caller]
pub fn expect_one_line_error<T: std::fmt::Debug>(r: Result<T>, prefix: &str, kind: ErrorKind) -> String {
    let e = match r {
        Ok(v) => panic!("expected a {kind} error, got {v:?}"),
        Err(e) => e,
    };
    let line = e.to_string();
    assert_eq!(e.kind(), kind, "{line}");
    assert!(line.starts_with(prefix), "{line}");
    assert!(!line.contains('\n'), "{line}");
    line
}
