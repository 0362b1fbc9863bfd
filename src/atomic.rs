//! The output layer: every file a command writes is planned, checked, staged and put in
//! place here, so a failure or a signal never leaves a half-written, partial or stray
//! result, and never destroys a file the command does not own.
//!
//! # Plan, stage, commit
//!
//! ```no_run
//! # fn main() -> Result<(), brdf_basis::error::OutputError> {
//! use brdf_basis::atomic::OutputPlan;
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
/// it, then exit. A commit in progress is finished first.
#[doc(hidden)]
pub fn remove_pending() {
    ABORTING.store(true, Ordering::SeqCst);
    let _commit = lock(&COMMIT);
    let v = std::mem::take(&mut *lock(&PENDING));
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
    r
}

// ---------------------------------------------------------------------------------------
// Checks.
// ---------------------------------------------------------------------------------------

/// What an existing path is, for messages.
fn kind_of(meta: &std::fs::Metadata) -> &'static str {
    let t = meta.file_type();
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_char_device() {
            return "a character device";
        }
        if t.is_block_device() {
            return "a block device";
        }
        if t.is_fifo() {
            return "a FIFO";
        }
        if t.is_socket() {
            return "a socket";
        }
    }
    if t.is_symlink() {
        "a symbolic link"
    } else if t.is_dir() {
        "a directory"
    } else if t.is_file() {
        "a regular file"
    } else {
        "not a regular file"
    }
}

/// The existing thing at `path` a file output may not replace (`None`: missing or a
/// regular file).
fn not_replaceable(path: &Path, flag: &str) -> Option<OutputError> {
    let meta = std::fs::symlink_metadata(path).ok()?;
    let t = meta.file_type();
    if t.is_file() {
        return None;
    }
    Some(refused(
        path,
        if t.is_dir() {
            format!("{flag} is a directory; give a file name")
        } else if t.is_symlink() {
            format!("{flag} is a symbolic link; outputs are never written through a link (give the file itself or a new name)")
        } else {
            format!(
                "{flag} exists and is {}, not a regular file; give a file name",
                kind_of(&meta)
            )
        },
    ))
}

/// Checks, before any long computation, that `path` can later be written as an output
/// file: not empty, not an existing directory, device, FIFO, socket or symbolic link, and
/// its parent directory exists. `what` names the flag in the message (e.g. `--out`).
/// Prefer [`OutputPlan`], which also refuses inputs and duplicates and proves the parent
/// writable.
pub fn check_output_path(path: &Path, what: &str) -> Result<(), OutputError> {
    if path.as_os_str().is_empty() {
        return Err(refused(path, format!("{what}: empty path")));
    }
    if let Some(e) = not_replaceable(path, what) {
        return Err(e);
    }
    parent_is_dir(path, what)
}

/// Checks that the directory `path` is in exists (`flag` names the flag in the message).
fn parent_is_dir(path: &Path, flag: &str) -> Result<(), OutputError> {
    let parent = parent_of(path);
    match std::fs::metadata(&parent) {
        Ok(m) if m.is_dir() => Ok(()),
        Ok(_) => Err(refused(
            path,
            format!("{flag}: {} is not a directory", parent.display()),
        )),
        Err(_) => Err(refused(
            path,
            format!("{flag}: the directory {} does not exist", parent.display()),
        )),
    }
}

/// The directory `path` is in (`.` for a bare name).
fn parent_of(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// `path` made absolute and normalised: the canonical form of its nearest existing
/// ancestor, then the remaining components (`.` dropped, `..` applied lexically). The
/// last component is not resolved (a link is not followed), so a link and its target
/// have different keys; links are refused on their own.
fn key(path: &Path) -> PathBuf {
    let abs = if path.is_absolute() {
        path.to_path_buf()
    } else {
        std::env::current_dir()
            .unwrap_or_else(|_| PathBuf::from("/"))
            .join(path)
    };
    let mut lexical = PathBuf::new();
    for c in abs.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                lexical.pop();
            }
            other => lexical.push(other),
        }
    }
    let name = lexical.file_name().map(|n| n.to_os_string());
    let mut base = lexical.parent().map(Path::to_path_buf);
    let mut rest = Vec::new();
    if let Some(n) = name {
        rest.push(n);
    }
    while let Some(b) = base {
        if let Ok(c) = b.canonicalize() {
            let mut out = c;
            for r in rest.iter().rev() {
                out.push(r);
            }
            return out;
        }
        if let Some(n) = b.file_name() {
            rest.push(n.to_os_string());
        }
        base = b.parent().map(Path::to_path_buf);
    }
    lexical
}

