//! The bases `reproduce` compares (paper VI-D) and the paper's own (Table I, read from a
//! CSV `basis,material`).
//!
//! To add a basis source (e.g. error-driven selection): add a [`BasisSource`] variant and
//! push a [`Basis`] in [`super::run`]'s `bases` stage; `dedupe` names coincident
//! bases once, and the fits, tables and figures pick it up from there.

use super::ExperimentError;
use crate::collection::Collection;
use crate::select::Empirical;
use crate::select::{best_run, ClusteringSet};
use std::path::Path;

/// Where a basis comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum BasisSource {
    /// Materials contributing to more than `more_than` leave-one-out fits (Algorithm 1).
    Empirical,
    /// The k-medoids run with the lowest DB over every k (BRDF_it).
    KMedoidsBest,
    /// The best k-medoids run at the largest k (BRDF_it).
    KMedoidsLargestK,
    /// The best GCUK run (BRDF_it).
    GcukBest,
    /// The best GCUK run among those with the largest k found (BRDF_it).
    GcukLargestK,
    /// Greedy forward selection on the fitting error S (SPEC 8), in-sample.
    Greedy,
    /// Swap refinement of the greedy basis on S (SPEC 8), in-sample.
    Swap,
    /// A basis of the paper's Table I, from `--paper-bases`.
    Paper,
}

/// A named basis.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Basis {
    /// Name (also the stem of `fit-<name>.json`).
    pub name: String,
    /// Names of other constructions that gave the same set of materials.
    #[serde(default)]
    pub same_as: Vec<String>,
    /// Where it comes from.
    pub source: BasisSource,
    /// Materials, in the order the source gives them.
    pub materials: Vec<String>,
    /// A remark shown in the report (e.g. a fallback taken), if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub note: Option<String>,
}

/// The five bases of the paper's VI-D from our own runs: empirical, k-medoids best over k,
/// k-medoids at `k_max`, GCUK best, GCUK best at the largest k found (BRDF_it sets).
pub(crate) fn our_bases(
    coll: &Collection,
    emp: &Empirical,
    brdf_it: &[ClusteringSet],
    k_max: usize,
    k_min: usize,
) -> Vec<Basis> {
    let mut out = Vec::new();
    let (materials, note) = if emp.basis.is_empty() {
        let mut order: Vec<usize> = (0..coll.len()).collect();
        order.sort_by_key(|&j| (std::cmp::Reverse(emp.counts[j]), j));
        let m: Vec<String> = order
            .into_iter()
            .take(k_min)
            .map(|j| coll.names()[j].clone())
            .collect();
        (
            m,
            Some(format!(
                "no material contributed to enough fits; the {k_min} most frequent contributors are used"
            )),
        )
    } else {
        (emp.basis.clone(), None)
    };
    out.push(Basis {
        name: "empirical".into(),
        same_as: vec![],
        source: BasisSource::Empirical,
        materials,
        note,
    });
    let km: Vec<&ClusteringSet> = brdf_it
        .iter()
        .filter(|s| s.method.starts_with("kmedoids"))
        .collect();
    if let Some(b) = best_run(km.iter().flat_map(|s| &s.runs)) {
        out.push(basis(
            format!("kmedoids-best-k{}", b.k),
            BasisSource::KMedoidsBest,
            &b.medoids,
        ));
    }
    let at_max = format!("kmedoids-k{k_max}");
    if let Some(s) = km.iter().find(|s| s.method == at_max) {
        out.push(basis(
            at_max,
            BasisSource::KMedoidsLargestK,
            &s.best.medoids,
        ));
    }
    if let Some(g) = brdf_it.iter().find(|s| s.method == "gcuk") {
        out.push(basis(
            format!("gcuk-best-k{}", g.best.k),
            BasisSource::GcukBest,
            &g.best.medoids,
        ));
        let kmax = g.runs.iter().map(|r| r.k).max().unwrap_or(0);
        if let Some(b) = best_run(g.runs.iter().filter(|r| r.k == kmax)) {
            out.push(basis(
                format!("gcuk-largest-k{kmax}"),
                BasisSource::GcukLargestK,
                &b.medoids,
            ));
        }
    }
    out
}

