//! Writing an output file so that its path never holds a half-written file: the content goes to
//! a temporary file beside it (`.<name>.partial`), which is renamed over the path only once it is
//! complete and flushed. A crash or a kill while writing leaves the path as it was (an older file
//! stays intact) and at most the temporary file behind.

use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use crate::{IoError as Error, IoResult as Result};

/// The temporary file an [`AtomicFile`] writes before renaming it to `path`.
pub fn partial_path(path: &Path) -> PathBuf {
    let name = path.file_name().map_or_else(|| "output".into(), |n| n.to_string_lossy().into_owned());
    path.with_file_name(format!(".{name}.partial"))
}

/// An output file being written: the content goes to the temporary file ([`partial_path`]),
/// which [`AtomicFile::commit`] renames over the path once complete. Dropped uncommitted (an
/// error, a panic), it removes the temporary file and leaves the path as it was.
#[derive(Debug)]
pub struct AtomicFile {
    // Declared before `partial` so that the file is closed before it is removed.
    out: BufWriter<File>,
    path: PathBuf,
    partial: PartialFile,
}

/// The temporary file, removed when dropped unless it was renamed to the path.
#[derive(Debug)]
struct PartialFile {
    path: PathBuf,
    renamed: bool,
}

impl Drop for PartialFile {
    fn drop(&mut self) {
        if !self.renamed {
            let _ = std::fs::remove_file(&self.path);
        }
    }
}

impl AtomicFile {
    /// Creates (or truncates) the temporary file of `path` and opens a buffered writer on it;
    /// `path` itself is untouched until [`Self::commit`].
    ///
    /// # Errors
    /// [`Error::Io`] if the temporary file cannot be created.
    pub fn create(path: &Path) -> Result<Self> {
        let partial = partial_path(path);
        let file = File::create(&partial).map_err(|e| Error::io(path.display(), e))?;
        Ok(Self { out: BufWriter::new(file), path: path.to_path_buf(), partial: PartialFile { path: partial, renamed: false } })
    }

    /// The buffered writer on the temporary file.
    pub fn writer(&mut self) -> &mut BufWriter<File> {
        &mut self.out
    }

    /// Flushes and syncs the temporary file, closes it and renames it to the path, replacing
    /// any file there. On failure the temporary file is removed and the path left as it was.
    ///
    /// # Errors
    /// [`Error::Io`] if flushing, syncing or renaming fails.
    pub fn commit(self) -> Result<()> {
        let Self { out, path, mut partial } = self;
        let io = |e: std::io::Error| Error::io(path.display(), e);
        let file = out.into_inner().map_err(|e| io(e.into_error()))?;
        file.sync_all().map_err(io)?;
        drop(file);
        std::fs::rename(&partial.path, &path).map_err(io)?;
        partial.renamed = true;
        Ok(())
    }
}

/// Writes `path` through `write`, which gets a buffered writer on the temporary file
/// ([`partial_path`]); flushes, syncs and renames it to `path` when `write` succeeds, removes it
/// when it fails ([`AtomicFile`]).
///
/// # Errors
/// [`Error::Io`] if the temporary file cannot be created, written or renamed; errors of `write`
/// as they are.
pub fn write_atomically(path: &Path, write: impl FnOnce(&mut BufWriter<File>) -> Result<()>) -> Result<()> {
    let mut file = AtomicFile::create(path)?;
    write(file.writer())?;
    file.commit()
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use std::io::Write;

    #[test]
    fn a_failed_write_leaves_the_old_file_and_no_partial() {
        let dir = std::env::temp_dir().join(format!("uwbimu_atomic_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("out.csv");
        write_atomically(&path, |w| w.write_all(b"old\n").map_err(|e| Error::io("t", e))).unwrap();
        let failed = write_atomically(&path, |w| {
            w.write_all(b"half").map_err(|e| Error::io("t", e))?;
            Err(Error::io("t", std::io::Error::other("disk full")))
        });
        assert!(failed.is_err());
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "old\n");
        assert!(!partial_path(&path).exists());
        write_atomically(&path, |w| w.write_all(b"new\n").map_err(|e| Error::io("t", e))).unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "new\n");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_dropped_file_leaves_the_old_file_and_no_partial() {
        let dir = std::env::temp_dir().join(format!("uwbimu_atomic_drop_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("out.mcap");
        let mut file = AtomicFile::create(&path).unwrap();
        file.writer().write_all(b"old\n").unwrap();
        file.commit().unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "old\n");
        assert!(!partial_path(&path).exists());
        let mut file = AtomicFile::create(&path).unwrap();
        file.writer().write_all(&[b'x'; 100_000]).unwrap();
        assert!(partial_path(&path).exists());
        drop(file);
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "old\n");
        assert!(!partial_path(&path).exists());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
