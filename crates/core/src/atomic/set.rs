//! [`OutputSet`]: outputs staged together and put in place at its commit.

use super::*;

/// Outputs staged together and put in place by [`commit`](Self::commit); dropped
/// uncommitted, it removes what it staged and the directories it created.
#[derive(Debug, Default)]
pub struct OutputSet {
    /// `None`: a set without a plan ([`OutputSet::new`]).
    pub(super) plan: Option<OutputPlan>,
    /// Staging directory of each destination directory `(dest, scratch)`.
    pub(super) scratch: Vec<(PathBuf, PathBuf)>,
    /// `(staged, target)`.
    pub(super) staged: Vec<(PathBuf, PathBuf)>,
    /// `(target, staging root, owns)` of trees.
    pub(super) trees: Vec<(PathBuf, PathBuf, Owns)>,
    pub(super) created: Vec<PathBuf>,
}

impl OutputSet {
    /// A set without a plan: each staged path is checked when staged
    /// (`check_output_path`). Prefer [`OutputPlan`], which checks before the work.
    pub fn new() -> Self {
        Self::default()
    }

    /// The planned entry of `path`, if planned.
    pub(super) fn planned(&self, path: &Path) -> Option<&Planned> {
        let k = key(path);
        self.plan.as_ref()?.planned.iter().find(|p| p.key == k)
    }

    /// Creates `dir` if it is missing (its parent must exist), remembering it.
    pub(super) fn ensure_dir(&mut self, dir: &Path) -> Result<(), OutputError> {
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
    pub(super) fn scratch_in(&mut self, dest: &Path) -> Result<PathBuf, OutputError> {
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
        // Audit 3, U2: a set committed inside another set's staging directory (a matrix
        // saved into `reproduce`'s tree) puts nothing where the user sees it.
        let visible = self
            .staged
            .iter()
            .map(|(_, t)| t)
            .chain(self.trees.iter().map(|(t, _, _)| t))
            .chain(self.plan.iter().flat_map(|p| {
                p.planned
                    .iter()
                    .filter(|p| p.kind == Kind::Remove)
                    .map(|p| &p.path)
            }))
            .any(|t| !in_pending_scratch(t));
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
        if visible {
            mark_in_place();
        }
        Ok(())
    }

    /// The renames of [`commit`](Self::commit), each recorded in `moves` (for a rollback).
    pub(super) fn commit_moves(
        &mut self,
        moves: &mut Vec<(PathBuf, PathBuf)>,
    ) -> Result<(), OutputError> {
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
