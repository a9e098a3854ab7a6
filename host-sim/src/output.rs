//! Writing results: atomic output directories and files, and the trajectory CSV.
//!
//! Owns [`OutDir`]: everything is written into a temporary sibling directory
//! (`tempfile`) that is renamed into place only when the command succeeds, so an error
//! never leaves a half-written result. An existing output directory is only replaced if
//! host-sim made it (it holds the marker file [`MARKER`]); anything else is refused.
//! [`write_file`] does the same for a single file (records, pages, blocks, URDFs) and
//! replaces only a file host-sim wrote ([`FileKind`]), and [`CsvSink`] streams the
//! trajectory in shortest round-trip form (parsing gives back the core's bits);
//! [`read_trajectory_csv`] reads it back (`check`, `view`).

use crate::error::{CliError, Context};
use reactionless::Sample;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use tempfile::TempDir;

/// Marker file that identifies a directory written by host-sim.
pub const MARKER: &str = ".host-sim";

/// An output directory being written.
#[derive(Debug)]
pub struct OutDir {
    target: PathBuf,
    tmp: TempDir,
}

/// The directory `path` lives in (`.` for a bare name).
fn parent_of(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// `path`'s file name, or a bad-input error naming `what`.
fn file_name(path: &Path, what: &str) -> Result<String, CliError> {
    path.file_name()
        .map(|n| n.to_string_lossy().to_string())
        .ok_or_else(|| CliError::input(format!("{what} {}: not a file name", path.display())))
}

impl OutDir {
    /// Prepares to write `target` (named `--out` in messages). Refuses a path that exists
    /// and is not an empty directory or an earlier host-sim output.
    pub fn create(target: &Path) -> Result<Self, CliError> {
        let shown = target.display();
        if target.exists() {
            if !target.is_dir() {
                return Err(CliError::input(format!(
                    "--out {shown}: exists and is not a directory"
                )));
            }
            let mut entries = std::fs::read_dir(target).or_input(|| format!("--out {shown}"))?;
            let empty = entries.next().is_none();
            if !empty && !target.join(MARKER).exists() {
                return Err(CliError::input(format!(
                    "--out {shown}: exists, is not empty and was not written by host-sim; refusing to replace it"
                )));
            }
        }
        let name = file_name(target, "--out")?;
        let parent = parent_of(target);
        std::fs::create_dir_all(&parent)
            .or_input(|| format!("--out {shown}: cannot create parent"))?;
        let mut builder = tempfile::Builder::new();
        let prefix = format!(".{name}.tmp-");
        builder.prefix(&prefix);
        umask_mode(&mut builder, true);
        let tmp = builder
            .tempdir_in(&parent)
            .or_input(|| format!("--out {shown}: cannot create a temporary directory"))?;
        Ok(Self {
            target: target.to_path_buf(),
            tmp,
        })
    }

    /// Path of `name` inside the directory being written.
    pub fn path(&self, name: &str) -> PathBuf {
        self.tmp.path().join(name)
    }

    /// Writes a whole file.
    pub fn write(&self, name: &str, contents: &[u8]) -> Result<(), CliError> {
        std::fs::write(self.path(name), contents).or_input(|| format!("cannot write {name}"))
    }

    /// Writes `value` as pretty JSON with a trailing newline.
    pub fn write_json<T: serde::Serialize>(&self, name: &str, value: &T) -> Result<(), CliError> {
        let mut s =
            serde_json::to_string_pretty(value).or_internal(|| format!("JSON for {name}"))?;
        s.push('\n');
        self.write(name, s.as_bytes())
    }

    /// Moves the finished directory into place (replacing an earlier host-sim output).
    pub fn commit(self) -> Result<PathBuf, CliError> {
        self.write(MARKER, b"written by host-sim\n")?;
        let shown = self.target.display();
        // The old output is moved into a temporary directory of its own first, so the
        // rename of the new one cannot meet a non-empty directory; it goes when `old` drops.
        let old = match self.target.exists() {
            true => {
                let old = tempfile::Builder::new()
                    .prefix(".host-sim-old-")
                    .tempdir_in(parent_of(&self.target))
                    .or_input(|| format!("cannot replace {shown}"))?;
                std::fs::rename(&self.target, old.path().join("out"))
                    .or_input(|| format!("cannot replace {shown}"))?;
                Some(old)
            }
            false => None,
        };
        let tmp = self.tmp.keep();
        if let Err(e) = std::fs::rename(&tmp, &self.target) {
            if let Some(old) = &old {
                let _ = std::fs::rename(old.path().join("out"), &self.target);
            }
            let _ = std::fs::remove_dir_all(&tmp);
            return Err(CliError::input(format!(
                "cannot move output into {shown}: {e}"
            )));
        }
        Ok(self.target)
    }
}

/// A single file host-sim writes with `--out FILE`, recognised by its content: such a file
/// is replaced, any other is not.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FileKind {
    /// A certification record (`record`).
    Record,
    /// A 3-D replay page (`view`).
    Page,
    /// A task block (`block`).
    Block,
    /// A dispersed robot (`disperse --export-sample`).
    Urdf,
    /// A path's clearance (`check --clearance-json`).
    Clearance,
}

