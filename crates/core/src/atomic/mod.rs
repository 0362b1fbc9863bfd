//! The output layer: every file a command writes is planned, checked, staged and put in
//! place here, so a failure or a signal never leaves a half-written, partial or stray
//! result, and never destroys a file the command does not own.
//!
//! # Plan, stage, commit
//!
//! ```no_run
//! # fn main() -> Result<(), brdf_basis_core::error::OutputError> {
//! use brdf_basis_core::atomic::OutputPlan;
//! use std::path::{Path, PathBuf};
//! let inputs = vec![PathBuf::from("coll.csv")];
//! // 1. Before any work: every output path of the command, each with the flag that
//! //    named it (used in every message).
//! let mut plan = OutputPlan::new(&inputs);
//! plan.file(Path::new("fits.json"), "--json")?;
//! plan.dir(Path::new("fitted"), "--export")?;
//! plan.file(Path::new("fitted/gold.binary"), "--export")?;
//! let mut set = plan.into_set()?; // parents proven writable (probe file)
//! // 2. The work; then stage every file.
//! set.stage(Path::new("fits.json"), |w| w.write_all(b"{}\n"))?;
//! let tmp = set.stage_path(Path::new("fitted/gold.binary"))?; // for writers taking a path
//! # let _ = tmp;
//! // 3. All in place together (or none: dropping the set removes what it staged).
//! set.commit()?;
//! # Ok(()) }
//! ```
//!
//! * [`OutputPlan::new`]`(&inputs)`: the command's input paths (collections, `--fit`
//!   JSON, `--distances`, tiles, ...). A `.npy` input brings its `.names.json` sidecar; an
//!   input directory brings every `.binary` in it. [`OutputPlan::input`] adds more.
//! * [`OutputPlan::file`]`(path, flag)`: a file the user named. Refused: an empty path, an
//!   existing directory, device, FIFO or socket, a symbolic link, an input (any spelling:
//!   `./x`, `a/../x`, a hard link), a `.binary` inside an input directory, the same path
//!   as another output, a parent that does not exist (and is not a planned directory).
//!   An existing regular file is replaced.
//! * [`OutputPlan::owned_file`]`(path, flag, what, owns)`: a file the command writes
//!   without the user naming it (a sidecar, an index): as `file`, and an existing file is
//!   replaced only when `owns(path)` says it is one of ours (`what` names it in the
//!   refusal).
//! * [`OutputPlan::dir`]`(path, flag)`: a directory files are written into: it exists, or
//!   its parent does and it is created at staging (removed again if the set is not
//!   committed). What else is in it is kept.
//! * [`OutputPlan::remove`]`(path, flag)`: a stale file of ours, removed at commit.
//! * [`OutputPlan::tree`]`(path, flag, force, owns)`: a directory the command owns as a
//!   whole (`reproduce --out`): missing (its parent exists) or empty; with `force`, one
//!   whose every entry `owns(name)` accepts, which the commit replaces.
//! * [`OutputPlan::into_set`]: proves every directory written into writable (creates and
//!   removes a probe file) and returns the [`OutputSet`].
//! * [`OutputSet::stage`]`(path, fill)` writes a planned file into a private staging
//!   directory beside it; [`OutputSet::stage_path`]`(path)` returns that staging location
//!   for writers that take a path (a `.npy` staged there gets its sidecar staged beside
//!   it, under the same names); [`OutputSet::tree_root`]`(path)` returns the staging root
//!   of a planned tree, where anything may be written.
//! * [`OutputSet::commit`] renames everything into place (replaced files are kept aside
//!   until all renames succeeded, and put back if one fails), removes the planned stale
//!   files, and removes the staging directories. Dropped uncommitted (an error, a
//!   panic), the set removes what it staged and the directories it created.
//!
//! Staging directories, temporary files and created directories are listed in a
//! process-wide registry, so a binary that catches SIGINT/SIGTERM/SIGHUP removes them
//! with [`remove_pending`] before it exits (`brdf-basis` does); a signal during a commit
//! waits for the commit to finish. SIGKILL leaves its staging directories behind: the next
//! run that stages into the same directory removes those of dead processes (see
//! `remove_stale_stages`).
//!
//! [`write_atomic`] writes one file alone (a temporary sibling renamed over it); the
//! writers in `io` and `merl` use it, and write into a staging directory when given a
//! path from [`OutputSet::stage_path`].
//!
//! This module sits at the bottom of the crate (it uses only [`crate::error`]).

