//! The library's messages in the Python package's words.
//!
//! The library writes its advice for the command line (`give --intensity FILE.npy`, `add
//! --force`, `use --speed-penalty 0.01`). A Python caller sets keywords instead, so each
//! `--flag` becomes its keyword: `--flag VALUE` → `flag=VALUE` (a number as it is, a
//! placeholder such as `FILE.npy` quoted), a switch → `flag=True` (or `weld=False` for
//! `--no-weld`), and a flag mentioned alone → `flag`. Command names become functions
//! (`meshflow track` → `meshflow.track()`).

/// Switches of the command line: the keyword setting that means the same.
const SWITCHES: &[(&str, &str)] = &[
    ("--force", "force=True"),
    ("--repair", "repair=True"),
    ("--no-weld", "weld=False"),
    ("--large-motion", "large_motion=True"),
    ("--no-large-motion", "large_motion=False"),
    ("--median-filter", "median_filter=True"),
    ("--keep-going", "keep_going=True"),
    ("--keep-uncovered", "keep_uncovered=True"),
    ("--whole-sphere", "whole_sphere=True"),
    (
        "--allow-external-files",
        "meshflow.set_limits(allow_external_files=True)",
    ),
];

/// Flags whose value is a word, with the words they take (a word after any other flag is
/// English, not a value: `--weld-tolerance to keep them apart`).
const WORD_VALUES: &[(&str, &[&str])] = &[
    ("--channels", &["auto", "grey", "rgb", "all"]),
    ("--align", &["rigid", "similarity", "none"]),
    ("--relax", &["arap", "none"]),
    ("--shape", &["graph", "sphere-like"]),
    ("--regularizer", &["covariant", "strain", "embedded"]),
];

/// Commands named in messages, and what to call from Python.
const COMMANDS: &[(&str, &str)] = &[
    ("`meshflow track`", "meshflow.track()"),
    ("meshflow track", "meshflow.track()"),
    ("`meshflow sample`", "meshflow.sample_volume()"),
    ("`meshflow solve`", "meshflow.compute_flow()"),
];

/// `message` with command-line flags and commands replaced by Python keywords and functions.
pub fn in_python_words(message: &str) -> String {
    let mut text = message.to_string();
    for (command, function) in COMMANDS {
        text = text.replace(command, function);
    }
    let mut out = String::with_capacity(text.len());
    let mut rest = text.as_str();
    while let Some(at) = rest.find("--") {
        let (before, flag_onwards) = rest.split_at(at);
        out.push_str(before);
        let name_length = flag_onwards[2..]
            .find(|c: char| !(c.is_ascii_lowercase() || c.is_ascii_digit() || c == '-'))
            .map_or(flag_onwards.len() - 2, |n| n);
        let flag = &flag_onwards[..2 + name_length];
        rest = &flag_onwards[flag.len()..];
        // Not a flag: `--` alone, or inside a word.
        if name_length == 0 || before.ends_with(|c: char| c.is_alphanumeric()) {
            out.push_str(flag);
            continue;
        }
        if let Some((_, keyword)) = SWITCHES.iter().find(|(s, _)| *s == flag) {
            out.push_str(keyword);
            continue;
        }
        let keyword = flag[2..].replace('-', "_");
        match value_after(flag, rest) {
            Some(value) => {
                out.push_str(&format!("{keyword}={}", python_value(value)));
                rest = &rest[1 + value.len()..];
            }
            None => out.push_str(&keyword),
        }
    }
    out.push_str(rest);
    out
}

/// The value of `flag` at the start of `rest` (` 0.01`, ` FILE.npy`, ` X`, ` rgb`), if there
/// is one.
fn value_after<'a>(flag: &str, rest: &'a str) -> Option<&'a str> {
    let word = rest.strip_prefix(' ')?;
    let value = &word[..word
        .find(|c: char| c.is_whitespace() || matches!(c, ',' | ';' | ')' | '('))
        .unwrap_or(word.len())];
    let value = value.trim_end_matches(['.', ':']);
    let number = value.parse::<f64>().is_ok();
    let placeholder = value.starts_with(|c: char| c.is_ascii_uppercase())
        && value
            .chars()
            .all(|c| c.is_ascii_uppercase() || c.is_ascii_digit() || matches!(c, '.' | '_'))
        || value.ends_with(".npy");
    let word = WORD_VALUES
        .iter()
        .any(|(f, words)| *f == flag && words.contains(&value));
    (!value.is_empty() && (number || placeholder || word)).then_some(value)
}

/// A number as it is; anything else as a Python string.
fn python_value(value: &str) -> String {
    match value.parse::<f64>() {
        Ok(_) => value.to_string(),
        Err(_) => format!("'{value}'"),
    }
}