/// The device and inode of an existing file (a hard link is the same file).
fn file_id(path: &Path) -> Option<(u64, u64)> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        let m = std::fs::metadata(path).ok()?;
        Some((m.dev(), m.ino()))
    }
    #[cfg(not(unix))]
    {
        let _ = path;
        None
    }
}

// ---------------------------------------------------------------------------------------
// The plan.
// ---------------------------------------------------------------------------------------

/// Tells the entries of an owned tree (by file name) from any other file.
pub type Owns = fn(&str) -> bool;

#[derive(Debug, Clone)]
struct Input {
    /// What it is, for messages (`collection`, `tile`, ...).
    noun: String,
    shown: PathBuf,
    key: PathBuf,
    canonical: Option<PathBuf>,
    id: Option<(u64, u64)>,
    dir: bool,
}

#[derive(Debug, Clone, PartialEq)]
enum Kind {
    File,
    Dir,
    Remove,
    /// A wholly owned directory; `exists` when it was there at planning.
    Tree {
        exists: bool,
    },
}

#[derive(Debug, Clone)]
struct Planned {
    path: PathBuf,
    key: PathBuf,
    flag: String,
    kind: Kind,
}

/// Every output path of one command, checked before any work (see the
/// [module docs](self)); [`into_set`](Self::into_set) turns it into the [`OutputSet`]
/// that stages and commits them.
#[derive(Debug, Default)]
pub struct OutputPlan {
    inputs: Vec<Input>,
    planned: Vec<Planned>,
    /// Tree predicates, by index in `planned`.
    trees: Vec<(usize, Owns)>,
}

impl OutputPlan {
    /// A plan for a command reading `inputs` (files or directories; a `.npy` brings its
    /// `.names.json` sidecar).
    pub fn new(inputs: &[PathBuf]) -> Self {
        let mut plan = OutputPlan::default();
        for i in inputs {
            plan.input(i);
        }
        plan
    }

    /// Adds an input collection the outputs must not replace.
    pub fn input(&mut self, path: &Path) -> &mut Self {
        self.input_named(path, "collection")
    }

