//! Path checks of the output layer: what an existing path is, whether it may be
//! replaced, parents, and the keys that tell two spellings of one file apart.

use super::*;

/// What an existing path is, for messages.
pub(super) fn kind_of(meta: &std::fs::Metadata) -> &'static str {
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
pub(super) fn not_replaceable(path: &Path, flag: &str) -> Option<OutputError> {
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
pub(crate) fn check_output_path(path: &Path, what: &str) -> Result<(), OutputError> {
    if path.as_os_str().is_empty() {
        return Err(refused(path, format!("{what}: empty path")));
    }
    if let Some(e) = not_replaceable(path, what) {
        return Err(e);
    }
    parent_is_dir(path, what)
}

/// Checks that the directory `path` is in exists (`flag` names the flag in the message).
pub(super) fn parent_is_dir(path: &Path, flag: &str) -> Result<(), OutputError> {
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
pub(super) fn parent_of(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// `path` made absolute and normalised: the canonical form of its nearest existing
/// ancestor, then the remaining components (`.` dropped, `..` applied lexically). The
/// last component is not resolved (a link is not followed), so a link and its target
/// have different keys; links are refused on their own.
pub(super) fn key(path: &Path) -> PathBuf {
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
pub(super) fn file_id(path: &Path) -> Option<(u64, u64)> {
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
