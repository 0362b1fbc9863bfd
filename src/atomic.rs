//! Atomic file output: write to a temporary file beside the target, then rename over it,
//! so a failure never leaves a half-written file and never destroys an existing one.
//!
//! [`OutputSet`] extends this to several files written by one command: every file is
//! staged as a temporary sibling and all are renamed into place only at
//! [`OutputSet::commit`]; dropping the set uncommitted removes the staged files and the
//! directories it created. Temporary files are listed in a process-wide registry, so a
//! binary that catches SIGINT/SIGTERM can remove them with [`remove_pending`] before it
//! exits (`brdf-basis` does).
//!
//! This module sits at the bottom of the crate (it uses only [`crate::error`]), so the
//! `.binary` writer in `merl` and the writers in `io` can share it.

use crate::error::OutputError;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// Temporary files and directories created by this process and not yet renamed or
/// removed (see [`remove_pending`]).
static PENDING: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn pending() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    PENDING.lock().unwrap_or_else(|e| e.into_inner())
}

fn register(p: &Path) {
    pending().push(p.to_path_buf());
}

fn unregister(p: &Path) {
    let mut v = pending();
    if let Some(i) = v.iter().rposition(|x| x == p) {
        v.remove(i);
    }
}

/// Removes every temporary file (and every directory an uncommitted [`OutputSet`]
/// created, when empty) that this process has not yet renamed into place. For signal
/// handlers: call it, then exit.
pub fn remove_pending() {
    let v = std::mem::take(&mut *pending());
    for p in v.iter().rev() {
        if p.is_dir() {
            let _ = std::fs::remove_dir(p);
        } else {
            let _ = std::fs::remove_file(p);
        }
    }
}

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

/// Writes `fill` into the temporary sibling of `path` (flushed and synced); returns the
/// temporary path, registered as pending. On error it is removed.
fn stage<F>(path: &Path, fill: F) -> Result<PathBuf, OutputError>
where
    F: FnOnce(&mut dyn Write) -> std::io::Result<()>,
{
    let tmp = tmp_path(path);
    register(&tmp);
    let result = (|| {
        let file = std::fs::File::create(&tmp)?;
        let mut w = std::io::BufWriter::with_capacity(1 << 20, file);
        fill(&mut w)?;
        let file = w.into_inner().map_err(|e| e.into_error())?;
        file.sync_all()
    })();
    match result {
        Ok(()) => Ok(tmp),
        Err(source) => {
            let _ = std::fs::remove_file(&tmp);
            unregister(&tmp);
            Err(OutputError::Io {
                path: path.to_path_buf(),
                source,
            })
        }
    }
}

