//! The container of a saved simulation: a header — the magic bytes [`MAGIC`] and a
//! little-endian `u32` format version, [`VERSION`] — then named sections in a fixed
//! order, each its length (`u64`), the CRC-32 of its bytes (`u32`) and the bytes
//! (postcard). A reader checks every length against what is left of [`MAX_SAVE_BYTES`]
//! before it reads, every checksum before it decodes, and that nothing follows the last
//! section; its errors name the section ("particles: checksum mismatch"). So a file that
//! is not a save is refused after its first bytes, a truncated, corrupted or extended
//! one is refused whole, and nothing is allocated on a length the file merely claims.

use crate::error::{CleaveError, Result};
use serde::Serialize;
use serde::de::DeserializeOwned;
use std::io::{Read, Write};

/// The first bytes of a saved simulation.
pub const MAGIC: [u8; 8] = *b"cleave\0s";

/// The format version this build writes and reads.
pub const VERSION: u32 = 15;

/// Largest saved simulation a reader reads, in bytes.
pub const MAX_SAVE_BYTES: u64 = 4 << 30;

fn invalid(what: impl std::fmt::Display) -> CleaveError {
    CleaveError::Save(what.to_string())
}

/// Writes a header, then sections.
pub struct SaveWriter<W: Write> {
    out: W,
}

impl<W: Write> SaveWriter<W> {
    /// Writes the header to `out`.
    pub fn new(mut out: W) -> Result<Self> {
        out.write_all(&MAGIC)
            .and_then(|()| out.write_all(&VERSION.to_le_bytes()))
            .map_err(|e| invalid(format!("cannot write: {e}")))?;
        Ok(Self { out })
    }

    /// Writes `value` as the next section (`name` is for errors).
    pub fn section<T: Serialize>(&mut self, name: &str, value: &T) -> Result<()> {
        let bytes = postcard::to_stdvec(value).map_err(|e| invalid(format!("{name}: {e}")))?;
        let checksum = crc32fast::hash(&bytes);
        self.out
            .write_all(&(bytes.len() as u64).to_le_bytes())
            .and_then(|()| self.out.write_all(&checksum.to_le_bytes()))
            .and_then(|()| self.out.write_all(&bytes))
            .map_err(|e| invalid(format!("cannot write: {e}")))
    }

    /// Flushes the file.
    pub fn finish(mut self) -> Result<()> {
        self.out
            .flush()
            .map_err(|e| invalid(format!("cannot write: {e}")))
    }
}

/// Reads a header, then sections, checking each (see the module docs).
pub struct SaveReader<R: Read> {
    input: R,
    /// Bytes the rest of the file may still take.
    left: u64,
}

impl<R: Read> SaveReader<R> {
    /// Reads and checks the header of `input`.
    pub fn new(input: R) -> Result<Self> {
        let mut reader = Self {
            input,
            left: MAX_SAVE_BYTES,
        };
        let header: [u8; 12] = reader.exact("header")?;
        if header[..8] != MAGIC {
            return Err(invalid("not a saved cleave simulation"));
        }
        let version = u32::from_le_bytes([header[8], header[9], header[10], header[11]]);
        if version != VERSION {
            return Err(invalid(format!(
                "format version {version}, but this build reads version {VERSION}"
            )));
        }
        Ok(reader)
    }

    /// Reads `N` bytes that `what` needs.
    fn exact<const N: usize>(&mut self, what: &str) -> Result<[u8; N]> {
        let mut bytes = [0u8; N];
        self.input
            .read_exact(&mut bytes)
            .map_err(|e| invalid(format!("{what}: truncated ({e})")))?;
        self.left = self.left.saturating_sub(N as u64);
        Ok(bytes)
    }

    /// Reads, checks and decodes the next section, `name`.
    pub fn section<T: DeserializeOwned>(&mut self, name: &str) -> Result<T> {
        let length = u64::from_le_bytes(self.exact(name)?);
        let checksum = u32::from_le_bytes(self.exact(name)?);
        if length > self.left {
            return Err(invalid(format!(
                "{name}: claims {length} bytes, more than the file may hold ({} GiB in all)",
                MAX_SAVE_BYTES >> 30
            )));
        }
        let mut bytes = Vec::new();
        (&mut self.input)
            .take(length)
            .read_to_end(&mut bytes)
            .map_err(|e| invalid(format!("{name}: cannot read: {e}")))?;
        if bytes.len() as u64 != length {
            return Err(invalid(format!(
                "{name}: truncated ({} of {length} bytes)",
                bytes.len()
            )));
        }
        self.left -= length;
        if crc32fast::hash(&bytes) != checksum {
            return Err(invalid(format!("{name}: checksum mismatch")));
        }
        postcard::from_bytes(&bytes).map_err(|e| invalid(format!("{name}: corrupt ({e})")))
    }

    /// Checks that nothing follows the last section.
    pub fn finish(mut self) -> Result<()> {
        let mut byte = [0u8; 1];
        match self.input.read(&mut byte) {
            Ok(0) => Ok(()),
            Ok(_) => Err(invalid("bytes after the end of the saved simulation")),
            Err(e) => Err(invalid(format!("cannot read: {e}"))),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn saved() -> Vec<u8> {
        let mut bytes = Vec::new();
        let mut w = SaveWriter::new(&mut bytes).expect("header");
        w.section("numbers", &vec![1.5f32, 2.5, -3.0])
            .expect("a section");
        w.section("name", &"cleave".to_string()).expect("a section");
        w.finish().expect("flushed");
        bytes
    }

    fn read(bytes: &[u8]) -> Result<(Vec<f32>, String)> {
        let mut r = SaveReader::new(bytes)?;
        let numbers = r.section("numbers")?;
        let name = r.section("name")?;
        r.finish()?;
        Ok((numbers, name))
    }

    #[test]
    fn every_flipped_byte_truncation_and_extension_is_refused() {
        let good = saved();
        assert_eq!(
            read(&good).expect("reads"),
            (vec![1.5, 2.5, -3.0], "cleave".into())
        );
        for at in 0..good.len() {
            let mut bad = good.clone();
            bad[at] ^= 0x5a;
            assert!(read(&bad).is_err(), "byte {at} flipped was read");
        }
        for cut in 0..good.len() {
            assert!(read(&good[..cut]).is_err(), "truncated at {cut} was read");
        }
        let mut longer = good.clone();
        longer.push(0);
        let e = read(&longer).unwrap_err().to_string();
        assert!(e.contains("bytes after the end"), "{e}");
        let mut twice = good.clone();
        twice.extend_from_slice(&good);
        assert!(read(&twice).is_err());
    }

    #[test]
    fn errors_name_the_section_and_lengths_are_checked_before_reading() {
        let good = saved();
        // the first section's payload starts after the header (12) and its frame (12)
        let mut bad = good.clone();
        bad[25] ^= 1;
        let e = read(&bad).unwrap_err().to_string();
        assert!(e.contains("numbers: checksum mismatch"), "{e}");
        // a length of 2^63: refused without reading or allocating it
        let mut huge = good.clone();
        huge[12..20].copy_from_slice(&(1u64 << 63).to_le_bytes());
        let e = read(&huge).unwrap_err().to_string();
        assert!(e.contains("numbers: claims"), "{e}");
        // not a save at all: refused after its first 12 bytes, however long it is
        let zeros = std::io::repeat(0).take(1 << 40);
        let e = SaveReader::new(zeros).err().expect("refused").to_string();
        assert!(e.contains("not a saved cleave simulation"), "{e}");
    }
}