    /// Adds an input the outputs must not replace, called `noun` in messages (e.g.
    /// `tile`, `fit file`, `distance matrix`); a `.npy` brings its sidecar.
    pub fn input_named(&mut self, path: &Path, noun: &str) -> &mut Self {
        let mut add = |p: &Path, noun: String| {
            self.inputs.push(Input {
                noun,
                shown: p.to_path_buf(),
                key: key(p),
                canonical: p.canonicalize().ok(),
                id: file_id(p),
                dir: p.is_dir(),
            })
        };
        add(path, noun.to_string());
        if path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("npy"))
        {
            add(
                &path.with_extension("names.json"),
                format!("{noun}'s sidecar"),
            );
        }
        self
    }

    /// Refuses `path` (key `k`) when it names an input.
    fn check_input(&self, path: &Path, k: &Path, flag: &str) -> Result<(), OutputError> {
        let id = file_id(path);
        let out_parent = k.parent();
        for i in &self.inputs {
            let same = i.key == k
                || i.canonical.as_deref() == Some(k)
                || (id.is_some() && id == i.id && !i.dir);
            if same {
                return Err(refused(
                    path,
                    format!(
                        "{flag} would overwrite the input {}{} {}",
                        i.noun,
                        if i.dir { " directory" } else { "" },
                        i.shown.display()
                    ),
                ));
            }
            // A directory collection reads every `.binary` file in it.
            let in_dir = i.dir
                && out_parent.is_some_and(|d| Some(d) == i.canonical.as_deref() || d == i.key)
                && k.extension().is_some_and(|e| e == "binary");
            if in_dir {
                return Err(refused(
                    path,
                    format!(
                        "{flag} would write a .binary into the input collection directory {} (replacing or adding a material)",
                        i.shown.display()
                    ),
                ));
            }
        }
        Ok(())
    }

    /// Refuses a second output on the same path, or an output inside a planned tree.
    fn check_duplicate(&self, path: &Path, k: &Path, flag: &str) -> Result<(), OutputError> {
        for p in &self.planned {
            if p.key == k {
                return Err(refused(
                    path,
                    format!(
                        "{flag}: the same file is given for two outputs ({} and {flag})",
                        p.flag
                    ),
                ));
            }
        }
        Ok(())
    }

    fn is_dir_kind(&self, k: &Path) -> bool {
        self.planned
            .iter()
            .any(|p| p.key == k && p.kind == Kind::Dir)
    }

    /// The common checks of a path: not empty, named, not an input, not planned twice;
    /// returns its key.
    fn common(&self, path: &Path, flag: &str) -> Result<PathBuf, OutputError> {
        if path.as_os_str().is_empty() {
            return Err(refused(path, format!("{flag}: empty path")));
        }
        if matches!(
            path.components().next_back(),
            Some(Component::ParentDir) | None
        ) {
            return Err(refused(path, format!("{flag}: give a name, not `..`")));
        }
        let k = key(path);
        self.check_input(path, &k, flag)?;
        self.check_duplicate(path, &k, flag)?;
        Ok(k)
    }

    /// Checks that the parent of `path` exists as a directory or is a planned directory.
    fn check_parent(&self, path: &Path, k: &Path, flag: &str) -> Result<(), OutputError> {
        if k.parent().is_some_and(|kp| self.is_dir_kind(kp)) {
            return Ok(());
        }
        parent_is_dir(path, flag)
    }

    /// A file the user named (see the [module docs](self)).
    pub fn file(&mut self, path: &Path, flag: &str) -> Result<(), OutputError> {
        self.push_file(path, flag, Kind::File)
    }

    fn push_file(&mut self, path: &Path, flag: &str, kind: Kind) -> Result<(), OutputError> {
        let k = self.common(path, flag)?;
        if let Some(e) = not_replaceable(path, flag) {
            return Err(e);
        }
        self.check_parent(path, &k, flag)?;
        self.planned.push(Planned {
            path: path.to_path_buf(),
            key: k,
            flag: flag.to_string(),
            kind,
        });
        Ok(())
    }

    /// A file the command writes on its own (a sidecar, an index): as [`file`](Self::file),
    /// and an existing file is replaced only when `owns(path)` is true; otherwise refused
    /// as not being a `what` (e.g. "matrix sidecar written by brdf-basis").
    pub fn owned_file(
        &mut self,
        path: &Path,
        flag: &str,
        what: &str,
        owns: impl Fn(&Path) -> bool,
    ) -> Result<(), OutputError> {
        if std::fs::symlink_metadata(path).is_ok_and(|m| m.is_file()) && !owns(path) {
            return Err(refused(
                path,
                format!("{flag}: would replace this file, which is not a {what}; move it away or choose another name"),
            ));
        }
        self.file(path, flag)
    }

    /// A stale file of the command's own (e.g. an export an earlier run listed and this
    /// one does not write), removed at commit. A missing path is ignored; anything but a
    /// regular file is refused.
    pub fn remove(&mut self, path: &Path, flag: &str) -> Result<(), OutputError> {
        match std::fs::symlink_metadata(path) {
            Err(_) => Ok(()),
            Ok(m) if m.is_file() => self.push_file(path, flag, Kind::Remove),
            Ok(m) => Err(refused(
                path,
                format!(
                    "{flag}: an earlier output here is now {}; remove it by hand",
                    kind_of(&m)
                ),
            )),
        }
    }

    /// A directory files are written into (see the [module docs](self)).
    pub fn dir(&mut self, path: &Path, flag: &str) -> Result<(), OutputError> {
        let k = self.common(path, flag)?;
        self.check_dir_target(path, &k, flag)?;
        self.planned.push(Planned {
            path: path.to_path_buf(),
            key: k,
            flag: flag.to_string(),
            kind: Kind::Dir,
        });
        Ok(())
    }

    /// A directory: a real directory, or missing with an existing parent.
    fn check_dir_target(&self, path: &Path, k: &Path, flag: &str) -> Result<bool, OutputError> {
        match std::fs::symlink_metadata(path) {
            Ok(m) if m.is_dir() => Ok(true),
            Ok(m) if m.file_type().is_symlink() => Err(refused(
                path,
                format!("{flag} is a symbolic link; give the directory itself or a new name"),
            )),
            Ok(m) => Err(refused(
                path,
                format!(
                    "{flag} exists and is {}, not a directory; give a directory name",
                    kind_of(&m)
                ),
            )),
            Err(_) => {
                self.check_parent(path, k, flag)?;
                Ok(false)
            }
        }
    }

    /// A directory the command owns as a whole (see the [module docs](self)): `owns`
    /// tells its entries (by file name) from anything else.
    pub fn tree(
        &mut self,
        path: &Path,
        flag: &str,
        force: bool,
        owns: Owns,
    ) -> Result<(), OutputError> {
        let k = self.common(path, flag)?;
        if let Some(i) = self.inputs.iter().find(|i| {
            i.key.starts_with(&k) || i.canonical.as_ref().is_some_and(|c| c.starts_with(&k))
        }) {
            return Err(refused(
                path,
                format!("{flag} holds the input {}", i.shown.display()),
            ));
        }
        let exists = self.check_dir_target(path, &k, flag)?;
        if exists {
            // A run killed by SIGKILL left its staging root in the tree: not an entry of
            // an earlier result, and removable (only those of dead processes).
            remove_stale_stages(path);
            let entries: Vec<String> = std::fs::read_dir(path)
                .map_err(|e| io_err(path, e))?
                .map(|e| e.map(|e| e.file_name().to_string_lossy().into_owned()))
                .collect::<Result<_, _>>()
                .map_err(|e| io_err(path, e))?;
            if !entries.is_empty() && !force {
                return Err(refused(
                    path,
                    format!(
                        "{flag}: the directory is not empty ({} entries); choose a new directory, or add --force to replace the files of an earlier run",
                        entries.len()
                    ),
                ));
            }
            if let Some(e) = entries.iter().find(|e| !owns(e)) {
                return Err(refused(
                    path,
                    format!(
                        "{flag}: --force replaces only the files this command writes, and `{e}` is not one of them; remove it or choose another directory"
                    ),
                ));
            }
        }
        self.trees.push((self.planned.len(), owns));
        self.planned.push(Planned {
            path: path.to_path_buf(),
            key: k,
            flag: flag.to_string(),
            kind: Kind::Tree { exists },
        });
        Ok(())
    }

    /// Proves every directory that will be written into writable (a probe file created
    /// and removed) and returns the set that stages the planned outputs.
    pub fn into_set(self) -> Result<OutputSet, OutputError> {
        let mut probed: Vec<PathBuf> = Vec::new();
        for p in &self.planned {
            let (dir, shown) = match &p.kind {
                Kind::Tree { exists: true } => (p.path.clone(), p.path.clone()),
                Kind::Dir | Kind::Tree { exists: false } if !p.path.is_dir() => {
                    (parent_of(&p.path), p.path.clone())
                }
                Kind::Dir => (p.path.clone(), p.path.clone()),
                _ => {
                    let parent = parent_of(&p.path);
                    if !parent.is_dir() {
                        continue; // a planned directory, probed through its own entry
                    }
                    (parent, p.path.clone())
                }
            };
            let dk = key(&dir);
            if probed.contains(&dk) {
                continue;
            }
            probe(&dir).map_err(|e| {
                refused(
                    &shown,
                    format!(
                        "{}: cannot write in {}: {e}",
                        p.flag,
                        if dir == Path::new(".") {
                            "the current directory".to_string()
                        } else {
                            dir.display().to_string()
                        }
                    ),
                )
            })?;
            probed.push(dk);
        }
        Ok(OutputSet {
            plan: Some(self),
            scratch: Vec::new(),
            staged: Vec::new(),
            trees: Vec::new(),
            created: Vec::new(),
        })
    }
}

