//! Printing that survives a closed pipe or terminal. `println!` panics when standard output is
//! a pipe whose reader has gone (`brdf-rig ... | head`), and a panic in the middle of a capture
//! or a reconstruction would end the work for the sake of a message. Here a write to a closed
//! stream is dropped, the stream is not written again, and the work goes on (its results are
//! files; a capture's journal keeps every shot whatever happens to the terminal). Any other
//! write error (a full disk behind a redirection) is reported once on standard error.
//!
//! The macros `outln!`, `out!` (standard output) and `errln!` (standard error) stand for
//! `println!`, `print!` and `eprintln!` everywhere in `cli/`.

use std::fmt::Arguments;
use std::io::{ErrorKind, Write};
use std::sync::atomic::{AtomicBool, Ordering};

static STDOUT_GONE: AtomicBool = AtomicBool::new(false);
static STDERR_GONE: AtomicBool = AtomicBool::new(false);
static STDOUT_WARNED: AtomicBool = AtomicBool::new(false);

/// Writes to standard output (see the module header).
pub fn out(args: Arguments, newline: bool) {
    if STDOUT_GONE.load(Ordering::Relaxed) {
        return;
    }
    let mut o = std::io::stdout().lock();
    let r = o.write_fmt(args).and_then(|()| {
        if newline {
            o.write_all(b"\n")
        } else {
            o.flush()
        }
    });
    if let Err(e) = r {
        if e.kind() == ErrorKind::BrokenPipe {
            STDOUT_GONE.store(true, Ordering::Relaxed);
        } else if !STDOUT_WARNED.swap(true, Ordering::Relaxed) {
            err(
                format_args!("warning: writing to standard output failed: {e}"),
                true,
            );
        }
    }
}

/// Writes to standard error (see the module header).
pub fn err(args: Arguments, newline: bool) {
    if STDERR_GONE.load(Ordering::Relaxed) {
        return;
    }
    let mut o = std::io::stderr().lock();
    let r = o
        .write_fmt(args)
        .and_then(|()| if newline { o.write_all(b"\n") } else { Ok(()) });
    if r.is_err() {
        // nowhere left to say it
        STDERR_GONE.store(true, Ordering::Relaxed);
    }
}

/// `println!` that survives a closed pipe.
macro_rules! outln {
    () => {
        $crate::cli::output::out(format_args!(""), true)
    };
    ($($arg:tt)*) => {
        $crate::cli::output::out(format_args!($($arg)*), true)
    };
}

/// `print!` that survives a closed pipe (flushes).
macro_rules! out {
    ($($arg:tt)*) => {
        $crate::cli::output::out(format_args!($($arg)*), false)
    };
}

/// `eprintln!` that survives a closed pipe.
macro_rules! errln {
    () => {
        $crate::cli::output::err(format_args!(""), true)
    };
    ($($arg:tt)*) => {
        $crate::cli::output::err(format_args!($($arg)*), true)
    };
}

/// `eprint!` that survives a closed pipe.
macro_rules! errout {
    ($($arg:tt)*) => {
        $crate::cli::output::err(format_args!($($arg)*), false)
    };
}
