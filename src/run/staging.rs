//! Write-then-rename output directories.
//!
//! A file is written beside its target and renamed onto it
//! ([`crate::format::write_atomically`]). An output
//! directory (the `--out` of a command) is built in a hidden staging directory beside its
//! target and swapped in whole ([`StagedDir`]), so it holds exactly one run: never a mix of an
//! earlier run's files and a new one's. Each output directory carries a manifest,
//! [`RUN_MANIFEST`] (`meshflow_run.json`: the commands that made it and the files they wrote),
//! by which a later run recognises meshflow's own output. A directory that is neither missing,
//! empty nor such an output is refused unless forced ([`Overwrite::Force`]).
//!
//! Replacing an earlier output `OUT`: stage the new files in `.OUT.partial-PID`, write its
//! manifest, rename `OUT` to `.OUT.previous-PID`, rename the staging directory to `OUT`
//! (renaming the old one back if that fails), remove `.OUT.previous-PID`. An update
//! ([`StagedDir::update`], e.g. new pictures of a solve output) hard-links the files it keeps
//! into the staging directory first (copies them where hard links are not possible).
//!
//! A mount point (a Docker volume, a bind mount) cannot be renamed or removed (`EBUSY`), and
//! its parent may be another file system or read-only. There the files are staged inside the
//! target, in `OUT/.meshflow.partial-PID`, and moved into place one by one, the manifest last:
//! each file appears whole, though not the directory at once.
//!
//! Staging directories of processes that are gone (killed, or the machine went down) are
//! removed by the next run into the same target. The command line also removes its own on
//! SIGINT, SIGTERM and SIGHUP ([`remove_live_staging`], called from its signal handler).

use super::guard::{refuse_output_over_inputs, OutputKind};
use super::SolveRecord;
use crate::format::{quoted, read_file_at_most, write_atomically, IoError};
use serde::{Deserialize, Serialize};
use std::collections::BTreeSet;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// The name of a staging directory inside its target (a mount point), without the PID.
const INSIDE_STAGING: &str = ".meshflow.partial-";

/// The staging directories of this process's uncommitted outputs.
static LIVE_STAGING: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn live_staging() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    LIVE_STAGING.lock().unwrap_or_else(|e| e.into_inner())
}

/// Removes the staging directories of all uncommitted outputs of this process, for a signal
/// handler that is about to end the process (a dropped [`StagedDir`] removes its own).
pub fn remove_live_staging() {
    let mut live = live_staging();
    for staging in live.drain(..) {
        let _ = std::fs::remove_dir_all(staging);
    }
    // The process ends next: keep the lock, so that no thread creates a staging directory
    // between this removal and the exit (creating one takes the lock, see `StagedDir`).
    std::mem::forget(live);
}

/// The manifest file that marks a directory as meshflow's output.
pub const RUN_MANIFEST: &str = "meshflow_run.json";

/// The contents of [`RUN_MANIFEST`].
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct RunManifest {
    /// Always `"meshflow run"`: tells the file from any other JSON of that name.
    pub format: String,
    /// The meshflow version that wrote it.
    pub version: String,
    /// The command lines that made the directory, oldest first (a solve, then re-renders).
    pub commands: Vec<Vec<String>>,
    /// The directory's entries (besides the manifest), sorted.
    pub files: Vec<String>,
    /// The working directory of the first command: its relative paths are relative to it
    /// (absent in manifests of earlier versions).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub directory: Option<PathBuf>,
    /// The files outside the directory that the first command read, as it read them: a later
    /// command that reads them again (`advect`, `analyze`) uses them only while they still
    /// hold this ([`RunManifest::check_inputs`]).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub inputs: Vec<RecordedInput>,
    /// What a solve read and how (absent in other commands' outputs and in manifests of
    /// earlier versions): what [`super::SolveInput::of_run`] reads back.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub solve: Option<SolveRecord>,
    /// The microscope recording that `meshflow sample` read onto this sequence, for viewers
    /// that show the surface over it (absent elsewhere).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub recording: Option<super::RecordingRecord>,
}

/// A file a run read, as it was then.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct RecordedInput {
    /// The file with links resolved.
    pub path: PathBuf,
    pub bytes: u64,
    /// The BLAKE3 hash of its contents, in hex.
    pub blake3: String,
}

