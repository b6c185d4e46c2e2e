//! Standard output that a reader who has gone does not stop: `pmsm simulate … | head` closes
//! the pipe after ten lines, and `println!` would then panic on the next one, before the plot
//! was written. Once a write fails the report stops quietly (a broken pipe) or with one line on
//! standard error (any other error), and the command goes on to write its files.

use std::io::{self, Write};
use std::sync::atomic::{AtomicBool, Ordering};

/// Standard output has failed once: the rest of the report is dropped.
static STOPPED: AtomicBool = AtomicBool::new(false);

/// Writes `args` to standard output unless it has failed before.
pub fn emit(args: std::fmt::Arguments) {
    if STOPPED.load(Ordering::Relaxed) {
        return;
    }
    let mut out = io::stdout().lock();
    if let Err(e) = out.write_fmt(args).and_then(|()| out.flush()) {
        STOPPED.store(true, Ordering::Relaxed);
        if e.kind() != io::ErrorKind::BrokenPipe {
            eprintln!("pmsm: standard output: {e}; the report stops here, the files are written");
        }
    }
}

/// `println!` through [`emit`].
#[macro_export]
macro_rules! outln {
    () => {
        $crate::out::emit(format_args!("\n"))
    };
    ($($arg:tt)*) => {
        $crate::out::emit(format_args!("{}\n", format_args!($($arg)*)))
    };
}