/// Creates and removes a probe file in `dir`.
fn probe(dir: &Path) -> std::io::Result<()> {
    let p = dir.join(format!(
        ".brdf-basis-probe-{}-{}",
        std::process::id(),
        SEQ.fetch_add(1, Ordering::Relaxed)
    ));
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&p)?;
    std::fs::remove_file(&p)
}

/// Name prefix of a staging directory: `.brdf-basis-stage-PID-N`.
const STAGE_PREFIX: &str = ".brdf-basis-stage-";

/// The process id in a staging directory's name `.brdf-basis-stage-PID-N` (both decimal).
fn stage_pid(name: &str) -> Option<u32> {
    let (pid, seq) = name.strip_prefix(STAGE_PREFIX)?.split_once('-')?;
    let digits = |t: &str| !t.is_empty() && t.bytes().all(|b| b.is_ascii_digit());
    (digits(pid) && digits(seq))
        .then(|| pid.parse().ok())
        .flatten()
}

/// Removes, best effort, the staging directories in `dir` that a killed run left behind
/// (SIGKILL leaves no chance to clean up): only entries named exactly
/// `.brdf-basis-stage-PID-N` that are directories (not links), owned by this user, of a
/// process that no longer exists (`kill(PID, 0)` fails with `ESRCH`; another user's live
/// process answers `EPERM` and is kept). Errors are ignored: a directory that cannot be
/// read or removed is left as it is.
#[cfg(unix)]
fn remove_stale_stages(dir: &Path) {
    use std::os::unix::fs::MetadataExt;
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    // SAFETY: geteuid has no preconditions and cannot fail.
    let uid = unsafe { libc::geteuid() };
    for e in entries.flatten() {
        let name = e.file_name();
        let Some(pid) = name.to_str().and_then(stage_pid) else {
            continue;
        };
        if pid == std::process::id() || pid == 0 || pid > i32::MAX as u32 {
            continue;
        }
        let path = e.path();
        let Ok(m) = std::fs::symlink_metadata(&path) else {
            continue;
        };
        if !m.is_dir() || m.uid() != uid {
            continue;
        }
        // SAFETY: signal 0 only checks that the process exists; nothing is sent.
        let dead = unsafe { libc::kill(pid as libc::pid_t, 0) } != 0
            && std::io::Error::last_os_error().raw_os_error() == Some(libc::ESRCH);
        if dead {
            let _ = std::fs::remove_dir_all(&path);
        }
    }
}