use crate::error::OutputError;
use std::io::Write;
use std::path::{Component, Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Mutex, MutexGuard};

mod paths;
mod plan;
mod set;

pub(crate) use paths::check_output_path;
use paths::*;
use plan::*;
pub use plan::{OutputPlan, Owns};
pub use set::OutputSet;

// ---------------------------------------------------------------------------------------
// The process-wide registry of what is not yet in place.
// ---------------------------------------------------------------------------------------

#[derive(Debug, Clone, PartialEq)]
enum Pending {
    /// A temporary file (removed).
    File(PathBuf),
    /// A private staging directory (removed with its content).
    Scratch(PathBuf),
    /// A directory created for an output (removed when empty).
    Created(PathBuf),
}

static PENDING: Mutex<Vec<Pending>> = Mutex::new(Vec::new());
/// Held during a commit: a signal handler's [`remove_pending`] waits for it.
static COMMIT: Mutex<()> = Mutex::new(());
static SEQ: AtomicUsize = AtomicUsize::new(0);
/// Set by [`remove_pending`]: no file or directory is created any more.
static ABORTING: AtomicBool = AtomicBool::new(false);
/// Set when an [`OutputSet`] of this process committed (its outputs are in place).
static IN_PLACE: AtomicBool = AtomicBool::new(false);

/// What [`remove_pending`] found: what a signal handler tells the user.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[doc(hidden)]
pub struct Cleanup {
    /// Temporary files, staging directories and created directories removed.
    pub removed: usize,
    /// Whether any output of this process was already in place (committed or written
    /// outside a staging directory).
    pub in_place: bool,
}

impl Cleanup {
    /// The sentence a signal handler prints: what was removed and what stays.
    pub fn message(&self) -> &'static str {
        match (self.removed > 0, self.in_place) {
            (true, false) => "interrupted; the outputs not yet in place were removed and none was in place: nothing of this run is left",
            (true, true) => "interrupted; the outputs not yet in place were removed (those already in place stay)",
            (false, true) => "interrupted after the outputs were in place; nothing was removed",
            (false, false) => "interrupted before any output was written",
        }
    }
}

fn mark_in_place() {
    IN_PLACE.store(true, Ordering::SeqCst);
}

/// Whether `path` lies inside a staging directory not yet put in place (removed with it).
fn in_pending_scratch(path: &Path) -> bool {
    lock(&PENDING)
        .iter()
        .any(|p| matches!(p, Pending::Scratch(s) if path.starts_with(s)))
}

/// Whether [`remove_pending`] has run (a signal arrived): the process is about to exit,
/// and every later write fails.
pub fn interrupted() -> bool {
    ABORTING.load(Ordering::SeqCst)
}

fn refuse_if_interrupted(path: &Path) -> Result<(), OutputError> {
    if interrupted() {
        return Err(io_err(
            path,
            std::io::Error::other("interrupted; no more output is written"),
        ));
    }
    Ok(())
}

fn lock<T>(m: &'static Mutex<T>) -> MutexGuard<'static, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

fn register(p: Pending) {
    lock(&PENDING).push(p);
}

fn unregister(p: &Pending) {
    let mut v = lock(&PENDING);
    if let Some(i) = v.iter().rposition(|x| x == p) {
        v.remove(i);
    }
}

/// Removes every temporary file, staging directory and created (still empty) directory
/// that this process has not yet put in place, newest first. For signal handlers: call
/// it, print [`Cleanup::message`], then exit. A commit in progress is finished first (so
/// a signal at the commit leaves every output of the command in place, and says so).
#[doc(hidden)]
pub fn remove_pending() -> Cleanup {
    ABORTING.store(true, Ordering::SeqCst);
    let _commit = lock(&COMMIT);
    let v = std::mem::take(&mut *lock(&PENDING));
    let cleanup = Cleanup {
        removed: v.len(),
        in_place: IN_PLACE.load(Ordering::SeqCst),
    };
    for p in v.iter().rev() {
        match p {
            Pending::File(f) => {
                let _ = std::fs::remove_file(f);
            }
            Pending::Scratch(d) => remove_tree(d),
            Pending::Created(d) => {
                let _ = std::fs::remove_dir(d);
            }
        }
    }
    cleanup
}

/// `remove_dir_all`, retried: another thread may still be writing into it.
fn remove_tree(d: &Path) {
    for _ in 0..5 {
        match std::fs::remove_dir_all(d) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                std::thread::sleep(std::time::Duration::from_millis(2));
            }
            _ => return,
        }
    }
}