fn rename_into_place(tmp: &Path, path: &Path) -> Result<(), OutputError> {
    let r = std::fs::rename(tmp, path);
    if r.is_err() {
        let _ = std::fs::remove_file(tmp);
    }
    unregister(tmp);
    r.map_err(|source| OutputError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// Writes `path` atomically: `fill` writes the content into a buffered temporary file,
/// which is flushed, synced and renamed over `path`. On any error the temporary file is
/// removed and `path` is left as it was.
pub fn write_atomic<F>(path: &Path, fill: F) -> Result<(), OutputError>
where
    F: FnOnce(&mut dyn Write) -> std::io::Result<()>,
{
    let tmp = stage(path, fill)?;
    rename_into_place(&tmp, path)
}

/// Checks, before any long computation, that `path` can later be written as an output
/// file: its parent directory exists and is a directory, and `path` itself is not a
/// directory. `what` names the flag in the message (e.g. `--out`).
pub fn check_output_path(path: &Path, what: &str) -> Result<(), OutputError> {
    let bad = |message: String| OutputError::Encode {
        path: path.to_path_buf(),
        message,
    };
    if path.as_os_str().is_empty() {
        return Err(bad(format!("{what}: empty path")));
    }
    if path.is_dir() {
        return Err(bad(format!("{what} is a directory; give a file name")));
    }
    if path.exists() && !path.is_file() {
        // A device, a FIFO, a socket: renaming a temporary file over it would replace it.
        return Err(bad(format!(
            "{what} exists and is not a regular file (a device, FIFO or socket); give a file name"
        )));
    }
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() && !p.is_dir() => Err(bad(format!(
            "{what}: the directory {} does not exist",
            p.display()
        ))),
        _ => Ok(()),
    }
}

/// Refuses an output path that names one of the `inputs` (the same file, through any
/// spelling), which the command would otherwise overwrite with its result.
pub fn check_not_input(path: &Path, what: &str, inputs: &[PathBuf]) -> Result<(), OutputError> {
    let key = |p: &Path| -> Option<PathBuf> {
        if let Ok(c) = p.canonicalize() {
            return Some(c);
        }
        let parent = match p.parent() {
            Some(d) if !d.as_os_str().is_empty() => d.canonicalize().ok()?,
            _ => std::env::current_dir().ok()?,
        };
        Some(parent.join(p.file_name()?))
    };
    let Some(out) = key(path) else { return Ok(()) };
    for input in inputs {
        // A directory collection reads every `.binary` file in it.
        let in_dir = input.is_dir()
            && out
                .parent()
                .is_some_and(|d| Some(d.to_path_buf()) == key(input))
            && out.extension().is_some_and(|e| e == "binary")
            && out.exists();
        if key(input).as_ref() == Some(&out) || in_dir {
            return Err(OutputError::Encode {
                path: path.to_path_buf(),
                message: format!(
                    "{what} would overwrite the input collection {}",
                    input.display()
                ),
            });
        }
    }
    Ok(())
}

/// Several output files written as one: each is staged as a temporary sibling and all
/// are renamed into place by [`commit`](Self::commit). Dropped uncommitted (an error,
/// a panic), it removes what it staged and the directories it created, leaving the
/// file system as it found it.
#[derive(Debug, Default)]
pub struct OutputSet {
    staged: Vec<(PathBuf, PathBuf)>,
    created_dirs: Vec<PathBuf>,
}

impl OutputSet {
    /// An empty set.
    pub fn new() -> Self {
        Self::default()
    }

    /// Creates `dir` and its missing parents, remembering which it created (removed again
    /// if the set is dropped uncommitted).
    pub fn create_dir_all(&mut self, dir: &Path) -> Result<(), OutputError> {
        let mut missing = Vec::new();
        let mut d = Some(dir);
        while let Some(p) = d {
            if p.as_os_str().is_empty() || p.exists() {
                break;
            }
            missing.push(p.to_path_buf());
            d = p.parent();
        }
        for p in missing.into_iter().rev() {
            std::fs::create_dir(&p).map_err(|source| OutputError::Io {
                path: p.clone(),
                source,
            })?;
            register(&p);
            self.created_dirs.push(p);
        }
        if !dir.is_dir() {
            return Err(OutputError::Encode {
                path: dir.to_path_buf(),
                message: "exists and is not a directory".into(),
            });
        }
        Ok(())
    }

    /// Stages `path`: `fill` writes its content into a temporary sibling.
    pub fn stage<F>(&mut self, path: &Path, fill: F) -> Result<(), OutputError>
    where
        F: FnOnce(&mut dyn Write) -> std::io::Result<()>,
    {
        let tmp = stage(path, fill)?;
        self.staged.push((tmp, path.to_path_buf()));
        Ok(())
    }

    /// Renames every staged file into place, in the order staged. Targets are checked
    /// first (none may be a directory); should a rename still fail, the files this set
    /// had already put in place where none existed are removed again.
    pub fn commit(mut self) -> Result<(), OutputError> {
        for (_, path) in &self.staged {
            check_output_path(path, "output")?;
        }
        let staged = std::mem::take(&mut self.staged);
        let mut result = Ok(());
        let mut placed = Vec::new();
        for (tmp, path) in staged {
            if result.is_ok() {
                let existed = path.exists();
                result = rename_into_place(&tmp, &path);
                if result.is_ok() && !existed {
                    placed.push(path);
                }
            } else {
                let _ = std::fs::remove_file(&tmp);
                unregister(&tmp);
            }
        }
        if result.is_err() {
            for p in placed {
                let _ = std::fs::remove_file(p);
            }
            return result;
        }
        for d in std::mem::take(&mut self.created_dirs) {
            unregister(&d);
        }
        result
    }
}

impl Drop for OutputSet {
    fn drop(&mut self) {
        for (tmp, _) in self.staged.drain(..) {
            let _ = std::fs::remove_file(&tmp);
            unregister(&tmp);
        }
        for d in self.created_dirs.drain(..).rev() {
            let _ = std::fs::remove_dir(&d);
            unregister(&d);
        }
    }
}
