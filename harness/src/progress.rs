//! Progress bars (indicatif) behind the library's [`scenes::Progress`] trait. Bars draw on
//! stderr and hide themselves when stderr is not a terminal (CI logs stay clean).

use std::sync::atomic::{AtomicBool, Ordering};

use indicatif::{MultiProgress, ProgressBar, ProgressStyle};

/// A progress bar that re-arms for each phase.
pub struct Bar {
    bar: ProgressBar,
    /// Drawn below other bars (`reproduce`'s per-table bar) instead of on its own.
    multi: Option<MultiProgress>,
    /// Whether the bar has been added to `multi` yet.
    added: AtomicBool,
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
            multi: None,
            added: AtomicBool::new(false),
        }
    }

    /// A phase bar drawn under the other bars of `multi` (added when first started).
    pub fn under(multi: &MultiProgress) -> Self {
        Self {
            multi: Some(multi.clone()),
            ..Self::new()
        }
    }
}

impl scenes::Progress for Bar {
    fn start(&self, what: &str, total: u64) {
        match &self.multi {
            Some(m) if !self.added.swap(true, Ordering::Relaxed) => {
                m.add(self.bar.clone());
            }
            Some(_) => {}
            None => self
                .bar
                .set_draw_target(indicatif::ProgressDrawTarget::stderr()),
        }
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