impl RecordedInput {
    /// `path`'s size and hash now.
    pub fn of(path: &Path) -> Result<Self, IoError> {
        let in_file = |e| IoError::file(path, e);
        let resolved = path.canonicalize().map_err(in_file)?;
        let mut hasher = blake3::Hasher::new();
        let (mut file, _) = crate::format::open_regular(&resolved)?;
        let bytes = std::io::copy(&mut file, &mut hasher).map_err(in_file)?;
        Ok(Self {
            path: resolved,
            bytes,
            blake3: hasher.finalize().to_hex().to_string(),
        })
    }
}

/// The regular files that the inputs `paths` stand for: a file itself, the regular files
/// directly in a directory, the files a glob matches; sorted.
pub fn input_files(paths: &[&Path]) -> Vec<PathBuf> {
    let mut files = BTreeSet::new();
    for path in paths {
        if path.is_file() {
            files.insert(path.to_path_buf());
        } else if let Ok(entries) = std::fs::read_dir(path) {
            let entries = entries.filter_map(Result::ok).map(|e| e.path());
            files.extend(entries.filter(|p| p.is_file()));
        } else if let Ok(matches) = glob::glob(&path.to_string_lossy()) {
            files.extend(matches.filter_map(Result::ok).filter(|p| p.is_file()));
        }
    }
    files.into_iter().collect()
}

const MANIFEST_FORMAT: &str = "meshflow run";

/// The most bytes a run manifest may have. Its largest part is the fingerprint of every input
/// file (some 200 bytes each): 64 MiB hold some 300,000 of them.
const MANIFEST_MOST_BYTES: u64 = 64 << 20;

/// Whether `name` is a plain file name in its directory: not empty, not `.` or `..`, not the
/// manifest itself, no separator.
fn is_plain_name(name: &str) -> bool {
    !matches!(name, "" | "." | ".." | RUN_MANIFEST) && !name.contains(['/', '\\', '\0'])
}

impl RunManifest {
    /// `path` as the first command meant it: relative paths against [`Self::directory`].
    pub fn resolve(&self, path: &Path) -> PathBuf {
        match (&self.directory, path.is_relative()) {
            (Some(directory), true) => directory.join(path),
            _ => path.to_path_buf(),
        }
    }

    /// The manifest of the run `dir`, with a message that tells a missing manifest from a
    /// corrupt one; refused when it lists a file that is not a plain name in `dir`
    /// ([`Self::check_entries`]).
    pub fn read_run(dir: &Path) -> Result<Self, IoError> {
        let manifest = Self::parse(dir)?;
        manifest.check_entries(&dir.join(RUN_MANIFEST))?;
        Ok(manifest)
    }

