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
//! instead of corrupting anything. Another process may still change the file while it is
//! mapped, and what a private mapping then shows is up to the kernel (Linux shows the
//! new bytes in pages not yet copied). Neither change may end in a wrong result or a
//! crash:
//!
//! * **Rewritten in place** (`dd conv=notrunc`, a program writing into it): the values
//!   read afterwards are whatever the bytes now hold (every bit pattern is a valid `f64`:
//!   meaningless, never unsafe). [`MappedFile::unchanged`] tells: the file's size,
//!   modification time and change time (`fstat` of the descriptor the map was made from)
//!   are recorded when it is mapped, and after the work the file must still have them
//!   and its bytes must still hash to the checksum checked when it was loaded (one more
//!   sequential read: 0.1-0.2 s per GB from the page cache). `select --distances` checks
//!   this after clustering and refuses the result otherwise. The change time cannot be
//!   set back by a program, and the checksum catches a write within the timestamps'
//!   granularity.
//! * **Truncated** (`truncate`, or `cp other.npy d.npy`, which truncates first): reading
//!   a page past the new end raises `SIGBUS`, which would kill the process. On Linux a
//!   `SIGBUS` handler, installed with the first map, catches a fault inside a live
//!   mapping, maps a page of zeros over the page that faulted (so the read completes with
//!   zeros) and records it; [`MappedFile::unchanged`] then reports the truncation. A
//!   `SIGBUS` anywhere else goes to the handler that was there before (Rust's own, or
//!   Python's `faulthandler`), or, with none, to the default action, as if this handler
//!   did not exist. Elsewhere (no guard) a truncation still raises `SIGBUS`.
//!
//! A file replaced by a rename (`mv new.npy d.npy`) changes nothing: the mapping keeps
//! the old file, which is what was checked.
//!
//! Where mapping is not possible (a platform without `mmap`, a data offset that is not a
//! multiple of 8, a big-endian machine, a file system that refuses it), the loader falls
//! back to reading the matrix into memory, with the same checks and the same values.

use crate::distance::SharedValues;
use std::fs::File;
use std::io;

/// The first `len` bytes of a file, mapped read-only and private. Unmapped on drop.
pub struct MappedFile {
    ptr: std::ptr::NonNull<u8>,
    len: usize,
    /// The file, kept open to tell whether it changed ([`MappedFile::unchanged`]).
    file: File,
    /// Its size and times when mapped.
    stamp: Stamp,
    /// Its slot in the `SIGBUS` guard (`None`: unguarded).
    guard: Option<usize>,
}

/// What a file looked like: size, modification and change times (seconds, nanoseconds).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Stamp {
    len: u64,
    mtime: (i64, i64),
    ctime: (i64, i64),
}

impl Stamp {
    fn of(file: &File) -> io::Result<Self> {
        let m = file.metadata()?;
        #[cfg(unix)]
        {
            use std::os::unix::fs::MetadataExt;
            Ok(Self {
                len: m.len(),
                mtime: (m.mtime(), m.mtime_nsec()),
                ctime: (m.ctime(), m.ctime_nsec()),
            })
        }
        #[cfg(not(unix))]
        Ok(Self {
            len: m.len(),
            mtime: (0, 0),
            ctime: (0, 0),
        })
    }
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
    /// a file that changes or shrinks afterwards. `Unsupported` on platforms without
    /// `mmap`.
    pub fn map(file: &File, len: u64) -> io::Result<Self> {
        let stamp = Stamp::of(file)?;
        let size = stamp.len;
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
        let (ptr, len) = Self::map_unix(file, len)?;
        let guard = guard::register(ptr.as_ptr() as usize, len);
        Ok(Self {
            ptr,
            len,
            file: file.try_clone()?,
            stamp,
            guard,
        })
    }

