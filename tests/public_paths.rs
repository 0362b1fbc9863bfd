//! One public path per item (issue "Crates as fences"): in the core and GPU crates, a
//! `pub use` may only lift items out of a private module. A `pub use` of a sibling
//! `pub mod`'s items, or of an item that lives elsewhere (`crate::`, `super::`, another
//! crate), gives the item a second public path and fails the test, named by file and
//! line. The facade crate `brdf-basis` re-exports the core's modules under the same
//! paths on purpose (docs/architecture.md) and is not scanned.

use crate::hygiene::rust_files;
use std::path::Path;

/// `(line, path)` of every `pub use` in `code` that gives an item a second public path.
fn second_paths(code: &str) -> Vec<(usize, String)> {
    let lines: Vec<&str> = code
        .lines()
        .map(|l| l.split("//").next().unwrap_or(""))
        .collect();
    let public_mods: Vec<String> = lines
        .iter()
        .filter_map(|l| l.trim().strip_prefix("pub mod "))
        .filter_map(|r| r.strip_suffix(';'))
        .map(str::to_string)
        .collect();
    let mut out = Vec::new();
    for (i, l) in lines.iter().enumerate() {
        let Some(path) = l.trim().strip_prefix("pub use ") else {
            continue;
        };
        let first = path.split("::").next().unwrap_or("").trim();
        let elsewhere = [
            "crate",
            "super",
            "self",
            "brdf_basis_core",
            "brdf_basis_gpu",
        ];
        if public_mods.iter().any(|m| m == first) || elsewhere.contains(&first) {
            out.push((i + 1, path.trim_end_matches(';').to_string()));
        }
    }
    out
}

#[test]
fn every_public_item_of_the_core_and_gpu_crates_has_one_path() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut files = Vec::new();
    for dir in ["crates/core/src", "crates/gpu/src"] {
        rust_files(&root.join(dir), &mut files);
    }
    assert!(files.len() > 50, "found only {} source files", files.len());
    let mut bad = Vec::new();
    for f in &files {
        let code = std::fs::read_to_string(f).unwrap_or_else(|e| panic!("{}: {e}", f.display()));
        for (line, path) in second_paths(&code) {
            let rel = f.strip_prefix(root).unwrap_or(f);
            bad.push(format!("{}:{line}: pub use {path}", rel.display()));
        }
    }
    assert!(
        bad.is_empty(),
        "items with a second public path:\n{}",
        bad.join("\n")
    );
}

#[test]
fn the_path_check_finds_planted_second_paths() {
    let code = "pub mod grid;\nmod binary;\npub use binary::*;\npub use grid::Mask;\n\
                pub(crate) use grid::lookup;\npub use crate::brdf::LobeParams; // two\n\
                // pub use grid::Old;\npub use super::TEX_W;\n";
    let found: Vec<usize> = second_paths(code).into_iter().map(|(l, _)| l).collect();
    assert_eq!(found, vec![4, 6, 8]);
}
