//! A battery of hostile and mistaken inputs run through the `meshflow` binary, as an attacker
//! and a careless user would try them. The first round ([`round_one`]): bombs (tiny files
//! declaring terabytes), files that name files outside their directory, outputs over inputs,
//! unbounded options, edited manifests. The second ([`round_two`]): manifests that name files
//! outside their run (and `--force`), OME-Zarr stores that link outside themselves, chunk bombs,
//! runs whose files are FIFOs, links or edited, silent zeros and absurd values.
//!
//! Each case must end in exit 0 or a one-line error (exit 1 or 2: never a panic, an abort or a
//! signal) of at most 400 characters within 30 s and 2 GB of resident memory, with every input
//! file unchanged and every file outside the outputs unchanged (victims planted beside the
//! inputs among them); a case that must be refused ([`Expect::Refused`]) must exit 1 with a
//! message that says why, one that must work ([`Expect::Succeeds`]) must exit 0. Every case
//! runs with `--memory-limit 1.5G`. Prints a row per case (exit code, seconds, peak resident
//! memory, the message) and exits non-zero if any case fails. The tests run it
//! (`hostile_readers::the_hostile_battery_holds`).
//!
//! ```text
//! cargo build --release && cargo run --release --example hostile_battery
//! ```

#[path = "../../tests/hostile_support/mod.rs"]
pub mod hostile_support;
#[path = "round_one.rs"]
mod round_one;
#[path = "round_two.rs"]
mod round_two;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const TIME_LIMIT: Duration = Duration::from_secs(30);
const MEMORY_LIMIT_KB: i64 = 2 << 20;
/// The longest error line a case may print.
const LONGEST_MESSAGE: usize = 400;

#[allow(dead_code)] // the tests call `run_battery` instead
fn main() {
    let binary = std::env::var_os("MESHFLOW_BIN")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("target/release/meshflow")
        });
    assert!(
        binary.exists(),
        "build the binary first: cargo build --release"
    );
    std::process::exit(i32::from(run_battery(&binary) > 0));
}

/// One case: a name, the command line (without `meshflow`) and what must come of it.
pub struct Case {
    name: String,
    args: Vec<String>,
    expect: Expect,
}

impl Case {
    fn new(name: &str, args: &[&str], expect: Expect) -> Self {
        Self {
            name: name.to_string(),
            args: args.iter().map(|a| a.to_string()).collect(),
            expect,
        }
    }
}