    /// Whether the file is as it was when mapped: not truncated under the mapping (a read
    /// past its new end was caught, module documentation), the same size, modification
    /// and change times, and, when `xxh3` is given, its bytes still hash to it (XXH3-64 of
    /// the whole file, [`crate::hash::Hasher`]). The error says what changed.
    pub fn unchanged(&self, xxh3: Option<u64>) -> Result<(), String> {
        if self.guard.is_some_and(guard::faulted) {
            return Err("truncated: a read past its new end was caught".into());
        }
        let now = Stamp::of(&self.file).map_err(|e| format!("cannot stat it again: {e}"))?;
        if now.len != self.stamp.len {
            return Err(format!(
                "its size went from {} to {} bytes",
                self.stamp.len, now.len
            ));
        }
        if now != self.stamp {
            return Err("written to: its modification or change time differs".into());
        }
        if let Some(want) = xxh3 {
            use std::io::Read;
            let mut h = crate::hash::Hasher::new();
            let mut f = &self.file;
            std::io::Seek::seek(&mut f, io::SeekFrom::Start(0))
                .map_err(|e| format!("cannot read it again: {e}"))?;
            let mut buf = vec![0u8; 1 << 20];
            let mut total = 0u64;
            loop {
                let n = f
                    .read(&mut buf)
                    .map_err(|e| format!("cannot read it again: {e}"))?;
                if n == 0 {
                    break;
                }
                total += n as u64;
                h.write(&buf[..n]);
            }
            if total != self.stamp.len || h.finish() != want {
                return Err(format!(
                    "rewritten: its checksum was {} when loaded and is {} now",
                    crate::hash::hex(want),
                    crate::hash::hex(h.finish())
                ));
            }
        }
        Ok(())
    }

    #[cfg(unix)]
    fn map_unix(file: &File, len: usize) -> io::Result<(std::ptr::NonNull<u8>, usize)> {
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
        Ok((ptr, len))
    }

    #[cfg(not(unix))]
    fn map_unix(_file: &File, _len: usize) -> io::Result<(std::ptr::NonNull<u8>, usize)> {
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
        if let Some(slot) = self.guard {
            guard::unregister(slot);
        }
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
    /// The whole file's checksum as checked when loaded ([`Self::set_checksum`]).
    xxh3: Option<u64>,
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
            Ok(Self {
                map,
                offset,
                count,
                xxh3: None,
            })
        } else {
            Err(map)
        }
    }

    /// Records the whole file's XXH3-64 as checked when it was loaded: [`Self::unchanged`]
    /// then also checks that the file still hashes to it.
    pub fn set_checksum(&mut self, xxh3: u64) {
        self.xxh3 = Some(xxh3);
    }

    /// [`MappedFile::unchanged`] with the recorded checksum.
    pub fn unchanged(&self) -> Result<(), String> {
        self.map.unchanged(self.xxh3)
    }

    /// [`MappedFile::unchanged`] without reading the file again (size, times, truncation).
    pub fn unchanged_quick(&self) -> Result<(), String> {
        self.map.unchanged(None)
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

    fn unchanged(&self) -> Result<(), String> {
        MappedF64::unchanged(self)
    }

    fn unchanged_quick(&self) -> Result<(), String> {
        MappedF64::unchanged_quick(self)
    }
}

/// The `SIGBUS` guard of live mappings (module documentation): a table of mapped ranges
/// and a handler that maps zeros over a page that faulted inside one and records it.
#[cfg(any(target_os = "linux", target_os = "android"))]
mod guard {
    use std::sync::atomic::{AtomicBool, AtomicU8, AtomicUsize, Ordering};
    use std::sync::OnceLock;

    const FREE: u8 = 0;
    const BUSY: u8 = 1;
    const LIVE: u8 = 2;

    struct Slot {
        state: AtomicU8,
        start: AtomicUsize,
        end: AtomicUsize,
        faulted: AtomicBool,
    }

    #[allow(clippy::declare_interior_mutable_const)]
    const EMPTY: Slot = Slot {
        state: AtomicU8::new(FREE),
        start: AtomicUsize::new(0),
        end: AtomicUsize::new(0),
        faulted: AtomicBool::new(false),
    };

    /// Live mappings at once (more are mapped unguarded).
    const SLOTS: usize = 64;
    static TABLE: [Slot; SLOTS] = [EMPTY; SLOTS];
    static PAGE: AtomicUsize = AtomicUsize::new(4096);
    /// The handler before this one (`None`: installing failed; nothing is guarded).
    static PREVIOUS: OnceLock<Option<libc::sigaction>> = OnceLock::new();

