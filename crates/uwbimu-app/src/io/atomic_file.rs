//! Writing an output file so that its path never holds a half-written file: the content goes to
//! a temporary file beside it (`.<name>.partial`), which is renamed over the path only once it is
//! complete and flushed. A crash or a kill while writing leaves the path as it was (an older file
//! stays intact) and at most the temporary file behind.

use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use crate::io::{IoError as Error, IoResult as Result};

/// The temporary file [`write_atomically`] writes before renaming it to `path`.
pub fn partial_path(path: &Path) -> PathBuf {
    let name = path.file_name().map_or_else(|| "output".into(), |n| n.to_string_lossy().into_owned());
    path.with_file_name(format!(".{name}.partial"))
}

/// Writes `path` through `write`, which gets a buffered writer on the temporary file
/// ([`partial_path`]); flushes, syncs and renames it to `path` when `write` succeeds, removes it
/// when it fails.
///
/// # Errors
/// [`Error::Io`] if the temporary file cannot be created, written or renamed; errors of `write`
/// as they are.
pub fn write_atomically(path: &Path, write: impl FnOnce(&mut BufWriter<File>) -> Result<()>) -> Result<()> {
    let label = path.display().to_string();
    let partial = partial_path(path);
    let io = |e: std::io::Error| Error::io(&label, e);
    let mut out = BufWriter::new(File::create(&partial).map_err(io)?);
    let written = write(&mut out).and_then(|()| {
        let file = out.into_inner().map_err(|e| io(e.into_error()))?;
        file.sync_all().map_err(io)
    });
    match written {
        Ok(()) => std::fs::rename(&partial, path).map_err(io),
        Err(e) => {
            let _ = std::fs::remove_file(&partial);
            Err(e)
        }
    }
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
}
