//! Records of a fixed number of `f64` kept in an unnamed temporary file, for what a long replay
//! must keep but not hold in memory (the segments and steps an RTS pass reads back newest
//! first). The file is unlinked from the start, so the system removes it when it is closed,
//! also after a crash. Values are stored bit for bit (little-endian).

use std::fs::File;
use std::io::{BufReader, BufWriter, Read, Seek, SeekFrom, Write};
use std::path::Path;

use crate::{IoError as Error, IoResult as Result};

/// Records read back per block ([`Spill::newest_first`]).
const BLOCK_RECORDS: usize = 1024;

/// A file of records of `N` numbers each, appended in order and read back either way.
pub struct Spill<const N: usize> {
    out: BufWriter<File>,
    len: u64,
    label: String,
}

impl<const N: usize> Spill<N> {
    const BYTES: usize = N * 8;

    /// A new, empty spill file in `dir`; `label` names it in errors (e.g. what it holds).
    ///
    /// # Errors
    /// [`Error::Io`] if the file cannot be created there.
    pub fn create(dir: &Path, label: &str) -> Result<Self> {
        let label = format!("{label} (temporary file in {})", dir.display());
        let file = tempfile::tempfile_in(dir).map_err(|e| Error::io(&label, e))?;
        Ok(Self { out: BufWriter::with_capacity(1 << 16, file), len: 0, label })
    }

    /// Records written so far.
    pub fn len(&self) -> u64 {
        self.len
    }

    /// Whether nothing was written.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Appends one record.
    ///
    /// # Errors
    /// [`Error::Io`] if writing fails (e.g. the disk is full).
    pub fn push(&mut self, record: &[f64; N]) -> Result<()> {
        let mut bytes = [0u8; 8];
        for v in record {
            bytes.copy_from_slice(&v.to_le_bytes());
            self.out.write_all(&bytes).map_err(|e| Error::io(&self.label, e))?;
        }
        self.len += 1;
        Ok(())
    }

    /// A handle on the file with everything written so far, for reading.
    fn reader(&mut self) -> Result<(File, u64, String)> {
        let label = self.label.clone();
        let io = |e: std::io::Error| Error::io(&label, e);
        self.out.flush().map_err(io)?;
        let file = self.out.get_ref().try_clone().map_err(io)?;
        Ok((file, self.len, label))
    }

    /// The records in the order written (a reader sharing the file's position: write nothing
    /// more while reading).
    ///
    /// # Errors
    /// [`Error::Io`] if the file cannot be flushed; each item: if reading fails.
    pub fn oldest_first(&mut self) -> Result<impl Iterator<Item = Result<[f64; N]>>> {
        let (mut file, len, label) = self.reader()?;
        file.seek(SeekFrom::Start(0)).map_err(|e| Error::io(&label, e))?;
        let mut input = BufReader::with_capacity(1 << 16, file);
        let mut bytes = vec![0u8; Self::BYTES];
        Ok((0..len).map(move |_| {
            input.read_exact(&mut bytes).map_err(|e| Error::io(&label, e))?;
            Ok(decode(&bytes))
        }))
    }

    /// The records newest first, read in blocks of 1024 from the end.
    ///
    /// # Errors
    /// [`Error::Io`] if the file cannot be flushed; each item: if reading fails.
    pub fn newest_first(&mut self) -> Result<impl Iterator<Item = Result<[f64; N]>>> {
        let (mut file, len, label) = self.reader()?;
        let mut block = Vec::new();
        let mut unread = len;
        let mut at = 0usize;
        Ok(std::iter::from_fn(move || {
            if at == 0 {
                if unread == 0 {
                    return None;
                }
                let n = unread.min(BLOCK_RECORDS as u64);
                unread -= n;
                block.resize(n as usize * Self::BYTES, 0);
                let read = file.seek(SeekFrom::Start(unread * Self::BYTES as u64)).and_then(|_| file.read_exact(&mut block));
                if let Err(e) = read {
                    unread = 0;
                    return Some(Err(Error::io(&label, e)));
                }
                at = n as usize;
            }
            at -= 1;
            Some(Ok(decode(&block[at * Self::BYTES..(at + 1) * Self::BYTES])))
        }))
    }
}

fn decode<const N: usize>(bytes: &[u8]) -> [f64; N] {
    let mut out = [0.0; N];
    for (v, b) in out.iter_mut().zip(bytes.chunks_exact(8)) {
        let mut le = [0u8; 8];
        le.copy_from_slice(b);
        *v = f64::from_le_bytes(le);
    }
    out
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn filled(n: u64) -> Spill<3> {
        let mut s = Spill::<3>::create(&std::env::temp_dir(), "test").unwrap();
        for k in 0..n {
            let x = k as f64;
            s.push(&[x, -x * 0.1, f64::from_bits(k)]).unwrap();
        }
        s
    }

    #[test]
    fn records_come_back_bit_for_bit_in_either_order() {
        for n in [0, 1, 1023, 1024, 1025, 3000] {
            let forward: Vec<[f64; 3]> = filled(n).oldest_first().unwrap().map(Result::unwrap).collect();
            let mut backward: Vec<[f64; 3]> = filled(n).newest_first().unwrap().map(Result::unwrap).collect();
            backward.reverse();
            assert_eq!(forward.len() as u64, n);
            for (k, (a, b)) in forward.iter().zip(&backward).enumerate() {
                let x = k as f64;
                assert_eq!(a.map(f64::to_bits), [x, -x * 0.1, f64::from_bits(k as u64)].map(f64::to_bits));
                assert_eq!(a.map(f64::to_bits), b.map(f64::to_bits));
            }
        }
    }

    #[test]
    fn a_directory_that_does_not_exist_is_an_error_naming_it() {
        let e = Spill::<3>::create(Path::new("/nonexistent/uwbimu"), "segments").err().unwrap().to_string();
        assert!(e.contains("segments") && e.contains("/nonexistent/uwbimu"), "{e}");
    }
}
