//! Writing results: atomic output directories, the trajectory CSV and number formatting.
//!
//! Owns [`OutDir`]: everything is written into a temporary sibling directory that is
//! renamed into place only when the command succeeds, so an error never leaves a
//! half-written result. An existing output directory is only replaced if host-sim made it
//! (it holds the marker file [`MARKER`]); anything else is refused.

use crate::error::CliError;
use reactionless::Sample;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// Marker file that identifies a directory written by host-sim.
pub const MARKER: &str = ".host-sim";

/// An output directory being written.
#[derive(Debug)]
pub struct OutDir {
    target: PathBuf,
    tmp: PathBuf,
    committed: bool,
}

impl OutDir {
    /// Prepares to write `target`. Refuses a path that exists and is not an empty directory
    /// or an earlier host-sim output.
    pub fn create(target: &Path) -> Result<Self, CliError> {
        let shown = target.display();
        if target.exists() {
            if !target.is_dir() {
                return Err(CliError::input(format!(
                    "--out {shown}: exists and is not a directory"
                )));
            }
            let mut entries = std::fs::read_dir(target)
                .map_err(|e| CliError::input(format!("--out {shown}: {e}")))?;
            let empty = entries.next().is_none();
            if !empty && !target.join(MARKER).exists() {
                return Err(CliError::input(format!(
                    "--out {shown}: exists, is not empty and was not written by host-sim; refusing to replace it"
                )));
            }
        }
        let name = target
            .file_name()
            .ok_or_else(|| CliError::input(format!("--out {shown}: not a directory name")))?
            .to_string_lossy()
            .to_string();
        let parent = match target.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        std::fs::create_dir_all(&parent)
            .map_err(|e| CliError::input(format!("--out {shown}: cannot create parent: {e}")))?;
        let tmp = parent.join(format!(".{name}.tmp-{}", std::process::id()));
        if tmp.exists() {
            std::fs::remove_dir_all(&tmp).map_err(|e| {
                CliError::input(format!("cannot clear stale {}: {e}", tmp.display()))
            })?;
        }
        std::fs::create_dir(&tmp)
            .map_err(|e| CliError::input(format!("cannot create {}: {e}", tmp.display())))?;
        Ok(Self {
            target: target.to_path_buf(),
            tmp,
            committed: false,
        })
    }

    /// Path of `name` inside the directory being written.
    pub fn path(&self, name: &str) -> PathBuf {
        self.tmp.join(name)
    }

    /// Writes a whole file.
    pub fn write(&self, name: &str, contents: &[u8]) -> Result<(), CliError> {
        std::fs::write(self.path(name), contents)
            .map_err(|e| CliError::input(format!("cannot write {name}: {e}")))
    }

    /// Writes `value` as pretty JSON with a trailing newline.
    pub fn write_json<T: serde::Serialize>(&self, name: &str, value: &T) -> Result<(), CliError> {
        let mut s = serde_json::to_string_pretty(value)
            .map_err(|e| CliError::internal(format!("JSON for {name}: {e}")))?;
        s.push('\n');
        self.write(name, s.as_bytes())
    }

    /// Moves the finished directory into place.
    pub fn commit(mut self) -> Result<PathBuf, CliError> {
        self.write(MARKER, b"written by host-sim\n")?;
        let old = self.tmp.with_file_name(format!(
            ".{}.old-{}",
            self.target
                .file_name()
                .map(|n| n.to_string_lossy().to_string())
                .unwrap_or_default(),
            std::process::id()
        ));
        let had_old = self.target.exists();
        if had_old {
            std::fs::rename(&self.target, &old).map_err(|e| {
                CliError::input(format!("cannot replace {}: {e}", self.target.display()))
            })?;
        }
        if let Err(e) = std::fs::rename(&self.tmp, &self.target) {
            if had_old {
                let _ = std::fs::rename(&old, &self.target);
            }
            return Err(CliError::input(format!(
                "cannot move output into {}: {e}",
                self.target.display()
            )));
        }
        if had_old {
            let _ = std::fs::remove_dir_all(&old);
        }
        self.committed = true;
        Ok(self.target.clone())
    }
}

impl Drop for OutDir {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_dir_all(&self.tmp);
        }
    }
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
        let file = File::create(path)
            .map_err(|e| CliError::input(format!("cannot create {}: {e}", path.display())))?;
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
        self.out
            .flush()
            .map_err(|e| CliError::input(format!("writing trajectory.csv: {e}")))
    }
}
