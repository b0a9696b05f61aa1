//! Progress on stderr, in one of three modes chosen once per run ([`configure`]):
//!
//! - on a terminal, animated bars and spinners (indicatif);
//! - in a log, a pipe or a batch job (stderr not a terminal), plain lines stamped with the
//!   seconds since the start, `meshflow: [  12.3 s] CG iteration 40, residual 3.1e-04`: one
//!   when a phase starts, one when a phase of a second or more ends, every event (a warp, a
//!   factorization, a tracked frame), and the latest count or message at most every
//!   [`LINE_INTERVAL`];
//! - with `--quiet`, nothing (results on stdout, warnings and errors still print).
//!
//! Every line starts with [`LINE_PREFIX`], so that scripts (and our tests) can tell progress
//! from warnings (`meshflow: warning:`) and errors (`meshflow: error:`).

use std::io::IsTerminal;
use std::sync::{Mutex, OnceLock};
use std::time::{Duration, Instant};

/// The beginning of every plain progress line.
pub const LINE_PREFIX: &str = "meshflow: [";

/// Plain progress lines repeat a changing count or message at most this often.
pub const LINE_INTERVAL: Duration = Duration::from_secs(5);

#[derive(Clone, Copy, Debug, PartialEq)]
enum Mode {
    Bars,
    Lines,
    Quiet,
}

/// The run's mode and start time.
static RUN: OnceLock<(Mode, Instant)> = OnceLock::new();

/// Chooses the mode for the whole run: quiet if asked, else bars on a terminal, else lines.
pub fn configure(quiet: bool) {
    let mode = match (quiet, std::io::stderr().is_terminal()) {
        (true, _) => Mode::Quiet,
        (false, true) => Mode::Bars,
        (false, false) => Mode::Lines,
    };
    let _ = RUN.set((mode, Instant::now()));
}

fn run() -> (Mode, Instant) {
    *RUN.get_or_init(|| (Mode::Lines, Instant::now()))
}

/// One plain progress line.
fn line(text: &str) {
    let seconds = run().1.elapsed().as_secs_f64();
    stderr_line!("{LINE_PREFIX}{seconds:7.1} s] {text}");
}

/// What a plain-lines display remembers between lines.
struct Lines {
    what: String,
    total: Option<u64>,
    position: u64,
    message: Option<String>,
    started: Instant,
    last_line: Instant,
    pending: bool,
}

impl Lines {
    fn new(what: String, total: Option<u64>) -> Self {
        line(&what);
        let now = Instant::now();
        Lines {
            what,
            total,
            position: 0,
            message: None,
            started: now,
            last_line: now,
            pending: false,
        }
    }

    fn current(&self) -> String {
        let count = match self.total {
            Some(total) => format!("{} {}/{total}", self.what, self.position),
            None => self.what.clone(),
        };
        match &self.message {
            Some(message) => format!("{count}: {message}"),
            None => count,
        }
    }

    /// Prints the current state if it changed and the last line is old enough.
    fn changed(&mut self) {
        self.pending = true;
        if self.last_line.elapsed() >= LINE_INTERVAL {
            self.flush();
        }
    }

    fn flush(&mut self) {
        line(&self.current());
        self.last_line = Instant::now();
        self.pending = false;
    }

    fn finish(&mut self) {
        let seconds = self.started.elapsed().as_secs_f64();
        if self.pending && self.total.is_some() {
            self.flush();
        }
        if seconds >= 1.0 {
            line(&format!("{}: done in {seconds:.1} s", self.what));
        }
    }
}

/// A progress display in the run's mode; every method is safe to call from several threads.
pub struct Progress {
    bar: Option<indicatif::ProgressBar>,
    lines: Option<Mutex<Lines>>,
}