#[cfg(not(unix))]
fn remove_stale_stages(_dir: &Path) {}

// ---------------------------------------------------------------------------------------
// The set.
// ---------------------------------------------------------------------------------------

/// Outputs staged together and put in place by [`commit`](Self::commit); dropped
/// uncommitted, it removes what it staged and the directories it created.
#[derive(Debug, Default)]
pub struct OutputSet {
    /// `None`: a set without a plan ([`OutputSet::new`]).
    plan: Option<OutputPlan>,
    /// Staging directory of each destination directory `(dest, scratch)`.
    scratch: Vec<(PathBuf, PathBuf)>,
    /// `(staged, target)`.
    staged: Vec<(PathBuf, PathBuf)>,
    /// `(target, staging root, owns)` of trees.
    trees: Vec<(PathBuf, PathBuf, Owns)>,
    created: Vec<PathBuf>,
}

impl OutputSet {
    /// A set without a plan: each staged path is checked when staged
    /// ([`check_output_path`]). Prefer [`OutputPlan`], which checks before the work.
    pub fn new() -> Self {
        Self::default()
    }

    /// The planned entry of `path`, if planned.
    fn planned(&self, path: &Path) -> Option<&Planned> {
        let k = key(path);
        self.plan.as_ref()?.planned.iter().find(|p| p.key == k)
    }