// ---------------------------------------------------------------------------------------
// One file alone.
// ---------------------------------------------------------------------------------------

fn tmp_path(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = format!(".{name}.tmp-{}", std::process::id());
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.join(tmp),
        _ => PathBuf::from(tmp),
    }
}

/// Creates `tmp` and writes `fill` into it (buffered, flushed, synced); on error `tmp`
/// is removed and the error names `shown`.
fn write_file<F>(tmp: &Path, shown: &Path, fill: F) -> Result<(), OutputError>
where
    F: FnOnce(&mut dyn Write) -> std::io::Result<()>,
{
    refuse_if_interrupted(shown)?;
    let result = (|| {
        let file = std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(tmp)?;
        let mut w = std::io::BufWriter::with_capacity(1 << 20, file);
        fill(&mut w)?;
        let file = w.into_inner().map_err(|e| e.into_error())?;
        file.sync_all()
    })();
    result.map_err(|source| {
        let _ = std::fs::remove_file(tmp);
        io_err(shown, source)
    })
}

fn io_err(path: &Path, source: std::io::Error) -> OutputError {
    OutputError::Io {
        path: path.to_path_buf(),
        source,
    }
}

fn refused(path: &Path, message: String) -> OutputError {
    OutputError::Encode {
        path: path.to_path_buf(),
        message,
    }
}

/// Writes `path` atomically: `fill` writes the content into a buffered temporary sibling,
/// which is flushed, synced and renamed over `path`. On any error the temporary file is
/// removed and `path` is left as it was.
pub fn write_atomic<F>(path: &Path, fill: F) -> Result<(), OutputError>
where
    F: FnOnce(&mut dyn Write) -> std::io::Result<()>,
{
    let tmp = tmp_path(path);
    let _ = std::fs::remove_file(&tmp); // a leftover of an earlier process with this id
    let entry = Pending::File(tmp.clone());
    register(entry.clone());
    let r = write_file(&tmp, path, fill).and_then(|()| {
        std::fs::rename(&tmp, path).map_err(|e| {
            let _ = std::fs::remove_file(&tmp);
            io_err(path, e)
        })
    });
    unregister(&entry);
    if r.is_ok() && !in_pending_scratch(path) {
        mark_in_place();
    }
    r
}

#[cfg(test)]
mod tests {
    #[test]
    fn stage_names_parse_exactly() {
        assert_eq!(super::stage_pid(".brdf-basis-stage-123-4"), Some(123));
        for bad in [
            ".brdf-basis-stage-123",
            ".brdf-basis-stage--4",
            ".brdf-basis-stage-12a-4",
            ".brdf-basis-stage-1-4-5",
            ".brdf-basis-stage-1-",
            "brdf-basis-stage-1-4",
            ".brdf-basis-probe-1-4",
        ] {
            assert_eq!(super::stage_pid(bad), None, "{bad}");
        }
    }

    use super::*;

    fn names(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn a_plan_stages_and_commits_together_and_drops_cleanly() {
        let d = tempfile::tempdir().unwrap();
        let a = d.path().join("a.json");
        let b = d.path().join("sub/b.bin");
        std::fs::write(&a, "old").unwrap();
        let mut plan = OutputPlan::new(&[]);
        plan.file(&a, "--json").unwrap();
        plan.dir(&d.path().join("sub"), "--export").unwrap();
        plan.file(&b, "--export").unwrap();
        let mut set = plan.into_set().unwrap();
        set.stage(&a, |w| w.write_all(b"new")).unwrap();
        set.stage(&b, |w| w.write_all(b"b")).unwrap();
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "old");
        drop(set);
        assert_eq!(names(d.path()), ["a.json"]);
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "old");

