//! Read-only memory maps of files: a small safe wrapper over `libc::mmap` ([`MappedFile`])
//! and the float64 values of a saved matrix read in place from one ([`MappedF64`]), so
//! that `select --distances` on an 80 GB matrix needs no 80 GB of memory: the kernel
//! pages the file in as the clustering reads it, and those pages are file-backed (they
//! count in the resident set as `RssFile`, not `RssAnon`, and the kernel drops them
//! under memory pressure and reads them again when needed).
//!
//! # A file changed while mapped
//!
//! The mapping is private (`MAP_PRIVATE`) and read-only (`PROT_READ`): nothing this
//! program does writes the file, and an accidental write through the mapping would fault
//! instead of corrupting anything. Whether a change that *another* process makes to the
//! file after it was mapped shows through is up to the kernel (POSIX leaves it
//! unspecified for a private mapping; Linux shows it in pages not yet copied). That is
//! the user's problem, as for any file changed while read; what it can do here:
//!
//! * rewritten bytes are read as whatever float64 values they now hold: every bit
//!   pattern is a valid `f64`, so no value is ever invalid for Rust, but such a matrix
//!   escapes the checks `load_saved_matrix` made when it was opened (checksum, finite,
//!   non-negative, symmetric): results computed from it are meaningless, not unsafe;
//! * a file truncated below the mapped length makes a read of a page past its new end
//!   raise `SIGBUS`, which ends the process (no wrong result is written: outputs are
//!   staged and committed at the end, [`crate::atomic`]).
//!
//! Where mapping is not possible (a platform without `mmap`, a data offset that is not a
//! multiple of 8, a big-endian machine, a file system that refuses it), the loader falls
//! back to reading the matrix into memory, with the same checks and the same values.

use crate::distance::matrix::SharedValues;
use std::fs::File;
use std::io;

/// The first `len` bytes of a file, mapped read-only and private. Unmapped on drop.
pub struct MappedFile {
    ptr: std::ptr::NonNull<u8>,
    len: usize,
}

// SAFETY: the mapping is plain read-only memory owned by this value; nothing in it is
// tied to a thread.
unsafe impl Send for MappedFile {}
// SAFETY: `&MappedFile` only reads the memory.
unsafe impl Sync for MappedFile {}

impl std::fmt::Debug for MappedFile {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MappedFile")
            .field("len", &self.len)
            .finish()
    }
}

impl MappedFile {
    /// Maps the first `len` bytes of `file` (opened for reading) read-only and private.
    /// Refuses `len = 0` and a `len` larger than the file's size now (`fstat`), so that
    /// every mapped page lies inside the file as it is; see the module documentation for
    /// a file that shrinks afterwards. `Unsupported` on platforms without `mmap`.
    pub fn map(file: &File, len: u64) -> io::Result<Self> {
        let size = file.metadata()?.len();
        if len == 0 || len > size {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!("cannot map {len} bytes of a file of {size} bytes"),
            ));
        }
        let len = usize::try_from(len).map_err(|_| {
            io::Error::new(
                io::ErrorKind::InvalidInput,
                "the file is larger than the address space",
            )
        })?;
        Self::map_unix(file, len)
    }

    #[cfg(unix)]
    fn map_unix(file: &File, len: usize) -> io::Result<Self> {
        use std::os::unix::io::AsRawFd;
        // SAFETY: a fresh mapping (address chosen by the kernel) of `len > 0` bytes of an
        // open descriptor; the result is checked against MAP_FAILED. The descriptor may
        // be closed afterwards: the mapping keeps its own reference to the file.
        let p = unsafe {
            libc::mmap(
                std::ptr::null_mut(),
                len,
                libc::PROT_READ,
                libc::MAP_PRIVATE,
                file.as_raw_fd(),
                0,
            )
        };
        if p == libc::MAP_FAILED {
            return Err(io::Error::last_os_error());
        }
        let ptr = std::ptr::NonNull::new(p.cast::<u8>())
            .ok_or_else(|| io::Error::other("mmap returned a null address"))?;
        Ok(Self { ptr, len })
    }

    #[cfg(not(unix))]
    fn map_unix(_file: &File, _len: usize) -> io::Result<Self> {
        Err(io::Error::new(
            io::ErrorKind::Unsupported,
            "memory maps are not supported on this platform",
        ))
    }

    /// The mapped bytes.
    pub fn bytes(&self) -> &[u8] {
        // SAFETY: `ptr..ptr + len` is mapped readable for the life of `self` (unmapped
        // only in drop), and this program never writes it while shared (see
        // `with_writable`, which takes `&mut self`).
        unsafe { std::slice::from_raw_parts(self.ptr.as_ptr(), self.len) }
    }

    /// Runs `f` on the mapped bytes made writable, then makes them read-only again. The
    /// mapping is private: written pages become private copies (anonymous memory, only
    /// those pages), and the file is never changed.
    #[cfg(unix)]
    pub fn with_writable<R>(&mut self, f: impl FnOnce(&mut [u8]) -> R) -> io::Result<R> {
        let protect = |prot| {
            // SAFETY: changes the protection of exactly the mapping this value owns.
            if unsafe { libc::mprotect(self.ptr.as_ptr().cast(), self.len, prot) } != 0 {
                Err(io::Error::last_os_error())
            } else {
                Ok(())
            }
        };
        protect(libc::PROT_READ | libc::PROT_WRITE)?;
        // SAFETY: the pages are now writable; `&mut self` makes this the only reference.
        let out = f(unsafe { std::slice::from_raw_parts_mut(self.ptr.as_ptr(), self.len) });
        protect(libc::PROT_READ)?;
        Ok(out)
    }

    /// Not reachable: no mapping exists on platforms without `mmap`.
    #[cfg(not(unix))]
    pub fn with_writable<R>(&mut self, _f: impl FnOnce(&mut [u8]) -> R) -> io::Result<R> {
        Err(io::Error::new(
            io::ErrorKind::Unsupported,
            "memory maps are not supported on this platform",
        ))
    }
}

