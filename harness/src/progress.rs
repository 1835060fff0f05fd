//! Progress bars (indicatif) behind the library's [`scenes::Progress`] trait. Bars draw on
//! stderr and hide themselves when stderr is not a terminal (CI logs stay clean).

use indicatif::{ProgressBar, ProgressStyle};

/// A progress bar that re-arms for each phase.
pub struct Bar {
    bar: ProgressBar,
}

impl Default for Bar {
    fn default() -> Self {
        Self::new()
    }
}

impl Bar {
    /// A hidden-until-started bar.
    pub fn new() -> Self {
        Self {
            bar: ProgressBar::hidden(),
        }
    }
}

impl scenes::Progress for Bar {
    fn start(&self, what: &str, total: u64) {
        self.bar
            .set_draw_target(indicatif::ProgressDrawTarget::stderr());
        self.bar.reset();
        self.bar.set_length(total);
        self.bar.set_position(0);
        if let Ok(style) =
            ProgressStyle::with_template("{msg:>28} [{bar:40}] {human_pos}/{human_len} ({eta})")
        {
            self.bar.set_style(style.progress_chars("=> "));
        }
        self.bar.set_message(what.to_string());
    }
    fn inc(&self, n: u64) {
        self.bar.inc(n);
    }
    fn finish(&self) {
        self.bar.finish_and_clear();
    }
}
