//! A batch's progress journal: the manifest entry of every variant as it
//! finishes, appended to `.{manifest name}.journal` beside the manifest.
//! A batch writes its manifest only at its end, so a batch that is killed
//! (preempted, timed out, its node lost) leaves no manifest; its journal
//! tells `--resume` what was already written. The journal is removed once
//! the manifest is in place.
//!
//! Format: a header line (the batch's identity, as JSON), then one JSON
//! line per finished variant. Lines are appended whole and flushed; a line
//! torn by a crash is ignored on reading. Nothing in it is trusted: every
//! output it lists is hashed again before it is skipped.

use std::fs::{self, File, OpenOptions};
use std::io::{self, Write};
use std::path::{Path, PathBuf};

use super::staged::parent_dir;

/// The journal that goes with the manifest at `manifest`.
pub fn path_for(manifest: &Path) -> PathBuf {
    let name = manifest
        .file_name()
        .map_or_else(|| "manifest".into(), |n| n.to_string_lossy().into_owned());
    parent_dir(manifest).join(format!(".{name}.journal"))
}

/// A journal being written.
pub struct Journal {
    file: File,
    path: PathBuf,
}

impl Journal {
    /// Starts (or restarts, truncating) the journal at `path` with its
    /// header line.
    pub fn start(path: &Path, header: &str) -> io::Result<Journal> {
        fs::create_dir_all(parent_dir(path))?;
        let mut file = OpenOptions::new()
            .write(true)
            .create(true)
            .truncate(true)
            .open(path)?;
        file.write_all(format!("{header}\n").as_bytes())?;
        Ok(Journal {
            file,
            path: path.to_path_buf(),
        })
    }

    /// Appends one line (written in one call, then flushed).
    pub fn append(&mut self, line: &str) -> io::Result<()> {
        self.file.write_all(format!("{line}\n").as_bytes())?;
        self.file.flush()
    }

    /// Removes the journal: the manifest now holds what it held.
    pub fn finish(self) -> io::Result<()> {
        drop(self.file);
        match fs::remove_file(&self.path) {
            Err(e) if e.kind() != io::ErrorKind::NotFound => Err(e),
            _ => Ok(()),
        }
    }
}

/// The header and the complete lines of the journal at `path`, if there
/// is one (a last line without its newline was torn and is left out).
pub fn read(path: &Path) -> io::Result<Option<(String, Vec<String>)>> {
    let Some(text) = super::read_json_text(path)? else {
        return Ok(None);
    };
    let complete = match text.rfind('\n') {
        Some(end) => &text[..end],
        None => return Ok(None),
    };
    let mut lines = complete.split('\n').map(str::to_owned);
    let Some(header) = lines.next() else {
        return Ok(None);
    };
    Ok(Some((header, lines.collect())))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_come_back_and_a_torn_one_is_dropped() {
        let dir = tempfile::tempdir().unwrap();
        let manifest = dir.path().join("out/manifest.json");
        let path = path_for(&manifest);
        assert_eq!(path, dir.path().join("out/.manifest.json.journal"));
        assert!(read(&path).unwrap().is_none());
        let mut journal = Journal::start(&path, "{\"batch\":1}").unwrap();
        journal.append("{\"index\":0}").unwrap();
        journal.append("{\"index\":1}").unwrap();
        let (header, lines) = read(&path).unwrap().unwrap();
        assert_eq!(header, "{\"batch\":1}");
        assert_eq!(lines, ["{\"index\":0}", "{\"index\":1}"]);
        // A crash mid-line.
        fs::OpenOptions::new()
            .append(true)
            .open(&path)
            .unwrap()
            .write_all(b"{\"ind")
            .unwrap();
        assert_eq!(read(&path).unwrap().unwrap().1.len(), 2);
        // Restarting truncates; finishing removes.
        let journal = Journal::start(&path, "{\"batch\":2}").unwrap();
        assert!(read(&path).unwrap().unwrap().1.is_empty());
        journal.finish().unwrap();
        assert!(!path.exists());
    }
}