/// What must come of a case besides the rules every case keeps (module docs).
#[derive(Clone, Copy, Debug)]
pub enum Expect {
    /// Exit 0 or a one-line error.
    Any,
    /// Exit 1 with one line that holds this.
    Refused(&'static str),
    /// Exit 0.
    Succeeds,
}

/// Runs every case of both rounds with `binary` in a temporary directory, printing a row per
/// case; the number of cases that failed.
pub fn run_battery(binary: &Path) -> usize {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let base = dir.path();
    let mut cases = round_one::cases(&base.join("one"), binary);
    cases.extend(round_two::cases(&base.join("two"), binary));
    let mut failures = 0;
    println!(
        "{:<52} {:>4} {:>7} {:>9}  message",
        "case", "exit", "seconds", "peak MB"
    );
    for case in &cases {
        let before = snapshot(base);
        let outcome = run(binary, &case.args);
        let after = snapshot(base);
        let changed: Vec<&PathBuf> = (before.iter())
            .filter(|(path, hash)| after.get(*path) != Some(hash))
            .map(|(path, _)| path)
            .collect();
        let problems = outcome.problems(&changed, case.expect);
        failures += usize::from(!problems.is_empty());
        println!(
            "{:<52} {:>4} {:>7.2} {:>9.1}  {}{}",
            case.name,
            outcome.code.map_or("sig".into(), |c| c.to_string()),
            outcome.seconds,
            outcome.peak_kb as f64 / 1024.0,
            shorten(&outcome.message),
            match problems.is_empty() {
                true => String::new(),
                false => format!("  <-- {}", problems.join("; ")),
            }
        );
    }
    println!("{} cases, {failures} failed", cases.len());
    failures
}

/// How one case ended.
struct Outcome {
    code: Option<i32>,
    seconds: f64,
    peak_kb: i64,
    /// The first line of stderr that is not a warning (or "ok").
    message: String,
    stderr_lines: usize,
}

impl Outcome {
    fn problems(&self, changed: &[&PathBuf], expect: Expect) -> Vec<String> {
        let mut problems = Vec::new();
        if !matches!(self.code, Some(0..=2)) {
            problems.push(format!("ended with {:?}", self.code));
        }
        if self.code != Some(0) && self.stderr_lines != 1 {
            problems.push(format!("{} lines of stderr", self.stderr_lines));
        }
        if self.message.chars().count() > LONGEST_MESSAGE {
            problems.push(format!("a message of {} characters", self.message.len()));
        }
        match expect {
            Expect::Refused(why) if self.code != Some(1) || !self.message.contains(why) => {
                problems.push(format!("not refused with {why:?}"))
            }
            Expect::Succeeds if self.code != Some(0) => problems.push("did not succeed".into()),
            _ => {}
        }
        if self.seconds > TIME_LIMIT.as_secs_f64() {
            problems.push("over 30 s".into());
        }
        if self.peak_kb > MEMORY_LIMIT_KB {
            problems.push("over 2 GB".into());
        }
        if !changed.is_empty() {
            problems.push(format!("inputs changed: {changed:?}"));
        }
        problems
    }
}

/// Runs the binary with `args` and `--memory-limit 1.5G --quiet`, measuring its own peak
/// resident memory (`wait4`), killed at the time limit.
// The child is reaped by `wait4`, which also gives its resource usage.
#[allow(clippy::zombie_processes)]
fn run(binary: &Path, args: &[String]) -> Outcome {
    let start = Instant::now();
    let child = Command::new(binary)
        .args(args)
        .args(["--memory-limit", "1.5G", "--quiet"])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the binary starts");
    let pid = child.id() as libc::pid_t;
    let mut status = 0;
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    let mut killed = false;
    loop {
        // SAFETY: `status` and `usage` are valid for writes; `pid` is our child.
        let done = unsafe { libc::wait4(pid, &mut status, libc::WNOHANG, &mut usage) };
        if done == pid {
            break;
        }
        if start.elapsed() > TIME_LIMIT + Duration::from_secs(5) && !killed {
            unsafe { libc::kill(pid, libc::SIGKILL) };
            killed = true;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    let seconds = start.elapsed().as_secs_f64();
    let mut stderr = String::new();
    use std::io::Read;
    let _ = child.stderr.expect("piped").read_to_string(&mut stderr);
    let code = libc::WIFEXITED(status).then(|| libc::WEXITSTATUS(status));
    let lines: Vec<&str> = stderr.lines().filter(|l| !l.contains("warning")).collect();
    Outcome {
        code,
        seconds,
        peak_kb: usage.ru_maxrss,
        message: lines.first().map_or("ok".to_string(), |l| l.to_string()),
        stderr_lines: lines.len(),
    }
}

fn shorten(line: &str) -> String {
    let line = line.trim_start_matches("meshflow: error: ");
    match line.char_indices().nth(150) {
        Some((at, _)) => format!("{}…", &line[..at]),
        None => line.to_string(),
    }
}

/// BLAKE3 of a file, or its size and time of change where it is large (a sparse chunk of
/// 50 GB among them).
fn fingerprint(path: &Path) -> String {
    let metadata = std::fs::metadata(path).ok();
    match metadata {
        Some(m) if m.len() > 16 << 20 => {
            format!("{} bytes, changed {:?}", m.len(), m.modified().ok())
        }
        _ => {
            let bytes = std::fs::read(path).unwrap_or_default();
            blake3::hash(&bytes).to_hex().to_string()
        }
    }
}

/// The fingerprint of every file below `dir`, except the outputs (`out*`).
fn snapshot(dir: &Path) -> BTreeMap<PathBuf, String> {
    let mut files = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).into_iter().flatten().flatten() {
            let path = entry.path();
            let name = entry.file_name().to_string_lossy().into_owned();
            if name.starts_with("out") {
                continue;
            }
            match entry.file_type() {
                Ok(t) if t.is_dir() => stack.push(path),
                Ok(t) if t.is_file() => {
                    files.insert(path.clone(), fingerprint(&path));
                }
                _ => {}
            }
        }
    }
    files
}
