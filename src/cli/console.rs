//! The commands' two output streams, written so that a closed one never
//! panics: `println!` and `eprintln!` panic when a write fails, which a
//! closed pipe makes them do (`izb compare … | head`, `izb render … | true`).
//!
//! Results go to stdout through [`say!`](crate::say): a failed write ends
//! the command with [`StreamClosed`], and `main` exits quietly with status
//! 141 (128 + SIGPIPE: what a shell reports for a writer a closed pipe
//! stopped), since nobody is left to read a message. Notes go to stderr
//! through [`note!`](crate::note): diagnostics a closed stderr loses
//! without stopping the run.

use std::fmt;
use std::io::Write;

/// Stdout could not be written: the command stopped there.
#[derive(Debug, thiserror::Error)]
#[error("stdout was closed ({0})")]
pub struct StreamClosed(std::io::ErrorKind);

/// The exit status of a command whose stdout was closed.
pub const STREAM_CLOSED_STATUS: i32 = 141;

/// Writes a line to stdout.
pub fn say_line(args: fmt::Arguments) -> Result<(), StreamClosed> {
    let mut out = std::io::stdout().lock();
    out.write_fmt(args)
        .and_then(|()| out.write_all(b"\n"))
        .and_then(|()| out.flush())
        .map_err(|e| StreamClosed(e.kind()))
}

/// Writes a line to stderr; a failed write is dropped.
pub fn note_line(args: fmt::Arguments) {
    let mut err = std::io::stderr().lock();
    let _ = err.write_fmt(args).and_then(|()| err.write_all(b"\n"));
}

/// `println!` that returns `Result<(), StreamClosed>` instead of
/// panicking on a closed stdout.
#[macro_export]
macro_rules! say {
    ($($arg:tt)*) => {
        $crate::cli::console::say_line(format_args!($($arg)*))
    };
}

/// `eprintln!` that drops the line on a closed stderr instead of
/// panicking.
#[macro_export]
macro_rules! note {
    ($($arg:tt)*) => {
        $crate::cli::console::note_line(format_args!($($arg)*))
    };
}