impl FileKind {
    /// `true` if `bytes` are a file of this kind that host-sim wrote.
    fn recognises(self, bytes: &[u8]) -> bool {
        let has = |needle: &str| bytes.windows(needle.len()).any(|w| w == needle.as_bytes());
        match self {
            FileKind::Record => has("\"format\": \"reactionless-record/"),
            FileKind::Page => has("reactionless: the 3-D replay page"),
            FileKind::Block => bytes.starts_with(b"RLTASK"),
            FileKind::Urdf => has("<!-- written by host-sim"),
            FileKind::Clearance => has("\"format\": \"reactionless-clearance/"),
        }
    }

    fn name(self) -> &'static str {
        match self {
            FileKind::Record => "a certification record",
            FileKind::Page => "a replay page",
            FileKind::Block => "a task block",
            FileKind::Urdf => "a URDF written by host-sim",
            FileKind::Clearance => "a clearance report",
        }
    }
}

/// Writes `contents` to `path` (named `--out`) as a file of `kind`, atomically: a temporary
/// file beside it, then a rename, with the mode the user's umask gives. An existing file is
/// replaced only if host-sim wrote it (it is of `kind`); a directory is refused.
pub fn write_file(path: &Path, contents: &[u8], kind: FileKind) -> Result<(), CliError> {
    let shown = path.display();
    if path.is_dir() {
        return Err(CliError::input(format!(
            "--out {shown}: is a directory; give a file name, e.g. {}",
            path.join("out").display()
        )));
    }
    if path.exists() {
        let old = std::fs::read(path).or_input(|| format!("--out {shown}"))?;
        if !kind.recognises(&old) {
            return Err(CliError::input(format!(
                "--out {shown}: exists and is not {} that host-sim wrote; refusing to replace it",
                kind.name()
            )));
        }
    }
    write_atomic(path, contents)
}

/// Writes `contents` to `path` atomically: a temporary file beside it, then a rename; the
/// file's mode is what the user's umask gives (as for any new file), not the temporary
/// file's 0600.
fn write_atomic(path: &Path, contents: &[u8]) -> Result<(), CliError> {
    let dir = parent_of(path);
    std::fs::create_dir_all(&dir).or_input(|| dir.display().to_string())?;
    let mut builder = tempfile::Builder::new();
    let prefix = format!(".{}.tmp-", file_name(path, "--out")?);
    builder.prefix(&prefix);
    umask_mode(&mut builder, false);
    let mut tmp = builder
        .tempfile_in(&dir)
        .or_input(|| path.display().to_string())?;
    tmp.write_all(contents)
        .or_input(|| path.display().to_string())?;
    tmp.persist(path)
        .map_err(|e| e.error)
        .or_input(|| path.display().to_string())?;
    Ok(())
}

