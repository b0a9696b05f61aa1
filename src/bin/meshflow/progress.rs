//! Progress display on stderr (hidden when stderr is not a terminal).

/// A spinner with a message, for steps without a measure of progress; hidden when stderr is
/// not a terminal.
pub fn spinner(message: String) -> indicatif::ProgressBar {
    let spinner = indicatif::ProgressBar::new_spinner().with_message(message);
    spinner.enable_steady_tick(std::time::Duration::from_millis(200));
    spinner
}

/// A bar that fills with the digits of residual reduction; hidden when stderr is not a terminal.
pub fn solver_progress(tolerance: f64) -> indicatif::ProgressBar {
    let digits = (-tolerance.log10()).ceil() as u64;
    let bar = indicatif::ProgressBar::new(digits);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{spinner} [{elapsed_precise}] {bar:30} {msg}")
            .expect("valid template"),
    );
    bar.enable_steady_tick(std::time::Duration::from_millis(200));
    bar
}

/// A bar counting `total` steps of `what`.
pub fn count_progress(total: u64, what: &str) -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::new(total);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{spinner} {msg} {pos}/{len} {bar:30} {eta}")
            .expect("valid template"),
    );
    bar.set_message(what.to_string());
    bar.enable_steady_tick(std::time::Duration::from_millis(200));
    bar
}

/// Runs `step` under a spinner saying `message`, so that no phase runs silently.
pub fn during<T>(message: impl Into<String>, step: impl FnOnce() -> T) -> T {
    let spinner = spinner(message.into());
    let result = step();
    spinner.finish_and_clear();
    result
}