impl Drop for MappedFile {
    fn drop(&mut self) {
        #[cfg(unix)]
        // SAFETY: unmaps exactly the mapping this value created; no reference into it
        // outlives `self` (every slice handed out borrows `self`, and `MappedF64`'s
        // values are read only while it, hence this mapping, lives).
        unsafe {
            libc::munmap(self.ptr.as_ptr().cast(), self.len);
        }
    }
}

/// `count` little-endian float64 values at byte `offset` of a mapped file, read in
/// place as `&[f64]`.
#[derive(Debug)]
pub struct MappedF64 {
    map: MappedFile,
    offset: usize,
    count: usize,
}

impl MappedF64 {
    /// The values at `offset`, or `None` when they cannot be read in place: they do not
    /// fit in the mapping, the offset leaves them unaligned for `f64` (the mapping starts
    /// on a page; `.npy` writers pad the header to 64 bytes, but the format only promises
    /// 16), or the machine is big-endian.
    pub fn new(map: MappedFile, offset: usize, count: usize) -> Result<Self, MappedFile> {
        let fits = count
            .checked_mul(8)
            .and_then(|b| b.checked_add(offset))
            .is_some_and(|end| end <= map.len);
        let aligned =
            (map.ptr.as_ptr() as usize + offset).is_multiple_of(std::mem::align_of::<f64>());
        if fits && aligned && cfg!(target_endian = "little") {
            Ok(Self { map, offset, count })
        } else {
            Err(map)
        }
    }

    /// The values' bytes, as in the file.
    pub fn bytes(&self) -> &[u8] {
        &self.map.bytes()[self.offset..self.offset + 8 * self.count]
    }

    /// The values.
    pub fn values(&self) -> &[f64] {
        let bytes = self.bytes();
        // SAFETY: `new` checked that the range fits and is aligned for f64 and that the
        // machine is little-endian (the file's byte order); every bit pattern is a valid
        // f64.
        unsafe { std::slice::from_raw_parts(bytes.as_ptr().cast::<f64>(), self.count) }
    }

    /// Runs `f` on the values made writable (private copies of the written pages; the
    /// file is not changed), then makes them read-only again.
    pub fn with_writable<R>(&mut self, f: impl FnOnce(&mut [f64]) -> R) -> io::Result<R> {
        let (offset, count) = (self.offset, self.count);
        self.map.with_writable(|bytes| {
            let bytes = &mut bytes[offset..offset + 8 * count];
            // SAFETY: as in `values`, and `bytes` is the only reference to the range.
            f(unsafe { std::slice::from_raw_parts_mut(bytes.as_mut_ptr().cast::<f64>(), count) })
        })
    }
}

// SAFETY: `values` returns the same range of the same mapping on every call, and the
// mapping lives (unmoved: it is the kernel's, not this struct's memory) until drop.
unsafe impl SharedValues for MappedF64 {
    fn values(&self) -> &[f64] {
        MappedF64::values(self)
    }
}

#[cfg(all(test, unix))]
mod tests {
    use super::*;
    use std::io::Write;

    #[test]
    fn maps_the_file_and_refuses_lengths_beyond_it() {
        let dir = tempfile::tempdir().expect("tmp");
        let p = dir.path().join("f.bin");
        let mut bytes = vec![0u8; 16];
        for v in [1.5f64, -2.25, 1e300] {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
        std::fs::File::create(&p)
            .and_then(|mut f| f.write_all(&bytes))
            .expect("write");
        let f = File::open(&p).expect("open");
        let m = MappedFile::map(&f, bytes.len() as u64).expect("map");
        assert_eq!(m.bytes(), &bytes[..]);
        for bad in [0, bytes.len() as u64 + 1] {
            let e = MappedFile::map(&f, bad).expect_err("refused");
            assert_eq!(e.kind(), io::ErrorKind::InvalidInput, "{bad}: {e}");
        }
        let mut v = MappedF64::new(m, 16, 3).expect("aligned");
        assert_eq!(v.values(), &[1.5, -2.25, 1e300]);
        // Written pages are private: the file keeps its bytes.
        v.with_writable(|x| x[1] = 7.0).expect("writable");
        assert_eq!(v.values(), &[1.5, 7.0, 1e300]);
        assert_eq!(std::fs::read(&p).expect("read"), bytes);
        // Unaligned or too long: not read in place.
        let m = MappedFile::map(&f, bytes.len() as u64).expect("map");
        let m = MappedF64::new(m, 12, 3).expect_err("unaligned");
        let m = MappedF64::new(m, 16, 4).expect_err("too long");
        assert!(MappedF64::new(m, 8, usize::MAX / 4).is_err());
    }
}