    /// The manifest of `dir` as its file says, unchecked: read with a size bound, a FIFO or
    /// device refused before it is opened ([`crate::format::read_file_at_most`]).
    fn parse(dir: &Path) -> Result<Self, IoError> {
        let path = dir.join(RUN_MANIFEST);
        let text = match std::fs::symlink_metadata(&path) {
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                return Err(IoError::format(
                    dir,
                    format!("not a meshflow output (no {RUN_MANIFEST})"),
                ))
            }
            Ok(metadata) if metadata.is_symlink() => {
                return Err(IoError::format(
                    &path,
                    "a link: a run's manifest is its own file",
                ))
            }
            _ => read_file_at_most(&path, MANIFEST_MOST_BYTES, "a run manifest")?,
        };
        let manifest = serde_json::from_slice::<Self>(&text)
            .map_err(|e| IoError::format(&path, format!("corrupt run manifest ({e})")))?;
        match manifest.format == MANIFEST_FORMAT {
            true => Ok(manifest),
            false => Err(IoError::format(
                &path,
                format!(
                    "not a meshflow run manifest (format {})",
                    quoted(&manifest.format)
                ),
            )),
        }
    }

    /// Refuses a manifest (at `path`) that lists anything but plain names of files in its own
    /// directory: `--force` and updates remove and replace the listed files, so a listed
    /// `../x`, `/home/me/thesis.tex` or `sub/x` would reach outside the run.
    fn check_entries(&self, path: &Path) -> Result<(), IoError> {
        match self.files.iter().find(|name| !is_plain_name(name)) {
            None => Ok(()),
            Some(name) => Err(IoError::format(
                path,
                format!(
                    "lists {} among its files, which is not a file meshflow writes in its \
                     directory: a foreign or edited manifest (remove it, or choose another \
                     output directory)",
                    quoted(name)
                ),
            )),
        }
    }

    /// Checks the inputs `paths` of a later command against what the run recorded: each must
    /// be something the run read (a file it recorded, or a directory or glob holding one: an
    /// edited manifest cannot name another input), every file under it that a load may read
    /// ([`crate::load::may_read`]: frames, arrays, textures; not notes beside them) must be
    /// recorded (a record that lost an entry, or a frame added since, is refused: the reader
    /// would read it unchecked), and every recorded file under it must still hold what it
    /// held then. Errors about `run` name what changed.
    pub fn check_inputs(&self, run: &Path, paths: &[&Path]) -> Result<(), IoError> {
        let refuse = |message: String| IoError::format(run, format!("{message}; solve again"));
        if self.inputs.is_empty() {
            return Err(refuse(format!(
                "its {RUN_MANIFEST} records no fingerprints of its inputs (an earlier meshflow \
                 wrote it, or it was edited)"
            )));
        }
        for path in paths {
            let recorded = self.recorded_under(path);
            if recorded.is_empty() {
                return Err(refuse(format!(
                    "its manifest names {}, which the run did not read (was {RUN_MANIFEST} \
                     edited?)",
                    path.display()
                )));
            }
            let files = input_files(&[path]);
            let unrecorded =
                (files.iter().filter(|file| crate::load::may_read(file))).find(|file| {
                    file.canonicalize()
                        .is_ok_and(|f| !recorded.iter().any(|r| r.path == f))
                });
            if let Some(file) = unrecorded {
                return Err(refuse(format!(
                    "its input {} holds {}, of which the run recorded no fingerprint (added \
                     since the run, or {RUN_MANIFEST} lost its entry)",
                    path.display(),
                    file.display()
                )));
            }
            for then in recorded {
                let now = match RecordedInput::of(&then.path) {
                    Err(IoError::File { source, .. })
                        if source.kind() == std::io::ErrorKind::NotFound =>
                    {
                        let gone =
                            format!("its input {} is gone since the run", then.path.display());
                        return Err(refuse(gone));
                    }
                    now => now?,
                };
                if &now != then {
                    return Err(refuse(format!(
                        "its input {} changed since the run ({} bytes, BLAKE3 {:.12}… then; \
                         {} bytes, {:.12}… now)",
                        then.path.display(),
                        then.bytes,
                        then.blake3,
                        now.bytes,
                        now.blake3
                    )));
                }
            }
        }
        Ok(())
    }

    /// The recorded files that the input `path` stands for: the file itself, the files directly
    /// in the directory, or the files a glob matches now.
    fn recorded_under(&self, path: &Path) -> Vec<&RecordedInput> {
        let resolved = path.canonicalize().ok();
        let matched: Vec<PathBuf> = (input_files(&[path]).iter())
            .filter_map(|file| file.canonicalize().ok())
            .collect();
        (self.inputs.iter())
            .filter(|r| {
                matched.contains(&r.path)
                    || resolved.as_ref().is_some_and(|dir| {
                        *dir == r.path || (dir.is_dir() && r.path.parent() == Some(dir))
                    })
            })
            .collect()
    }

    /// The manifest of `dir`, if it has one that reads as a manifest and lists plain names
    /// ([`Self::read_run`]).
    pub fn read(dir: &Path) -> Option<Self> {
        Self::read_run(dir).ok()
    }
}

/// What a [`StagedDir`] may replace at its target.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Overwrite {
    /// A missing or empty directory, or an earlier meshflow output (which is replaced as a
    /// whole); any other directory is refused when the `StagedDir` is made.
    #[default]
    EarlierRun,
    /// Also a directory meshflow did not write (all of it or some of its files): the new files
    /// are moved into it one by one, the files an earlier run's manifest lists are removed,
    /// and its other files stay.
    Force,
}