impl Progress {
    fn new(what: String, total: Option<u64>, bar: impl FnOnce() -> indicatif::ProgressBar) -> Self {
        match run().0 {
            Mode::Bars => Progress {
                bar: Some(bar()),
                lines: None,
            },
            Mode::Lines => Progress {
                bar: None,
                lines: Some(Mutex::new(Lines::new(what, total))),
            },
            Mode::Quiet => Progress {
                bar: None,
                lines: None,
            },
        }
    }

    fn with_lines(&self, f: impl FnOnce(&mut Lines)) {
        if let Some(lines) = &self.lines {
            f(&mut lines.lock().unwrap_or_else(|e| e.into_inner()));
        }
    }

    /// Replaces the message (a plain line at most every [`LINE_INTERVAL`]).
    pub fn set_message(&self, message: String) {
        self.replace_message(message, Lines::changed);
    }

    /// Replaces the message and says so at once in plain lines: a new phase of the step.
    pub fn announce(&self, message: String) {
        self.replace_message(message, Lines::flush);
    }

    /// The new message on the bar, and in plain lines followed by `then`.
    fn replace_message(&self, message: String, then: fn(&mut Lines)) {
        self.with_lines(|l| {
            l.message = Some(message.clone());
            then(l);
        });
        if let Some(bar) = &self.bar {
            bar.set_message(message);
        }
    }

    pub fn set_position(&self, position: u64) {
        if let Some(bar) = &self.bar {
            bar.set_position(position);
        }
        self.with_lines(|l| {
            l.position = position;
            l.changed();
        });
    }

    pub fn inc(&self, steps: u64) {
        if let Some(bar) = &self.bar {
            bar.inc(steps);
        }
        self.with_lines(|l| {
            l.position += steps;
            l.changed();
        });
    }

    /// An event worth its own line (a warp, a restart), above a bar or as a plain line.
    pub fn println(&self, text: String) {
        if let Some(bar) = &self.bar {
            bar.println(text);
        } else if self.lines.is_some() {
            line(&text);
        }
    }

    /// Runs `f` (which prints to stdout) with the bar out of the way.
    pub fn suspend<T>(&self, f: impl FnOnce() -> T) -> T {
        match &self.bar {
            Some(bar) => bar.suspend(f),
            None => f(),
        }
    }

    /// Removes the bar; in plain lines, the final count and how long the step took.
    pub fn finish(&self) {
        if let Some(bar) = &self.bar {
            bar.finish_and_clear();
        }
        self.with_lines(Lines::finish);
    }
}

/// A spinner with a message, for steps without a measure of progress.
pub fn spinner(message: String) -> Progress {
    Progress::new(message.clone(), None, || {
        let spinner = indicatif::ProgressBar::new_spinner().with_message(message);
        spinner.enable_steady_tick(Duration::from_millis(200));
        spinner
    })
}

/// A bar that fills with the digits of residual reduction.
pub fn solver_progress(tolerance: f64) -> Progress {
    Progress::new("solving".into(), None, || {
        let digits = (-tolerance.log10()).ceil() as u64;
        let bar = indicatif::ProgressBar::new(digits);
        bar.set_style(
            indicatif::ProgressStyle::with_template("{spinner} [{elapsed_precise}] {bar:30} {msg}")
                .expect("valid template"),
        );
        bar.enable_steady_tick(Duration::from_millis(200));
        bar
    })
}

/// A bar counting `total` steps of `what`.
pub fn count_progress(total: u64, what: &str) -> Progress {
    Progress::new(what.to_string(), Some(total), || {
        let bar = indicatif::ProgressBar::new(total);
        bar.set_style(
            indicatif::ProgressStyle::with_template("{spinner} {msg} {pos}/{len} {bar:30} {eta}")
                .expect("valid template"),
        );
        bar.set_message(what.to_string());
        bar.enable_steady_tick(Duration::from_millis(200));
        bar
    })
}

/// Runs `step` under a spinner saying `message`, so that no phase runs silently.
pub fn during<T>(message: impl Into<String>, step: impl FnOnce() -> T) -> T {
    let spinner = spinner(message.into());
    let result = step();
    spinner.finish();
    result
}
