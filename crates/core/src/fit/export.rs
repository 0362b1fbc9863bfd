//! Exporting fits: the fitted combination tabulated on the MERL grid, and the file names
//! of an export directory (sanitised so that no material name can choose a path).

use super::{combination_values, TargetFit};
use crate::collection::Collection;
use crate::merl::{cell_info, N_CELLS};

/// The fitted combination on the full grid, channel-planar (invalid cells -1), as
/// `write_binary` takes it.
pub fn combination_grid(coll: &Collection, basis: &[usize], f: &TargetFit) -> Vec<f32> {
    let cells: Vec<u32> = (0..N_CELLS as u32).collect();
    let mut rgb = vec![-1f32; 3 * N_CELLS];
    for c in 0..3 {
        let v = combination_values(coll, basis, f, c, &cells);
        for (cell, x) in v.into_iter().enumerate() {
            if cell_info(cell).valid {
                rgb[c * N_CELLS + cell] = x as f32;
            }
        }
    }
    rgb
}

/// A file name for material `name` that no name can turn into another path: ASCII
/// letters, digits, `-`, `_` and `.` are kept, anything else (`/`, `\`, spaces, control
/// characters, non-ASCII) becomes `_`; leading dots are dropped (no `..`, no hidden
/// file); a leading `-` becomes `_` (no name that a shell command reads as an option:
/// `rm *` in the directory); at most 100 characters; an empty result becomes `material`.
pub(crate) fn file_stem_for(name: &str) -> String {
    let mut s: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' || c == '.' {
                c
            } else {
                '_'
            }
        })
        .collect();
    s = s.trim_start_matches('.').chars().take(100).collect();
    if s.starts_with('-') {
        s.replace_range(..1, "_");
    }
    if s.is_empty() {
        s = "material".into();
    }
    s
}

/// File names (`<stem>.binary`) for the targets, sanitised by `file_stem_for` and made
/// unique (case-insensitively, for case-insensitive file systems) by a `-2`, `-3`, ...
/// suffix, in target order.
pub fn export_file_names(names: &[&str]) -> Vec<String> {
    let mut taken = std::collections::HashSet::new();
    names
        .iter()
        .map(|n| {
            let stem = file_stem_for(n);
            let mut cand = stem.clone();
            let mut k = 2;
            while !taken.insert(cand.to_lowercase()) {
                cand = format!("{stem}-{k}");
                k += 1;
            }
            format!("{cand}.binary")
        })
        .collect()
}

/// Name of the CSV (`material,file`) that `--export` writes beside the `.binary` files.
pub const EXPORT_INDEX: &str = "index.csv";

/// The `index.csv` of an export: `material,file`, one row per exported target.
pub fn export_index_csv(names: &[&str], files: &[String]) -> Result<Vec<u8>, csv::Error> {
    let mut index = Vec::new();
    {
        let mut wr = csv::Writer::from_writer(&mut index);
        wr.write_record(["material", "file"])?;
        for (n, file) in names.iter().zip(files) {
            wr.write_record([*n, file.as_str()])?;
        }
        wr.flush()?;
    }
    Ok(index)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_never_choose_a_path_and_are_unique() {
        assert_eq!(file_stem_for("../etc/passwd"), "_etc_passwd");
        assert_eq!(file_stem_for("..."), "material");
        // Audit 2, U8: never a name that starts like an option.
        assert_eq!(file_stem_for("-rf"), "_rf");
        assert_eq!(file_stem_for(".-rf"), "_rf");
        assert_eq!(file_stem_for("a-b"), "a-b");
        assert_eq!(
            export_file_names(&["a/b", "a_b", "A_B", "x"]),
            ["a_b.binary", "a_b-2.binary", "A_B-3.binary", "x.binary"]
        );
    }
}