/// What is at a target now.
#[derive(Debug)]
enum Existing {
    Missing,
    Empty,
    /// An earlier output and its manifest.
    Run(RunManifest),
    /// A directory with entries meshflow did not write (some of them, for messages), and the
    /// manifest if there is one.
    Foreign {
        strangers: Vec<String>,
        manifest: Option<RunManifest>,
    },
}

impl Existing {
    fn of(target: &Path) -> Result<Self, IoError> {
        let mut names = match entry_names(target) {
            // Staging inside a mount point is not part of the output.
            Ok(names) => names
                .into_iter()
                .filter(|n| !n.starts_with(INSIDE_STAGING))
                .collect::<BTreeSet<_>>(),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Self::Missing),
            Err(e) => return Err(IoError::file(target, e)),
        };
        if names.is_empty() {
            return Ok(Self::Empty);
        }
        // A manifest that does not read as one leaves the directory foreign; one that reads
        // but lists names outside it is refused outright, --force or not.
        let manifest = RunManifest::parse(target).ok();
        if let Some(manifest) = &manifest {
            manifest.check_entries(&target.join(RUN_MANIFEST))?;
        }
        if manifest.is_some() {
            names.remove(RUN_MANIFEST);
        }
        let listed: BTreeSet<&String> = manifest.iter().flat_map(|m| &m.files).collect();
        let strangers: Vec<String> = names.into_iter().filter(|n| !listed.contains(n)).collect();
        Ok(match (manifest, strangers.is_empty()) {
            (Some(manifest), true) => Self::Run(manifest),
            (manifest, _) => Self::Foreign {
                strangers,
                manifest,
            },
        })
    }

    /// Refuses a directory meshflow did not write, unless forced.
    fn check(&self, target: &Path, overwrite: Overwrite) -> Result<(), IoError> {
        let Self::Foreign {
            strangers,
            manifest,
        } = self
        else {
            return Ok(());
        };
        if overwrite == Overwrite::Force {
            return Ok(());
        }
        let mut named: Vec<String> = strangers.iter().take(3).cloned().collect();
        if strangers.len() > 3 {
            named.push(format!("{} more", strangers.len() - 3));
        }
        let what = match manifest {
            Some(_) => "holds files that meshflow did not write",
            None => "is not empty and not a meshflow output",
        };
        Err(IoError::format(
            target,
            format!(
                "{what} ({}); choose another output directory, empty it, or add --force to write into it (its other files stay)",
                named.join(", ")
            ),
        ))
    }
}

/// An output directory that appears complete or not at all, and holds exactly one run; see
/// the module documentation.
///
/// Files are written into [`StagedDir::path`]; [`StagedDir::commit`] writes the manifest and
/// puts the directory in place. Dropped uncommitted, the staging directory is removed and the
/// target is left as it was. Making one checks, before any long computation, that the target
/// may be replaced and that its location is writable.
#[derive(Debug)]
pub struct StagedDir {
    /// The directory as the caller named it, for messages.
    target: PathBuf,
    /// The same with a symbolic link resolved, where the renames happen.
    resolved: PathBuf,
    staging: PathBuf,
    /// Whether `staging` is inside the target (a mount point; see the module docs).
    inside: bool,
    overwrite: Overwrite,
    commands: Vec<Vec<String>>,
    /// Where the first command ran.
    directory: Option<PathBuf>,
    /// Files of the earlier output that stay (see [`StagedDir::update`]).
    kept: Vec<String>,
    /// The files outside the output that the first command read.
    inputs: Vec<RecordedInput>,
    /// The solve's input, when the output is a solve's.
    solve: Option<SolveRecord>,
    recording: Option<super::RecordingRecord>,
    committed: bool,
}

impl StagedDir {
    /// A new output at `target`, replacing an earlier meshflow output there
    /// ([`Overwrite::EarlierRun`]).
    pub fn new(target: &Path) -> Result<Self, IoError> {
        Self::create(target, Overwrite::EarlierRun)
    }