    fn install() -> bool {
        PREVIOUS
            .get_or_init(|| {
                // SAFETY: sysconf and sigaction with valid pointers; the new action's
                // handler is an `extern "C"` function with the SA_SIGINFO signature.
                unsafe {
                    let page = libc::sysconf(libc::_SC_PAGESIZE);
                    if page > 0 {
                        PAGE.store(page as usize, Ordering::Relaxed);
                    }
                    let mut old: libc::sigaction = std::mem::zeroed();
                    let mut new: libc::sigaction = std::mem::zeroed();
                    new.sa_sigaction = on_sigbus as *const () as usize;
                    new.sa_flags = libc::SA_SIGINFO | libc::SA_ONSTACK | libc::SA_NODEFER;
                    libc::sigemptyset(&mut new.sa_mask);
                    if libc::sigaction(libc::SIGBUS, &new, &mut old) != 0 {
                        return None;
                    }
                    Some(old)
                }
            })
            .is_some()
    }

    /// Guards `start..start + len`; its slot, or `None` (no handler, table full).
    pub(super) fn register(start: usize, len: usize) -> Option<usize> {
        if !install() {
            return None;
        }
        for (i, s) in TABLE.iter().enumerate() {
            if s.state
                .compare_exchange(FREE, BUSY, Ordering::AcqRel, Ordering::Relaxed)
                .is_ok()
            {
                s.start.store(start, Ordering::Relaxed);
                s.end.store(start + len, Ordering::Relaxed);
                s.faulted.store(false, Ordering::Relaxed);
                s.state.store(LIVE, Ordering::Release);
                return Some(i);
            }
        }
        None
    }

    /// Whether a read past the file's end was caught in slot `i`.
    pub(super) fn faulted(i: usize) -> bool {
        TABLE[i].faulted.load(Ordering::Acquire)
    }

    /// Frees slot `i` (before its range is unmapped).
    pub(super) fn unregister(i: usize) {
        TABLE[i].state.store(BUSY, Ordering::Release);
        TABLE[i].state.store(FREE, Ordering::Release);
    }

    /// Only async-signal-safe work: atomics, `mmap`, `sigaction`.
    extern "C" fn on_sigbus(sig: libc::c_int, info: *mut libc::siginfo_t, ctx: *mut libc::c_void) {
        // SAFETY: the kernel passes a valid siginfo for an SA_SIGINFO handler.
        let addr = unsafe { (*info).si_addr() } as usize;
        let page = PAGE.load(Ordering::Relaxed);
        for s in TABLE.iter() {
            if s.state.load(Ordering::Acquire) == LIVE
                && s.start.load(Ordering::Relaxed) <= addr
                && addr < s.end.load(Ordering::Relaxed)
            {
                let base = addr & !(page - 1);
                // SAFETY: replaces one page inside a mapping this program owns (live in
                // the table) by private zeros; the faulting read then completes.
                let p = unsafe {
                    libc::mmap(
                        base as *mut libc::c_void,
                        page,
                        libc::PROT_READ | libc::PROT_WRITE,
                        libc::MAP_PRIVATE | libc::MAP_ANONYMOUS | libc::MAP_FIXED,
                        -1,
                        0,
                    )
                };
                if p != libc::MAP_FAILED {
                    s.faulted.store(true, Ordering::Release);
                    return;
                }
            }
        }
        // Not ours: what would have happened without this handler.
        match PREVIOUS.get().copied().flatten() {
            Some(prev)
                if prev.sa_sigaction != libc::SIG_DFL && prev.sa_sigaction != libc::SIG_IGN =>
            {
                // SAFETY: the previous handler, called as it was installed.
                unsafe {
                    if prev.sa_flags & libc::SA_SIGINFO != 0 {
                        let f: extern "C" fn(libc::c_int, *mut libc::siginfo_t, *mut libc::c_void) =
                            std::mem::transmute(prev.sa_sigaction);
                        f(sig, info, ctx);
                    } else {
                        let f: extern "C" fn(libc::c_int) = std::mem::transmute(prev.sa_sigaction);
                        f(sig);
                    }
                }
            }
            _ => {
                // SAFETY: restores the default action; returning re-runs the faulting
                // access, which then ends the process as it would have.
                unsafe {
                    let mut dfl: libc::sigaction = std::mem::zeroed();
                    dfl.sa_sigaction = libc::SIG_DFL;
                    libc::sigaction(libc::SIGBUS, &dfl, std::ptr::null_mut());
                }
            }
        }
    }
}

/// No guard on this platform: a truncated mapped file raises `SIGBUS` as it always did.
#[cfg(not(any(target_os = "linux", target_os = "android")))]
mod guard {
    pub(super) fn register(_start: usize, _len: usize) -> Option<usize> {
        None
    }
    pub(super) fn faulted(_i: usize) -> bool {
        false
    }
    pub(super) fn unregister(_i: usize) {}
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
