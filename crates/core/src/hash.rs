//! Content hashes: XXH3 (64 bit) from the `xxhash-rust` crate, streaming.
//!
//! One hash for every integrity check of the crate: the checksum of a saved `.npy`
//! (the same value `xxhsum -H3 FILE` prints), the checksum of a matrix sidecar's content,
//! and the fingerprint of a collection. Every input bit reaches every output bit, so sign
//! flips, swapped words or reordered names change the hash (the word-wise FNV variant it
//! replaces missed any even number of sign flips).
//!
//! This module sits at the bottom of the crate: it imports nothing from it.

use xxhash_rust::xxh3::Xxh3;

/// A streaming XXH3-64 hash (seed 0). Splitting the input between calls of
/// [`write`](Self::write) does not change the result.
#[derive(Clone)]
pub struct Hasher(Xxh3);

impl std::fmt::Debug for Hasher {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Hasher({})", self.hex())
    }
}

impl Default for Hasher {
    fn default() -> Self {
        Self::new()
    }
}

impl Hasher {
    /// A fresh hash.
    pub fn new() -> Self {
        Self(Xxh3::new())
    }

    /// Adds bytes.
    pub fn write(&mut self, bytes: &[u8]) {
        self.0.update(bytes);
    }

    /// Adds `f64` values as little-endian bytes (the same on every platform), in chunks.
    pub fn write_f64s(&mut self, values: &[f64]) {
        let mut buf = Vec::with_capacity(8 * 4096);
        for chunk in values.chunks(4096) {
            buf.clear();
            for v in chunk {
                buf.extend_from_slice(&v.to_le_bytes());
            }
            self.0.update(&buf);
        }
    }

    /// Adds `f32` values as little-endian bytes, in chunks.
    pub fn write_f32s(&mut self, values: &[f32]) {
        let mut buf = Vec::with_capacity(4 * 8192);
        for chunk in values.chunks(8192) {
            buf.clear();
            for v in chunk {
                buf.extend_from_slice(&v.to_le_bytes());
            }
            self.0.update(&buf);
        }
    }

    /// The hash of everything written.
    pub fn finish(&self) -> u64 {
        self.0.digest()
    }

    /// The hash as 16 lower-case hex digits (as `xxhsum -H3` prints it).
    pub fn hex(&self) -> String {
        hex(self.finish())
    }
}

/// A hash as 16 lower-case hex digits.
pub(crate) fn hex(h: u64) -> String {
    format!("{h:016x}")
}

/// The XXH3-64 of `bytes`, as 16 hex digits.
pub(crate) fn hex_of(bytes: &[u8]) -> String {
    hex(xxhash_rust::xxh3::xxh3_64(bytes))
}

/// A writer that hashes and counts what passes through it.
pub struct HashingWriter<W> {
    inner: W,
    hash: Hasher,
    bytes: u64,
}

impl<W: std::io::Write> HashingWriter<W> {
    /// Wraps `inner`.
    pub fn new(inner: W) -> Self {
        Self {
            inner,
            hash: Hasher::new(),
            bytes: 0,
        }
    }

    /// Bytes written so far and their hash.
    pub fn digest(&self) -> (u64, u64) {
        (self.bytes, self.hash.finish())
    }
}

impl<W: std::io::Write> std::io::Write for HashingWriter<W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let k = self.inner.write(buf)?;
        self.hash.write(&buf[..k]);
        self.bytes += k as u64;
        Ok(k)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.inner.flush()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn splitting_the_input_does_not_change_the_hash() {
        let data: Vec<u8> = (0..1000u32).map(|i| (i * 7 % 251) as u8).collect();
        let mut a = Hasher::new();
        a.write(&data);
        let mut b = Hasher::new();
        for c in data.chunks(13) {
            b.write(c);
        }
        assert_eq!(a.finish(), b.finish());
        assert_eq!(a.hex(), hex_of(&data));
    }

    #[test]
    fn known_xxh3_value_of_the_empty_input() {
        // XXH3_64bits("") with seed 0 (the xxHash reference value).
        assert_eq!(Hasher::new().finish(), 0x2d06_8005_38d3_94c2);
    }

    #[test]
    fn two_sign_flips_change_the_hash() {
        let mut a = Hasher::new();
        a.write_f64s(&[0.5, 1.25, 3.0, 7.0]);
        let mut b = Hasher::new();
        b.write_f64s(&[-0.5, 1.25, -3.0, 7.0]);
        assert_ne!(a.finish(), b.finish());
    }
}