    /// [`StagedDir::create`] for a command that reads `inputs`: refused, before anything is
    /// written, when `target` is an input, holds one or lies inside an input directory (its
    /// outputs would mix with the input's files, and e.g. a `flow.glb` among OBJ frames breaks
    /// the next run). Call it before reading the inputs.
    pub fn create_apart_from(
        inputs: &[&Path],
        target: &Path,
        overwrite: Overwrite,
    ) -> Result<Self, IoError> {
        refuse_output_over_inputs(target, OutputKind::Directory, inputs)?;
        Self::create(target, overwrite)
    }

    /// A new output at `target`, replacing what `overwrite` allows.
    pub fn create(target: &Path, overwrite: Overwrite) -> Result<Self, IoError> {
        Self::stage(target, overwrite, None)
    }

    /// A new version of the output at `target` that keeps the earlier output's files for which
    /// `keep(name)` holds (e.g. all but the pictures, when drawing new pictures of a solve) and
    /// its commands; what is written into [`StagedDir::path`] replaces the rest.
    pub fn update(
        target: &Path,
        overwrite: Overwrite,
        keep: impl Fn(&str) -> bool,
    ) -> Result<Self, IoError> {
        Self::stage(target, overwrite, Some(&keep))
    }

    fn stage(
        target: &Path,
        overwrite: Overwrite,
        keep: Option<&dyn Fn(&str) -> bool>,
    ) -> Result<Self, IoError> {
        if target.is_file() {
            return Err(IoError::format(target, "is a file, not a directory"));
        }
        let resolved = match target.is_symlink() {
            true => std::fs::canonicalize(target).map_err(|e| IoError::file(target, e))?,
            false => target.to_path_buf(),
        };
        let existing = Existing::of(&resolved).map_err(|e| relabel(e, &resolved, target))?;
        existing.check(target, overwrite)?;
        let inside = is_mount_point(&resolved);
        let staging = match inside {
            true => resolved.join(format!("{INSIDE_STAGING}{}", std::process::id())),
            false => sibling(&resolved, "partial").map_err(|e| relabel(e, &resolved, target))?,
        };
        let parent = staging.parent().expect("a staging directory has a parent");
        remove_stale_staging(parent, &staging);
        std::fs::create_dir_all(parent).map_err(|e| IoError::file(target, e))?;
        {
            // Created and registered under one lock: a signal handler that runs meanwhile
            // ([`remove_live_staging`]) sees both or neither.
            let mut live = live_staging();
            std::fs::create_dir_all(&staging).map_err(|e| IoError::file(target, e))?;
            live.push(staging.clone());
        }
        let mut staged = Self {
            target: target.to_path_buf(),
            resolved,
            staging,
            inside,
            overwrite,
            commands: Vec::new(),
            directory: std::env::current_dir().ok(),
            kept: Vec::new(),
            inputs: Vec::new(),
            solve: None,
            recording: None,
            committed: false,
        };
        let manifest = match &existing {
            Existing::Run(manifest) => Some(manifest),
            Existing::Foreign { manifest, .. } => manifest.as_ref(),
            Existing::Missing | Existing::Empty => None,
        };
        if let (Some(keep), Some(manifest)) = (keep, manifest) {
            staged.commands = manifest.commands.clone();
            staged.directory = manifest.directory.clone();
            staged.inputs = manifest.inputs.clone();
            staged.solve = manifest.solve.clone();
            staged.recording = manifest.recording.clone();
            staged.kept = manifest.files.iter().filter(|n| keep(n)).cloned().collect();
        }
        // A whole directory is swapped in: the kept files must be in it. (Forced into a
        // foreign directory or moved into a mount point file by file, they stay where they are.)
        if let (Existing::Run(_), false) = (&existing, inside) {
            for name in &staged.kept {
                staged.link_earlier(name)?;
            }
        }
        Ok(staged)
    }

    /// Hard-links (or copies) the earlier output's file `name` into the staging directory.
    fn link_earlier(&self, name: &str) -> Result<(), IoError> {
        let (from, to) = (self.resolved.join(name), self.staging.join(name));
        if !is_own_file(&from) {
            return Ok(()); // a listed file removed since, a directory or a link: not kept
        }
        std::fs::hard_link(&from, &to)
            .or_else(|_| std::fs::copy(&from, &to).map(|_| ()))
            .map_err(|e| IoError::file(self.target.join(name), e))
    }

    /// Where to write the files now.
    pub fn path(&self) -> &Path {
        &self.staging
    }

