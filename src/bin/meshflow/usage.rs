//! Usage errors: clap's message as one line, with a hint where the shell expanded a glob.

use meshflow::load::FrameFormat;
use std::process::ExitCode;

/// `--help` and `--version` print as usual; a usage error becomes one line, exit code 2.
pub(crate) fn usage_error(error: clap::Error) -> ExitCode {
    use clap::error::ErrorKind;
    if matches!(
        error.kind(),
        ErrorKind::DisplayHelp
            | ErrorKind::DisplayVersion
            | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand
    ) {
        error.exit();
    }
    let text = error.render().to_string();
    let message: Vec<&str> = text
        .lines()
        .take_while(|line| !line.starts_with("Usage:"))
        .map(str::trim)
        .filter(|line| !line.is_empty() && !line.starts_with("For more information"))
        .collect();
    let hint = glob_hint(&error).unwrap_or_default();
    stderr_line!(
        "meshflow: {}{hint} (see meshflow --help)",
        message.join(" ")
    );
    ExitCode::from(2)
}

/// When there are unexpected arguments and several of the arguments are mesh, volume or points
/// files of one directory and extension, the shell has most likely expanded an unquoted glob
/// into many arguments: a hint to quote it, or to give the directory.
fn glob_hint(error: &clap::Error) -> Option<String> {
    use clap::error::ErrorKind;
    if error.kind() != ErrorKind::UnknownArgument {
        return None;
    }
    // Mesh frames, and the volumes and points of `sample`, `surface` and `match`.
    let per_frame = ["npy", "tif", "tiff", "csv"];
    let mut files: Vec<(String, String)> = std::env::args()
        .skip(1)
        .filter_map(|argument| {
            let path = std::path::Path::new(&argument);
            let extension = path.extension()?.to_string_lossy().to_lowercase();
            let known = FrameFormat::of(path).is_some() || per_frame.contains(&&*extension);
            let directory = match path.parent() {
                Some(parent) if !parent.as_os_str().is_empty() => parent.display().to_string(),
                _ => ".".to_string(),
            };
            known.then_some((directory, extension))
        })
        .collect();
    files.sort();
    let (directory, extension) = files.windows(2).find(|pair| pair[0] == pair[1])?[0].clone();
    Some(format!(
        "; it looks like the shell expanded a glob into many files: quote it \
         ('{directory}/*.{extension}') or give the directory ({directory})"
    ))
}