    /// Creates `dir` if it is missing (its parent must exist), remembering it.
    fn ensure_dir(&mut self, dir: &Path) -> Result<(), OutputError> {
        refuse_if_interrupted(dir)?;
        if dir.is_dir() {
            return Ok(());
        }
        std::fs::create_dir(dir).map_err(|e| io_err(dir, e))?;
        register(Pending::Created(dir.to_path_buf()));
        self.created.push(dir.to_path_buf());
        Ok(())
    }

    /// The private staging directory inside `dest` (created on first use).
    fn scratch_in(&mut self, dest: &Path) -> Result<PathBuf, OutputError> {
        let dk = key(dest);
        if let Some((_, s)) = self.scratch.iter().find(|(d, _)| key(d) == dk) {
            return Ok(s.clone());
        }
        self.ensure_dir(dest)?;
        refuse_if_interrupted(dest)?;
        remove_stale_stages(dest);
        let s = dest.join(format!(
            "{STAGE_PREFIX}{}-{}",
            std::process::id(),
            SEQ.fetch_add(1, Ordering::Relaxed)
        ));
        let mut b = std::fs::DirBuilder::new();
        #[cfg(unix)]
        std::os::unix::fs::DirBuilderExt::mode(&mut b, 0o700);
        register(Pending::Scratch(s.clone()));
        if let Err(e) = b.create(&s) {
            unregister(&Pending::Scratch(s.clone()));
            return Err(io_err(dest, e));
        }
        self.scratch.push((dest.to_path_buf(), s.clone()));
        Ok(s)
    }

    /// Marks the planned file `path` as staged and returns where to write it: the same
    /// file name in a private staging directory beside it (so a `.npy` written there gets
    /// its sidecar staged beside it, under the sidecar's own name). Write it with any
    /// writer; [`commit`](Self::commit) requires it to exist.
    pub fn stage_path(&mut self, path: &Path) -> Result<PathBuf, OutputError> {
        match self.planned(path).map(|p| p.kind.clone()) {
            Some(Kind::File) => {}
            Some(_) => {
                return Err(refused(
                    path,
                    "staged, but planned as a directory or a removal".into(),
                ))
            }
            None if self.plan.is_some() => {
                return Err(refused(
                    path,
                    "an output that was not checked before the work (not in the output plan)"
                        .into(),
                ))
            }
            None => check_output_path(path, "output")?,
        }
        if self.staged.iter().any(|(_, t)| key(t) == key(path)) {
            return Err(refused(path, "the same file is written twice".into()));
        }
        let name = path
            .file_name()
            .ok_or_else(|| refused(path, "no file name".into()))?;
        let tmp = self.scratch_in(&parent_of(path))?.join(name);
        self.staged.push((tmp.clone(), path.to_path_buf()));
        Ok(tmp)
    }

    /// Stages `path`: `fill` writes its content into its staging location.
    pub fn stage<F>(&mut self, path: &Path, fill: F) -> Result<(), OutputError>
    where
        F: FnOnce(&mut dyn Write) -> std::io::Result<()>,
    {
        let tmp = self.stage_path(path)?;
        let r = write_file(&tmp, path, fill);
        if r.is_err() {
            self.staged.pop();
        }
        r
    }

    /// The staging root of the planned tree `path`: write the tree's content beneath it
    /// with any writer; [`commit`](Self::commit) moves it into `path`.
    pub fn tree_root(&mut self, path: &Path) -> Result<PathBuf, OutputError> {
        let owns = {
            let plan = self.plan.as_ref();
            let k = key(path);
            plan.and_then(|pl| {
                pl.trees
                    .iter()
                    .find(|(i, _)| pl.planned[*i].key == k)
                    .map(|(_, f)| *f)
            })
        }
        .ok_or_else(|| refused(path, "not planned as an output directory".into()))?;
        if let Some((_, r, _)) = self.trees.iter().find(|(t, _, _)| key(t) == key(path)) {
            return Ok(r.clone());
        }
        let root = self.scratch_in(path)?;
        self.trees.push((path.to_path_buf(), root.clone(), owns));
        Ok(root)
    }