    /// Where the files will be.
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// Records the command line that makes this output, for the manifest.
    pub fn record_command<S: Into<String>>(&mut self, arguments: impl IntoIterator<Item = S>) {
        self.commands
            .push(arguments.into_iter().map(Into::into).collect());
    }

    /// Records what a solve read and how, for the commands that read its output back
    /// ([`super::SolveInput::of_run`]).
    pub fn record_solve(&mut self, record: SolveRecord) {
        self.solve = Some(record);
    }

    /// Records in the manifest the recording this output's surface was sampled from (its
    /// path relative to the output, [`super::RecordingRecord::path_from`]).
    pub fn record_recording(&mut self, record: super::RecordingRecord) {
        self.recording = Some(record);
    }

    /// Records the files `paths` stand for ([`input_files`]) with their sizes and hashes, for
    /// the commands that read them again later ([`RunManifest::check_inputs`]).
    pub fn record_inputs(&mut self, paths: &[&Path]) -> Result<(), IoError> {
        use rayon::prelude::*;
        // Hashed in parallel: a long sequence is many large files (200 OBJ frames of the
        // paper's torus: 1 GB).
        let files = input_files(paths);
        let recorded: Vec<RecordedInput> = files
            .par_iter()
            .map(|file| RecordedInput::of(file))
            .collect::<Result<_, _>>()?;
        for recorded in recorded {
            if !self.inputs.contains(&recorded) {
                self.inputs.push(recorded);
            }
        }
        Ok(())
    }

    /// `error` with a staged file's path replaced by its final path, for messages.
    pub fn in_target(&self, error: IoError) -> IoError {
        relabel(error, &self.staging, &self.target)
    }

    /// [`StagedDir::in_target`] for any error: a file error names the final path.
    pub fn error_in_target(&self, error: crate::Error) -> crate::Error {
        match error {
            crate::Error::Io(e) => crate::Error::Io(self.in_target(e)),
            other => other,
        }
    }

    /// Writes the manifest and puts the output in place (see the module documentation).
    pub fn commit(mut self) -> Result<(), IoError> {
        let fail = |e| IoError::file(&self.target, e);
        let mut files = entry_names(&self.staging).map_err(fail)?;
        let kept = self
            .kept
            .iter()
            .filter(|n| is_own_file(&self.resolved.join(n)));
        files.extend(kept.cloned());
        let manifest = RunManifest {
            format: MANIFEST_FORMAT.into(),
            version: env!("CARGO_PKG_VERSION").into(),
            commands: std::mem::take(&mut self.commands),
            files: files.into_iter().collect(),
            directory: self.directory.take(),
            inputs: std::mem::take(&mut self.inputs),
            solve: self.solve.take(),
            recording: self.recording.take(),
        };
        write_atomically(&self.staging.join(RUN_MANIFEST), |w| {
            serde_json::to_writer_pretty(&mut *w, &manifest).map_err(std::io::Error::other)?;
            writeln!(w)
        })
        .map_err(|e| self.in_target(e))?;
        // Checked again: the target may have changed during a long computation.
        let existing = Existing::of(&self.resolved).map_err(|e| self.in_target(e))?;
        existing.check(&self.target, self.overwrite)?;
        match existing {
            Existing::Run(manifest)
            | Existing::Foreign {
                manifest: Some(manifest),
                ..
            } if self.inside => self.merge(manifest.files)?,
            _ if self.inside => self.merge(Vec::new())?,
            Existing::Missing => std::fs::rename(&self.staging, &self.resolved).map_err(fail)?,
            Existing::Empty => {
                std::fs::remove_dir(&self.resolved).map_err(fail)?;
                std::fs::rename(&self.staging, &self.resolved).map_err(fail)?;
            }
            Existing::Run(_) => self.swap()?,
            Existing::Foreign { manifest, .. } => {
                self.merge(manifest.map(|m| m.files).unwrap_or_default())?
            }
        }
        self.committed = true;
        live_staging().retain(|s| *s != self.staging);
        Ok(())
    }