        let mut plan = OutputPlan::new(&[]);
        plan.file(&a, "--json").unwrap();
        plan.dir(&d.path().join("sub"), "--export").unwrap();
        plan.file(&b, "--export").unwrap();
        let mut set = plan.into_set().unwrap();
        set.stage(&a, |w| w.write_all(b"new")).unwrap();
        set.stage(&b, |w| w.write_all(b"b")).unwrap();
        set.commit().unwrap();
        assert_eq!(names(d.path()), ["a.json", "sub"]);
        assert_eq!(names(&d.path().join("sub")), ["b.bin"]);
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "new");
    }

    #[test]
    fn plans_refuse_inputs_duplicates_links_and_missing_parents() {
        let d = tempfile::tempdir().unwrap();
        let input = d.path().join("c.csv");
        std::fs::write(&input, "x").unwrap();
        let mut plan = OutputPlan::new(std::slice::from_ref(&input));
        let spelled = d.path().join("sub/../c.csv");
        assert!(plan.file(&spelled, "--out").is_err());
        #[cfg(unix)]
        {
            std::fs::hard_link(&input, d.path().join("h.csv")).unwrap();
            assert!(plan.file(&d.path().join("h.csv"), "--out").is_err());
            std::os::unix::fs::symlink(&input, d.path().join("l.csv")).unwrap();
            let e = plan.file(&d.path().join("l.csv"), "--out").unwrap_err();
            assert!(e.to_string().contains("would overwrite the input"), "{e}");
            std::fs::write(d.path().join("other"), "y").unwrap();
            std::os::unix::fs::symlink("other", d.path().join("l2.csv")).unwrap();
            let e = plan.file(&d.path().join("l2.csv"), "--out").unwrap_err();
            assert!(e.to_string().contains("symbolic link"), "{e}");
        }
        assert!(plan.file(&d.path().join("no/x.json"), "--json").is_err());
        plan.file(&d.path().join("s.json"), "--json").unwrap();
        let e = plan
            .file(&d.path().join("./s.json"), "--markdown")
            .unwrap_err();
        assert!(e.to_string().contains("--json") && e.to_string().contains("--markdown"));
        // An owned file that is not ours is refused.
        std::fs::write(d.path().join("x.names.json"), "mine").unwrap();
        let e = plan
            .owned_file(&d.path().join("x.names.json"), "--out", "sidecar", |_| {
                false
            })
            .unwrap_err();
        assert!(e.to_string().contains("not a sidecar"), "{e}");
    }

    #[test]
    fn a_tree_replaces_an_earlier_run_and_keeps_it_when_dropped() {
        let d = tempfile::tempdir().unwrap();
        let out = d.path().join("r");
        std::fs::create_dir(&out).unwrap();
        std::fs::write(out.join("report.md"), "old").unwrap();
        fn ours(n: &str) -> bool {
            n == "report.md" || n == "figures"
        }
        let mut plan = OutputPlan::new(&[]);
        assert!(plan.tree(&out, "--out", false, ours).is_err());
        plan.tree(&out, "--out", true, ours).unwrap();
        let mut set = plan.into_set().unwrap();
        let root = set.tree_root(&out).unwrap();
        std::fs::create_dir(root.join("figures")).unwrap();
        std::fs::write(root.join("report.md"), "new").unwrap();
        drop(set);
        assert_eq!(names(&out), ["report.md"]);
        assert_eq!(
            std::fs::read_to_string(out.join("report.md")).unwrap(),
            "old"
        );
        let mut plan = OutputPlan::new(&[]);
        plan.tree(&out, "--out", true, ours).unwrap();
        let mut set = plan.into_set().unwrap();
        let root = set.tree_root(&out).unwrap();
        std::fs::create_dir(root.join("figures")).unwrap();
        std::fs::write(root.join("report.md"), "new").unwrap();
        set.commit().unwrap();
        assert_eq!(names(&out), ["figures", "report.md"]);
        assert_eq!(
            std::fs::read_to_string(out.join("report.md")).unwrap(),
            "new"
        );
        // A missing tree is created, and removed again when dropped.
        let fresh = d.path().join("fresh");
        let mut plan = OutputPlan::new(&[]);
        plan.tree(&fresh, "--out", false, ours).unwrap();
        let mut set = plan.into_set().unwrap();
        let root = set.tree_root(&fresh).unwrap();
        std::fs::write(root.join("report.md"), "x").unwrap();
        drop(set);
        assert!(!fresh.exists());
    }
}
