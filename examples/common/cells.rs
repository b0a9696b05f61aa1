//! Benchmarks that measure each cell of a table in a process of its own (so that the peak
//! memory it reports is the cell's alone): the example runs itself with `--cell ARGS…`.

use std::process::Command;

/// The cell's arguments when this process was started as a cell.
pub fn cell_args(args: &[String]) -> Option<&[String]> {
    match args.split_first() {
        Some((flag, rest)) if flag == "--cell" => Some(rest),
        _ => None,
    }
}

/// Runs this example as the cell `args`: its standard output, or (`Ok(Err)`) its error
/// output when it failed.
pub fn run_cell_process(args: &[&str]) -> std::io::Result<Result<String, String>> {
    let output = Command::new(std::env::current_exe()?)
        .arg("--cell")
        .args(args)
        .env("RUST_BACKTRACE", "0")
        .output()?;
    Ok(match output.status.success() {
        true => Ok(String::from_utf8_lossy(&output.stdout).into_owned()),
        false => Err(String::from_utf8_lossy(&output.stderr).trim().to_string()),
    })
}