    /// Replaces the earlier output with the staging directory as a whole.
    fn swap(&self) -> Result<(), IoError> {
        let fail = |e| IoError::file(&self.target, e);
        let backup = sibling(&self.resolved, "previous")?;
        std::fs::rename(&self.resolved, &backup).map_err(fail)?;
        if let Err(e) = std::fs::rename(&self.staging, &self.resolved) {
            let _ = std::fs::rename(&backup, &self.resolved);
            return Err(fail(e));
        }
        // The new output is complete; a leftover backup is only clutter beside it.
        let _ = std::fs::remove_dir_all(&backup);
        Ok(())
    }

    /// [`Overwrite::Force`] into a directory with other files, or into a mount point: removes
    /// the files an earlier run listed (but those kept), then moves the staged files in one by
    /// one, the manifest last.
    fn merge(&self, earlier: Vec<String>) -> Result<(), IoError> {
        let fail = |e| IoError::file(&self.target, e);
        for name in earlier.iter().filter(|n| !self.kept.contains(n)) {
            let path = self.resolved.join(name);
            if is_own_file(&path) {
                std::fs::remove_file(&path)
                    .map_err(|e| IoError::file(self.target.join(name), e))?;
            }
        }
        let mut names = entry_names(&self.staging).map_err(fail)?;
        names.remove(RUN_MANIFEST);
        for name in names.iter().map(String::as_str).chain([RUN_MANIFEST]) {
            std::fs::rename(self.staging.join(name), self.resolved.join(name)).map_err(fail)?;
        }
        std::fs::remove_dir(&self.staging).map_err(fail)
    }
}

impl Drop for StagedDir {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_dir_all(&self.staging);
            live_staging().retain(|s| *s != self.staging);
        }
    }
}

/// Whether `path` is a regular file itself, not a link: what an output may remove or keep of
/// an earlier one (a link there was not written by meshflow, whatever the manifest says).
fn is_own_file(path: &Path) -> bool {
    std::fs::symlink_metadata(path).is_ok_and(|m| m.is_file())
}

/// The names of the entries of directory `dir`.
fn entry_names(dir: &Path) -> std::io::Result<BTreeSet<String>> {
    std::fs::read_dir(dir)?
        .map(|entry| Ok(entry?.file_name().to_string_lossy().into_owned()))
        .collect()
}

/// The hidden directory `.NAME.ROLE-PID` beside `target`.
fn sibling(target: &Path, role: &str) -> Result<PathBuf, IoError> {
    let name = target
        .file_name()
        .ok_or_else(|| IoError::format(target, "not a directory name"))?;
    let parent = match target.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    Ok(parent.join(format!(
        ".{}.{role}-{}",
        name.to_string_lossy(),
        std::process::id()
    )))
}

/// Removes the staging directories in `parent` named like `staging` (`.NAME.partial-PID` or
/// `.meshflow.partial-PID`) that runs left when they were killed: those whose process is gone.
/// A live process's staging stays; so does any other entry.
fn remove_stale_staging(parent: &Path, staging: &Path) {
    let Some(name) = staging
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
    else {
        return;
    };
    let Some((prefix, _pid)) = name.rsplit_once('-') else {
        return;
    };
    let prefix = format!("{prefix}-");
    let Ok(entries) = std::fs::read_dir(parent) else {
        return;
    };
    for entry in entries.flatten() {
        let file_name = entry.file_name().to_string_lossy().into_owned();
        let pid = file_name
            .strip_prefix(&prefix)
            .and_then(|p| p.parse::<u32>().ok());
        if pid.is_some_and(|pid| !process_is_alive(pid)) {
            let _ = std::fs::remove_dir_all(entry.path());
        }
    }
}

/// Whether the existing directory `dir` is a mount point: on another device than its parent,
/// or listed as one in `/proc/self/mountinfo` (a bind mount within one file system).
#[cfg(unix)]
fn is_mount_point(dir: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    let Ok(dir) = std::fs::canonicalize(dir) else {
        return false; // missing: it will be made
    };
    let Some(parent) = dir.parent() else {
        return true; // the root
    };
    let device = |p: &Path| std::fs::metadata(p).map(|m| m.dev()).ok();
    if device(&dir) != device(parent) {
        return true;
    }
    let Ok(mounts) = std::fs::read_to_string("/proc/self/mountinfo") else {
        return false;
    };
    // Field 5 is the mount point, with space, tab, newline and backslash as octal escapes.
    let escaped = dir
        .to_string_lossy()
        .replace('\\', "\\134")
        .replace(' ', "\\040")
        .replace('\t', "\\011")
        .replace('\n', "\\012");
    mounts
        .lines()
        .any(|line| line.split(' ').nth(4) == Some(escaped.as_str()))
}

