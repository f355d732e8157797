//! A one-line progress bar with elapsed time and ETA on stderr (`indicatif`), drawn only when
//! stderr is a terminal, so logs and pipes stay clean.

use indicatif::{ProgressBar, ProgressStyle};

pub struct Progress {
    bar: ProgressBar,
}

impl Progress {
    pub fn new(label: &'static str, total: usize) -> Self {
        let bar = ProgressBar::new(total as u64);
        bar.set_style(
            ProgressStyle::with_template(
                "{prefix} [{bar:30}] {pos}/{len} {elapsed_precise}, ETA {eta_precise}",
            )
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("#> "),
        );
        bar.set_prefix(label);
        Self { bar }
    }

    /// Reports that `done` of the total are finished.
    pub fn step(&mut self, done: usize) {
        self.bar.set_position(done as u64);
    }

    /// Ends the bar, leaving its last state on the line.
    pub fn finish(&mut self) {
        self.bar.finish();
    }
}