    /// Puts every staged output in place, removes the planned stale files and the
    /// staging directories. All or nothing: replaced files are kept aside until every
    /// rename succeeded and put back when one fails.
    pub fn commit(mut self) -> Result<(), OutputError> {
        let _commit = lock(&COMMIT);
        // Everything staged exists, and no target turned into something else meanwhile.
        for (tmp, target) in &self.staged {
            if std::fs::symlink_metadata(tmp).is_err() {
                return Err(refused(target, "was not written".into()));
            }
            if let Some(e) = not_replaceable(target, "output") {
                return Err(e);
            }
        }
        let mut moves: Vec<(PathBuf, PathBuf)> = Vec::new(); // (from, to) done
        let result = self.commit_moves(&mut moves);
        if result.is_err() {
            for (from, to) in moves.iter().rev() {
                let _ = std::fs::rename(to, from);
            }
            return result;
        }
        for (_, s) in std::mem::take(&mut self.scratch) {
            remove_tree(&s);
            unregister(&Pending::Scratch(s));
        }
        for d in std::mem::take(&mut self.created) {
            unregister(&Pending::Created(d));
        }
        Ok(())
    }

    /// The renames of [`commit`](Self::commit), each recorded in `moves` (for a rollback).
    fn commit_moves(&mut self, moves: &mut Vec<(PathBuf, PathBuf)>) -> Result<(), OutputError> {
        let mv = |from: &Path, to: &Path, moves: &mut Vec<(PathBuf, PathBuf)>| {
            std::fs::rename(from, to).map_err(|e| io_err(to, e))?;
            moves.push((from.to_path_buf(), to.to_path_buf()));
            Ok::<(), OutputError>(())
        };
        // Old files (replaced or stale) aside first, into a backup directory beside them.
        let removals: Vec<PathBuf> = self
            .plan
            .as_ref()
            .map(|p| {
                p.planned
                    .iter()
                    .filter(|p| p.kind == Kind::Remove)
                    .map(|p| p.path.clone())
                    .collect()
            })
            .unwrap_or_default();
        let staged = self.staged.clone();
        let mut olds: Vec<PathBuf> = staged
            .iter()
            .map(|(_, t)| t.clone())
            .filter(|t| std::fs::symlink_metadata(t).is_ok())
            .collect();
        olds.extend(removals.into_iter().filter(|p| p.is_file()));
        for (i, old) in olds.iter().enumerate() {
            let backup = self.scratch_in(&parent_of(old))?.join(format!(".old-{i}"));
            mv(old, &backup, moves)?;
        }
        // Trees: the earlier run's entries aside, then the new ones in.
        for (target, root, owns) in self.trees.clone() {
            let backup = self.scratch_in(&target)?.join(".old");
            std::fs::create_dir(&backup).map_err(|e| io_err(&target, e))?;
            for e in std::fs::read_dir(&target).map_err(|e| io_err(&target, e))? {
                let e = e.map_err(|e| io_err(&target, e))?;
                let name = e.file_name();
                let s = name.to_string_lossy();
                if owns(&s) && !s.starts_with(".brdf-basis-") {
                    mv(&e.path(), &backup.join(&name), moves)?;
                }
            }
            for e in std::fs::read_dir(&root).map_err(|e| io_err(&root, e))? {
                let e = e.map_err(|e| io_err(&root, e))?;
                let name = e.file_name();
                if name == ".old" {
                    continue;
                }
                let to = target.join(&name);
                if std::fs::symlink_metadata(&to).is_ok() {
                    return Err(refused(
                        &to,
                        "appeared while the command ran; not replaced".into(),
                    ));
                }
                mv(&e.path(), &to, moves)?;
            }
        }
        for (tmp, target) in &staged {
            mv(tmp, target, moves)?;
        }
        Ok(())
    }
}

impl Drop for OutputSet {
    fn drop(&mut self) {
        for (_, s) in self.scratch.drain(..).rev() {
            remove_tree(&s);
            unregister(&Pending::Scratch(s));
        }
        for d in self.created.drain(..).rev() {
            let _ = std::fs::remove_dir(&d);
            unregister(&Pending::Created(d));
        }
    }
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