/// Gives `builder` the mode a new file (`dir == false`, 0666) or directory (0777) is
/// created with before the user's umask applies, as the shell's would be; tempfile's own
/// 0600/0700 would otherwise stay after the rename. Elsewhere than Unix, the platform's.
fn umask_mode(builder: &mut tempfile::Builder<'_, '_>, dir: bool) {
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        builder.permissions(std::fs::Permissions::from_mode(if dir {
            0o777
        } else {
            0o666
        }));
    }
    #[cfg(not(unix))]
    let _ = (builder, dir);
}

/// Streams samples into `trajectory.csv`: header `t,q1..qN,qd1..qdN` (s, rad, rad/s).
#[derive(Debug)]
pub struct CsvSink {
    out: BufWriter<File>,
    error: Option<std::io::Error>,
    line: String,
}

impl CsvSink {
    /// Creates the file and writes the header for `n` joints.
    pub fn create(path: &Path, n: usize) -> Result<Self, CliError> {
        let file = File::create(path).or_input(|| format!("cannot create {}", path.display()))?;
        let mut out = BufWriter::new(file);
        let mut header = String::from("t");
        for i in 1..=n {
            header.push_str(&format!(",q{i}"));
        }
        for i in 1..=n {
            header.push_str(&format!(",qd{i}"));
        }
        header.push('\n');
        let error = out.write_all(header.as_bytes()).err();
        Ok(Self {
            out,
            error,
            line: String::new(),
        })
    }

    /// Appends one sample.
    pub fn push<const N: usize>(&mut self, s: &Sample<N>) {
        if self.error.is_some() {
            return;
        }
        self.line.clear();
        let mut buf = ryu::Buffer::new();
        self.line.push_str(buf.format(s.t));
        for v in s.q.iter().chain(s.qd.iter()) {
            self.line.push(',');
            self.line.push_str(buf.format(*v));
        }
        self.line.push('\n');
        if let Err(e) = self.out.write_all(self.line.as_bytes()) {
            self.error = Some(e);
        }
    }

    /// Flushes; reports the first write error.
    pub fn finish(mut self) -> Result<(), CliError> {
        if let Some(e) = self.error.take() {
            return Err(CliError::input(format!("writing trajectory.csv: {e}")));
        }
        self.out.flush().or_input(|| "writing trajectory.csv")
    }
}

/// Parses `trajectory.csv` as [`CsvSink`] writes it (header, then rows of `1 + 2N`
/// numbers, every value exactly as written); errors name `dir` and the row.
pub fn read_trajectory_csv<const N: usize>(
    dir: &Path,
    csv: &str,
) -> Result<Vec<Sample<N>>, CliError> {
    let err = |m: String| CliError::input(format!("{}: trajectory.csv: {m}", dir.display()));
    let mut lines = csv.lines();
    let header = lines.next().ok_or_else(|| err("empty file".into()))?;
    let mut want = String::from("t");
    for i in 1..=N {
        want.push_str(&format!(",q{i}"));
    }
    for i in 1..=N {
        want.push_str(&format!(",qd{i}"));
    }
    if header != want {
        return Err(err(format!("header {header:?}, expected {want:?}")));
    }
    let mut out = Vec::new();
    for (row, text) in lines.enumerate() {
        let values: Vec<f64> = text
            .split(',')
            .map(|v| v.parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|e| err(format!("row {}: {e}", row + 1)))?;
        if values.len() != 1 + 2 * N {
            return Err(err(format!(
                "row {}: {} values, expected {}",
                row + 1,
                values.len(),
                1 + 2 * N
            )));
        }
        let mut s = Sample {
            step: row as u32,
            t: values[0],
            q: [0.0; N],
            qd: [0.0; N],
        };
        s.q.copy_from_slice(&values[1..=N]);
        s.qd.copy_from_slice(&values[N + 1..]);
        out.push(s);
    }
    Ok(out)
}
