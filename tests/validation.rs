//! Bad input fails safely: every broken sequence in `tests/fixtures/invalid/` makes
//! `meshflow solve` exit non-zero with one line on stderr that names the file and element at
//! fault, and leaves no output behind (not even a staging directory).
//!
//! Each case is a directory holding the input files, `expected.txt` (lines that must all appear
//! in the error), and optionally `args.txt` (extra arguments) and `input.txt` (the input path,
//! relative to the case directory; default the directory itself). Commands run inside the case
//! directory, so relative paths in `args.txt` refer to its files.

use std::path::Path;
use std::process::Command;

fn fixtures() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/invalid")
}

fn read_lines(path: &Path) -> Vec<String> {
    std::fs::read_to_string(path)
        .map(|t| {
            t.lines()
                .map(str::to_string)
                .filter(|l| !l.is_empty())
                .collect()
        })
        .unwrap_or_default()
}

/// Runs one case; returns a description of what went wrong, if anything.
fn check_case(case: &Path) -> Option<String> {
    let parent = tempfile::tempdir().unwrap();
    let out = parent.path().join("result");
    let input = read_lines(&case.join("input.txt"))
        .pop()
        .unwrap_or(".".into());
    let args: Vec<String> = read_lines(&case.join("args.txt"))
        .iter()
        .flat_map(|l| l.split_whitespace().map(str::to_string).collect::<Vec<_>>())
        .collect();
    let run = Command::new(env!("CARGO_BIN_EXE_meshflow"))
        .current_dir(case)
        .args(["solve", &input, "--out", out.to_str().unwrap()])
        .args(&args)
        .output()
        .unwrap();
    // Without the plain progress lines (`meshflow: [  0.1 s] …`) written when stderr is a pipe.
    let stderr: String = String::from_utf8_lossy(&run.stderr)
        .lines()
        .filter(|line| !line.starts_with("meshflow: ["))
        .collect::<Vec<_>>()
        .join("\n");
    let missing: Vec<String> = read_lines(&case.join("expected.txt"))
        .into_iter()
        .filter(|e| !stderr.contains(e.as_str()))
        .collect();
    let leftovers = std::fs::read_dir(parent.path()).unwrap().count();
    let problems = [
        (run.status.success(), "succeeded".to_string()),
        (
            stderr.lines().count() != 1,
            "did not print exactly one line".into(),
        ),
        (!missing.is_empty(), format!("does not mention {missing:?}")),
        (
            leftovers > 0,
            format!("left {leftovers} entries in the output's parent"),
        ),
    ];
    let failed: Vec<&str> = problems
        .iter()
        .filter(|(bad, _)| *bad)
        .map(|(_, what)| what.as_str())
        .collect();
    (!failed.is_empty()).then(|| {
        format!(
            "{}: {} — stderr: {stderr}",
            case.display(),
            failed.join(", ")
        )
    })
}

#[test]
fn every_broken_fixture_fails_with_a_clear_line_and_no_output() {
    let mut cases: Vec<_> = std::fs::read_dir(fixtures())
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.is_dir())
        .collect();
    cases.sort();
    assert!(cases.len() >= 40, "only {} fixtures", cases.len());
    let failures: Vec<String> = cases.iter().filter_map(|c| check_case(c)).collect();
    assert!(
        failures.is_empty(),
        "{} of {} cases:\n{}",
        failures.len(),
        cases.len(),
        failures.join("\n")
    );
}
