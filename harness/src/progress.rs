//! Progress bars (indicatif) behind the library's [`scenes::Progress`] trait. Bars draw on
//! stderr and hide themselves when stderr is not a terminal (CI logs stay clean). A bar also
//! times its phases ([`Bar::phases`]): `build` records them in `build.json`, so where a
//! build's time goes is on file without a profiler.

use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use indicatif::{MultiProgress, ProgressBar, ProgressStyle};

/// A progress bar that re-arms for each phase.
pub struct Bar {
    bar: ProgressBar,
    /// Drawn below other bars (`reproduce`'s per-table bar) instead of on its own.
    multi: Option<MultiProgress>,
    /// Whether the bar has been added to `multi` yet.
    added: AtomicBool,
    /// The phase running (its name and start) and the phases finished (name, seconds).
    clock: Mutex<Clock>,
}

#[derive(Default)]
struct Clock {
    running: Option<(String, Instant)>,
    done: Vec<(String, f64)>,
}

impl Clock {
    /// Ends the running phase, if any.
    fn stop(&mut self) {
        if let Some((what, t0)) = self.running.take() {
            self.done.push((what, t0.elapsed().as_secs_f64()));
        }
    }
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
            clock: Mutex::new(Clock::default()),
        }
    }

    /// The phases started so far, in order, with their wall seconds (a phase still running
    /// counts up to now; one started while another ran ends that one).
    pub fn phases(&self) -> Vec<(String, f64)> {
        let c = self.clock.lock().unwrap_or_else(|e| e.into_inner());
        let mut out = c.done.clone();
        if let Some((what, t0)) = &c.running {
            out.push((what.clone(), t0.elapsed().as_secs_f64()));
        }
        out
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
        {
            let mut c = self.clock.lock().unwrap_or_else(|e| e.into_inner());
            c.stop();
            c.running = Some((what.to_string(), Instant::now()));
        }
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
        self.clock.lock().unwrap_or_else(|e| e.into_inner()).stop();
        self.bar.finish_and_clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use scenes::Progress as _;

    #[test]
    fn phases_are_timed_in_order() {
        let bar = Bar::new();
        bar.start("a", 1);
        std::thread::sleep(std::time::Duration::from_millis(20));
        bar.finish();
        bar.start("b", 0);
        // A phase started while another runs ends that one.
        bar.start("c", 0);
        let p = bar.phases();
        let names: Vec<&str> = p.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(names, ["a", "b", "c"]);
        // `a` slept 20 ms; `sleep` never returns early.
        assert!(p[0].1 >= 0.02, "{p:?}");
        bar.finish();
        assert_eq!(bar.phases().len(), 3);
    }
}
