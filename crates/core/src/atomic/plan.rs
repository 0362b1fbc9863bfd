//! [`OutputPlan`]: every output path of a command, checked before any work.

use super::*;

/// Tells the entries of an owned tree (by file name) from any other file.
pub type Owns = fn(&str) -> bool;

#[derive(Debug, Clone)]
pub(super) struct Input {
    /// What it is, for messages (`collection`, `tile`, ...).
    pub(super) noun: String,
    pub(super) shown: PathBuf,
    pub(super) key: PathBuf,
    pub(super) canonical: Option<PathBuf>,
    pub(super) id: Option<(u64, u64)>,
    pub(super) dir: bool,
}

#[derive(Debug, Clone, PartialEq)]
pub(super) enum Kind {
    File,
    Dir,
    Remove,
    /// A wholly owned directory; `exists` when it was there at planning.
    Tree {
        exists: bool,
    },
}

#[derive(Debug, Clone)]
pub(super) struct Planned {
    pub(super) path: PathBuf,
    pub(super) key: PathBuf,
    pub(super) flag: String,
    pub(super) kind: Kind,
}

/// Every output path of one command, checked before any work (see the
/// [module docs](crate::atomic)); [`into_set`](Self::into_set) turns it into the [`OutputSet`]
/// that stages and commits them.
#[derive(Debug, Default)]
pub struct OutputPlan {
    pub(super) inputs: Vec<Input>,
    pub(super) planned: Vec<Planned>,
    /// Tree predicates, by index in `planned`.
    pub(super) trees: Vec<(usize, Owns)>,
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
    pub(super) fn check_input(&self, path: &Path, k: &Path, flag: &str) -> Result<(), OutputError> {
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
            // A directory collection reads every `.binary`, `.bsdf` and `.npy` file in it
            // (a `.npy` outside a neural BRDF set makes the directory unreadable).
            let read_kind = k.extension().and_then(|e| e.to_str()).and_then(|e| {
                ["binary", "bsdf", "npy"]
                    .into_iter()
                    .find(|x| e.eq_ignore_ascii_case(x))
            });
            let in_dir = i.dir
                && out_parent.is_some_and(|d| Some(d) == i.canonical.as_deref() || d == i.key);
            if let (true, Some(ext)) = (in_dir, read_kind) {
                return Err(refused(
                    path,
                    format!(
                        "{flag} would write a .{ext} into the input collection directory {} (the collection reads every .binary, .bsdf and .npy file there: this would replace or add a material, or make the directory unreadable)",
                        i.shown.display()
                    ),
                ));
            }
        }
        Ok(())
    }

    /// Refuses a second output on the same path, or an output inside a planned tree.
    pub(super) fn check_duplicate(
        &self,
        path: &Path,
        k: &Path,
        flag: &str,
    ) -> Result<(), OutputError> {
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

    pub(super) fn is_dir_kind(&self, k: &Path) -> bool {
        self.planned
            .iter()
            .any(|p| p.key == k && p.kind == Kind::Dir)
    }

    /// The common checks of a path: not empty, named, not an input, not planned twice;
    /// returns its key.
    pub(super) fn common(&self, path: &Path, flag: &str) -> Result<PathBuf, OutputError> {
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
    pub(super) fn check_parent(
        &self,
        path: &Path,
        k: &Path,
        flag: &str,
    ) -> Result<(), OutputError> {
        if k.parent().is_some_and(|kp| self.is_dir_kind(kp)) {
            return Ok(());
        }
        parent_is_dir(path, flag)
    }

    /// A file the user named (see the [module docs](crate::atomic)).
    pub fn file(&mut self, path: &Path, flag: &str) -> Result<(), OutputError> {
        self.push_file(path, flag, Kind::File)
    }

    pub(super) fn push_file(
        &mut self,
        path: &Path,
        flag: &str,
        kind: Kind,
    ) -> Result<(), OutputError> {
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

    /// A directory files are written into (see the [module docs](crate::atomic)).
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
    pub(super) fn check_dir_target(
        &self,
        path: &Path,
        k: &Path,
        flag: &str,
    ) -> Result<bool, OutputError> {
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

    /// A directory the command owns as a whole (see the [module docs](crate::atomic)): `owns`
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
pub(super) fn probe(dir: &Path) -> std::io::Result<()> {
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
pub(super) const STAGE_PREFIX: &str = ".brdf-basis-stage-";

/// The process id in a staging directory's name `.brdf-basis-stage-PID-N` (both decimal).
pub(super) fn stage_pid(name: &str) -> Option<u32> {
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
pub(super) fn remove_stale_stages(dir: &Path) {
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
pub(super) fn remove_stale_stages(_dir: &Path) {}
