//! Progress of the long runs on stderr.
//!
//! Every bar is drawn through one [`MultiProgress`], so a command's bar and the bars of its
//! stages (`cargo xtask perf`) share the terminal without tearing. indicatif hides the bars
//! when stderr is not a terminal; the lines of [`eprintln()`] are printed either way.

use indicatif::{MultiProgress, ProgressBar, ProgressStyle};
use std::borrow::Cow;
use std::sync::LazyLock;
use std::time::Duration;

static BARS: LazyLock<MultiProgress> = LazyLock::new(MultiProgress::new);

/// Name of the run, position/length, elapsed, ETA.
const TEMPLATE: &str = "{msg} [{bar:30}] {pos}/{len} {elapsed_precise} ETA {eta}";

/// A bar over `len` work items; cleared from the terminal when dropped (done or not).
pub struct Bar(ProgressBar);

impl std::ops::Deref for Bar {
    type Target = ProgressBar;
    fn deref(&self) -> &ProgressBar {
        &self.0
    }
}

impl Drop for Bar {
    fn drop(&mut self) {
        self.0.finish_and_clear();
        BARS.remove(&self.0);
    }
}

/// A bar over `len` work items named by `message`. It ticks twice a second so the elapsed
/// time moves during a long item.
pub fn bar(len: usize, message: impl Into<Cow<'static, str>>) -> Bar {
    let style = ProgressStyle::with_template(TEMPLATE)
        .unwrap_or_else(|_| ProgressStyle::default_bar())
        .progress_chars("=> ");
    let bar = BARS.add(
        ProgressBar::new(len as u64)
            .with_style(style)
            .with_message(message),
    );
    bar.enable_steady_tick(Duration::from_millis(500));
    Bar(bar)
}

/// `eprintln!` above the bars: printed whether they are shown or not.
pub fn eprintln(line: impl std::fmt::Display) {
    BARS.suspend(|| eprintln!("{line}"));
}