/// The basis of an error-driven selection (`greedy-k5`, `swap-k12`, ...), with its
/// in-sample score in the note.
pub(crate) fn error_driven_basis(s: &crate::select::Selection) -> Basis {
    let source = if s.method == "swap" {
        BasisSource::Swap
    } else {
        BasisSource::Greedy
    };
    Basis {
        name: format!("{}-k{}", s.method, s.k),
        same_as: vec![],
        source,
        materials: s.basis.clone(),
        note: Some(format!(
            "chosen by fitting error on the whole collection (in-sample S = {}; the cross-validation below is the fair comparison)",
            crate::stats::num(s.score)
        )),
    }
}

fn basis(name: String, source: BasisSource, materials: &[String]) -> Basis {
    Basis {
        name,
        same_as: vec![],
        source,
        materials: materials.to_vec(),
        note: None,
    }
}

/// Merges bases with the same set of materials into the first of them (the others'
/// names go to [`Basis::same_as`]), keeping the order.
pub(crate) fn dedupe(bases: Vec<Basis>) -> Vec<Basis> {
    let mut out: Vec<Basis> = Vec::new();
    for b in bases {
        let mut set = b.materials.clone();
        set.sort();
        let same = out.iter_mut().find(|o| {
            let mut s = o.materials.clone();
            s.sort();
            s == set
        });
        match same {
            Some(o) => o.same_as.push(b.name),
            None => out.push(b),
        }
    }
    out
}

/// Whether `name` may name a basis (and so a file `fit-<name>.json`): ASCII letters,
/// digits, `-`, `_`, `.`, not starting with `.`, at most 64 characters.
pub(crate) fn valid_basis_name(name: &str) -> bool {
    !name.is_empty()
        && name.len() <= 64
        && !name.starts_with('.')
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.'))
}

/// Reads the paper's bases from a CSV with (at least) the columns `basis,material`, one
/// row per member, bases in order of first appearance; each becomes `paper-<basis>`.
/// Every material must be in `coll` (errors name the line and suggest close names).
pub fn read_paper_bases(path: &Path, coll: &Collection) -> Result<Vec<Basis>, ExperimentError> {
    let bad = |line: u64, message: String| ExperimentError::PaperBases {
        path: path.to_path_buf(),
        line,
        message,
    };
    let mut rdr = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .from_path(path)
        .map_err(|e| bad(0, e.to_string()))?;
    let headers = rdr.headers().map_err(|e| bad(1, e.to_string()))?.clone();
    let col = |name: &str| {
        headers
            .iter()
            .position(|h| h == name)
            .ok_or_else(|| bad(1, format!("missing column `{name}` (need basis,material)")))
    };
    let (cb, cm) = (col("basis")?, col("material")?);
    let mut out: Vec<Basis> = Vec::new();
    for (i, rec) in rdr.records().enumerate() {
        let line = i as u64 + 2;
        let rec = rec.map_err(|e| bad(line, e.to_string()))?;
        let (b, m) = (
            rec.get(cb).unwrap_or_default(),
            rec.get(cm).unwrap_or_default(),
        );
        if !valid_basis_name(b) {
            return Err(bad(
                line,
                format!("basis name `{b}`: use letters, digits, `-`, `_` or `.` (it names a file)"),
            ));
        }
        coll.index_of(m).map_err(|e| bad(line, e.to_string()))?;
        let name = format!("paper-{b}");
        match out.iter_mut().find(|x| x.name == name) {
            Some(x) if x.materials.iter().any(|y| y == m) => {
                return Err(bad(line, format!("`{m}` is listed twice in basis `{b}`")))
            }
            Some(x) => x.materials.push(m.to_string()),
            None => out.push(basis(name, BasisSource::Paper, &[m.to_string()])),
        }
    }
    if out.is_empty() {
        return Err(bad(1, "no basis rows".into()));
    }
    Ok(out)
}
