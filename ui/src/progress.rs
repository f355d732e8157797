//! A one-line progress display on stderr, shown only when stderr is a terminal (so logs and
//! pipes stay clean).

use std::io::{IsTerminal, Write};
use std::time::Instant;

pub struct Progress {
    label: &'static str,
    total: usize,
    shown: bool,
    started: Instant,
    last_draw: Instant,
}

impl Progress {
    pub fn new(label: &'static str, total: usize) -> Self {
        let now = Instant::now();
        Self {
            label,
            total,
            shown: std::io::stderr().is_terminal(),
            started: now,
            last_draw: now,
        }
    }

    /// Reports that `done` of the total are finished (redraws at most ten times a second).
    pub fn step(&mut self, done: usize) {
        if !self.shown || (self.last_draw.elapsed().as_millis() < 100 && done < self.total) {
            return;
        }
        self.last_draw = Instant::now();
        let width = 30;
        let filled = (done * width).checked_div(self.total).unwrap_or(width);
        let mut err = std::io::stderr().lock();
        let _ = write!(
            err,
            "\r{} [{}{}] {done}/{} {:.1} s",
            self.label,
            "#".repeat(filled),
            " ".repeat(width - filled.min(width)),
            self.total,
            self.started.elapsed().as_secs_f64()
        );
        let _ = err.flush();
    }

    /// Ends the line.
    pub fn finish(&mut self) {
        if self.shown {
            let _ = writeln!(std::io::stderr());
        }
    }
}