#[cfg(not(unix))]
fn is_mount_point(_dir: &Path) -> bool {
    false
}

/// Whether a process with this id exists (signal 0 checks without sending anything).
#[cfg(unix)]
fn process_is_alive(pid: u32) -> bool {
    let Ok(pid) = libc::pid_t::try_from(pid) else {
        return false;
    };
    // SAFETY: kill with signal 0 sends nothing; it only reports whether `pid` exists.
    let status = unsafe { libc::kill(pid, 0) };
    status == 0 || std::io::Error::last_os_error().raw_os_error() == Some(libc::EPERM)
}

/// Elsewhere no process is known to be gone: nothing is removed.
#[cfg(not(unix))]
fn process_is_alive(_pid: u32) -> bool {
    true
}

/// `error` with a path under `from` moved under `to`.
fn relabel(mut error: IoError, from: &Path, to: &Path) -> IoError {
    let path = error.path_mut();
    if let Ok(relative) = path.strip_prefix(from) {
        *path = to.join(relative);
    }
    error
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An earlier output whose manifest lists `listed` beside its own file, and a file of the
    /// user's: foreign, so only `--force` may write into it.
    fn planted(dir: &Path, listed: &str) -> PathBuf {
        let out = dir.join("out");
        std::fs::create_dir(&out).unwrap();
        std::fs::write(out.join("flow.npy"), b"flow").unwrap();
        std::fs::write(out.join("mine.txt"), b"the user's").unwrap();
        let manifest = RunManifest {
            format: MANIFEST_FORMAT.into(),
            files: vec!["flow.npy".into(), listed.into()],
            ..RunManifest::default()
        };
        std::fs::write(
            out.join(RUN_MANIFEST),
            serde_json::to_vec(&manifest).unwrap(),
        )
        .unwrap();
        out
    }

    #[test]
    fn forced_outputs_never_remove_what_lies_outside_their_directory() {
        let dir = tempfile::tempdir().unwrap();
        let victim = dir.path().join("thesis.tex");
        std::fs::write(&victim, b"years of work").unwrap();
        let absolute = victim.to_str().unwrap().to_string();
        for listed in ["../thesis.tex", absolute.as_str(), "sub/x", "..", ".", ""] {
            let out = planted(dir.path(), listed);
            for overwrite in [Overwrite::EarlierRun, Overwrite::Force] {
                let error = StagedDir::create(&out, overwrite).unwrap_err().to_string();
                assert!(
                    error.contains("not a file meshflow writes"),
                    "{listed:?}: {error}"
                );
                assert!(error.contains(RUN_MANIFEST), "{error}");
            }
            assert!(StagedDir::update(&out, Overwrite::Force, |_| true).is_err());
            std::fs::remove_dir_all(&out).unwrap();
        }
        assert_eq!(std::fs::read(&victim).unwrap(), b"years of work");
    }

    #[test]
    fn forced_outputs_remove_listed_plain_files_but_not_links() {
        let dir = tempfile::tempdir().unwrap();
        let victim = dir.path().join("data.npy");
        std::fs::write(&victim, b"data").unwrap();
        let out = planted(dir.path(), "velocity.npy");
        #[cfg(unix)]
        std::os::unix::fs::symlink(&victim, out.join("velocity.npy")).unwrap();
        let staged = StagedDir::create(&out, Overwrite::Force).unwrap();
        std::fs::write(staged.path().join("summary.json"), b"{}").unwrap();
        staged.commit().unwrap();
        // The listed regular file went, the link stayed (not meshflow's), the user's file too.
        assert!(!out.join("flow.npy").exists());
        assert!(out.join("mine.txt").exists() && out.join("summary.json").exists());
        #[cfg(unix)]
        assert!(out.join("velocity.npy").is_symlink());
        assert_eq!(std::fs::read(&victim).unwrap(), b"data");
    }
}
