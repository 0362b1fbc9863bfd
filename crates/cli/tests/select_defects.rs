//! Defects of `select` and `cv` (issue 15), one test each; every one failed on the code
//! before the fix (noted per test).

use crate::common::{bin, shared_or_skip};
use brdf_basis::select::SelectOutput;
use brdf_basis::select::{best_index, best_run, ClusteringRun};
use std::path::{Path, PathBuf};
use std::process::Output;

/// A fresh scratch directory for `test`.
fn scratch(test: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!(
        "brdf-basis-select-defects-{test}-{}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("scratch dir");
    d
}

/// The first `rows` materials of the Ngan table as a CSV in `dir`.
fn base_csv(dir: &Path, rows: usize, test: &str) -> Option<PathBuf> {
    let ngan = shared_or_skip("ngan2005_ashikhmin_shirley.csv", test)?;
    let text = std::fs::read_to_string(ngan).expect("ngan table");
    let head: Vec<&str> = text.lines().take(rows + 1).collect();
    let p = dir.join("base.csv");
    std::fs::write(&p, head.join("\n") + "\n").expect("base.csv");
    Some(p)
}

fn run(args: &[&str]) -> Output {
    bin().args(args).output().expect("run brdf-basis")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

/// Before: `S = 0` and exit 0 (the basis held every target).
#[test]
fn select_objective_with_no_target_left_is_an_error() {
    let d = scratch("no-target");
    let Some(base) = base_csv(&d, 6, "select_objective_with_no_target_left_is_an_error") else {
        return;
    };
    let json = d.join("g.json");
    let o = run(&[
        "select",
        s(&base),
        "--stride",
        "4",
        "--method",
        "greedy",
        "-k",
        "6",
        "--json",
        s(&json),
    ]);
    assert!(!o.status.success(), "{}", stdout(&o));
    assert!(stderr(&o).contains("leave none to score"), "{}", stderr(&o));
    assert!(!json.exists());
}

/// Before: exit 0 with `"basis": []`.
#[test]
fn select_empty_empirical_basis_is_an_error() {
    let d = scratch("empty-empirical");
    let Some(base) = base_csv(&d, 6, "select_empty_empirical_basis_is_an_error") else {
        return;
    };
    let json = d.join("e.json");
    let o = run(&[
        "select",
        s(&base),
        "--stride",
        "8",
        "--method",
        "empirical",
        "--more-than",
        "100",
        "--json",
        s(&json),
    ]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("empirical basis is empty"),
        "{}",
        stderr(&o)
    );
    assert!(!json.exists());
}

/// Before: exit 0 with `"db_index": null` for the best run of an all-zero matrix.
#[test]
fn select_undefined_db_index_is_an_error() {
    let d = scratch("zero-matrix");
    let m = d.join("zero.csv");
    // Two pairs of identical materials: any 3 medoids include two at distance 0.
    std::fs::write(
        &m,
        "material,a,b,c,d\na,0,0,1,1\nb,0,0,1,1\nc,1,1,0,0\nd,1,1,0,0\n",
    )
    .unwrap();
    let json = d.join("k.json");
    let o = run(&[
        "select",
        "--distances",
        s(&m),
        "--method",
        "kmedoids",
        "-k",
        "3",
        "--runs",
        "3",
        "--json",
        s(&json),
    ]);
    assert!(!o.status.success(), "{}", stdout(&o));
    assert!(
        stderr(&o).contains("Davies-Bouldin index is undefined"),
        "{}",
        stderr(&o)
    );
}

/// Before: GCUK ran and returned its own k (16) without a word.
#[test]
fn select_gcuk_refuses_k() {
    let d = scratch("gcuk-k");
    let o = run(&[
        "select",
        "--method",
        "gcuk",
        "-k",
        "5",
        "--json",
        s(&d.join("g.json")),
    ]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("-k does not apply to --method gcuk"),
        "{}",
        stderr(&o)
    );
}

/// Before: `--candidates` was ignored by k-medoids.
#[test]
fn select_kmedoids_refuses_candidates() {
    let d = scratch("km-candidates");
    let o = run(&[
        "select",
        "--method",
        "kmedoids",
        "-k",
        "2",
        "--candidates",
        "a,b",
        "--json",
        s(&d.join("k.json")),
    ]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("--candidates applies to greedy, swap and ga"),
        "{}",
        stderr(&o)
    );
}

/// Before: `--stride` and `--metric` were ignored with `--distances`.
#[test]
fn select_distances_refuses_stride_and_metric() {
    let d = scratch("distances-stride");
    let m = d.join("m.csv");
    std::fs::write(&m, "material,a,b,c\na,0,1,2\nb,1,0,1.5\nc,2,1.5,0\n").unwrap();
    // A .npy's sidecar records the metric (a CSV's --metric only labels it).
    let npy = d.join("m.npy");
    for (flag, value, m) in [("--stride", "4", &m), ("--metric", "euclidean", &npy)] {
        let o = run(&[
            "select",
            "--distances",
            s(m),
            "--method",
            "kmedoids",
            "-k",
            "2",
            flag,
            value,
            "--json",
            s(&d.join("k.json")),
        ]);
        assert!(!o.status.success(), "{flag}");
        assert!(
            stderr(&o).contains(&format!("{flag} does not apply with --distances")),
            "{}",
            stderr(&o)
        );
    }
}

/// Before: "material `greedy` is listed twice".
#[test]
fn cv_duplicate_method_is_called_a_method() {
    let d = scratch("cv-dup");
    let o = run(&[
        "cv",
        "--methods",
        "greedy,greedy",
        "--json",
        s(&d.join("c.json")),
    ]);
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(
        e.contains("method `greedy` is listed twice") && !e.contains("material"),
        "{e}"
    );
}

/// Before: `--ga-mutation 2` was reported as `mutation_prob = 2`.
#[test]
fn select_messages_name_flags_not_fields() {
    let d = scratch("ga-mutation");
    let o = run(&[
        "select",
        "--method",
        "ga",
        "-k",
        "2",
        "--ga-mutation",
        "2",
        "--json",
        s(&d.join("g.json")),
    ]);
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(
        e.contains("--ga-mutation") && !e.contains("mutation_prob"),
        "{e}"
    );
}

/// Before: `select` replaced a FIFO given as `--json` with a regular file.
#[test]
fn select_refuses_a_fifo_json() {
    let d = scratch("fifo");
    let fifo = d.join("fifo");
    let made = std::process::Command::new("mkfifo").arg(&fifo).status();
    if !made.is_ok_and(|s| s.success()) {
        eprintln!("SKIP select_refuses_a_fifo_json: mkfifo failed");
        return;
    }
    let o = run(&[
        "select",
        "--method",
        "greedy",
        "-k",
        "2",
        "--stride",
        "8",
        "--json",
        s(&fifo),
    ]);
    assert!(!o.status.success());
    use std::os::unix::fs::FileTypeExt;
    assert!(std::fs::symlink_metadata(&fifo)
        .unwrap()
        .file_type()
        .is_fifo());
}

/// Before: `select coll.csv --json coll.csv` overwrote the collection.
#[test]
fn select_refuses_to_overwrite_its_input() {
    let d = scratch("input");
    let Some(base) = base_csv(&d, 6, "select_refuses_to_overwrite_its_input") else {
        return;
    };
    let before = std::fs::read(&base).unwrap();
    let o = run(&[
        "select",
        s(&base),
        "--method",
        "greedy",
        "-k",
        "2",
        "--stride",
        "8",
        "--json",
        s(&base),
    ]);
    assert!(!o.status.success());
    assert_eq!(std::fs::read(&base).unwrap(), before);
}

/// Before: `cv --json s.json --markdown s.json` kept only the Markdown, exit 0.
#[test]
fn cv_refuses_json_and_markdown_on_one_path() {
    let d = scratch("cv-same");
    let p = d.join("s.json");
    let o = run(&[
        "cv",
        "--methods",
        "random",
        "-k",
        "2",
        "--json",
        s(&p),
        "--markdown",
        s(&p),
    ]);
    assert!(!o.status.success());
    assert!(!p.exists());
}

/// Before: `--json nosuch/x.json` failed only after the clustering (the back-end was
/// opened and the distances computed first).
#[test]
fn select_kmedoids_checks_json_before_work() {
    let d = scratch("nosuch");
    let json = d.join("nosuch").join("x.json");
    let o = run(&[
        "select",
        "--method",
        "kmedoids",
        "-k",
        "2",
        "--json",
        s(&json),
    ]);
    assert!(!o.status.success());
    assert!(
        !stderr(&o).contains("backend:"),
        "work started: {}",
        stderr(&o)
    );
}

/// Before: select and reproduce chose best runs by different rules (strict `<=` in
/// reproduce); now both use the tie tolerance, ties to the first run.
#[test]
fn best_run_uses_the_tie_tolerance() {
    let run = |seed, db| ClusteringRun {
        seed,
        k: 2,
        medoids: vec![],
        labels: vec![],
        loss: 1.0,
        db_index: db,
        silhouette: 0.0,
        dunn: None,
    };
    let runs = [
        run(1, 1.0),
        run(2, 1.0 - 1e-9),
        run(3, 0.5 + 1e-12),
        run(4, 0.5),
    ];
    assert_eq!(best_run(&runs[..2]).unwrap().seed, 1);
    assert_eq!(best_run(&runs).unwrap().seed, 3);
    assert_eq!(best_index([2.0, 1.0, 1.0 - 1e-7]), Some(1));
    assert_eq!(best_index([2.0, 1.0, 0.99]), Some(2));
}

/// Before: the select JSON carried no fingerprint and was built from untyped values; it is
/// read back by the type that wrote it, and results are printed on stdout.
#[test]
fn select_output_round_trips_with_its_fingerprint() {
    let d = scratch("round-trip");
    let Some(base) = base_csv(&d, 6, "select_output_round_trips_with_its_fingerprint") else {
        return;
    };
    let json = d.join("g.json");
    let o = run(&[
        "select",
        s(&base),
        "--method",
        "greedy",
        "-k",
        "2",
        "--stride",
        "8",
        "--json",
        s(&json),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("greedy: k = 2, S = ") && stdout(&o).contains("wrote "),
        "{}",
        stdout(&o)
    );
    let out = SelectOutput::read(&json).expect("read back");
    let coll = brdf_basis::collection::Collection::load(&base).unwrap();
    assert_eq!(
        out.collection_fingerprint(),
        Some(coll.fingerprint().as_str())
    );
    assert_eq!(out.basis().len(), 2);
    assert!(matches!(out, SelectOutput::ErrorDriven(_)));
    assert_eq!(SelectOutput::from_json(&out.to_json()).unwrap(), out);
}

/// Before: the help listed three of six methods.
#[test]
fn help_lists_all_six_methods() {
    let top = stdout(&run(&["--help"]));
    assert!(top.contains("greedy") && top.contains("ga"), "{top}");
    let sel = stdout(&run(&["select", "--help"]));
    for m in ["empirical", "kmedoids", "gcuk", "greedy", "swap", "ga"] {
        assert!(
            sel.contains(&format!("{m}:")) || sel.contains(&format!("{m} ")),
            "{m}: {sel}"
        );
    }
    assert!(
        sel.contains("possible values") || sel.contains("Possible values"),
        "{sel}"
    );
}

/// Before: `--k-max = 12 is invalid: below the number of materials (6)`.
#[test]
fn reproduce_k_max_message_reads_right() {
    let d = scratch("kmax");
    let Some(base) = base_csv(&d, 6, "reproduce_k_max_message_reads_right") else {
        return;
    };
    let o = run(&[
        "reproduce",
        "--no-appearance",
        s(&base),
        "--out",
        s(&d.join("out")),
    ]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("it must be below the number of materials (6)"),
        "{}",
        stderr(&o)
    );
}

/// Before: the library defaults used seed 0 and the command line seed 1, so
/// `cross_validate(CvParams::default())` and `brdf-basis cv` used different folds.
#[test]
fn library_default_seeds_agree_with_the_command_line() {
    assert_eq!(brdf_basis::select::cv::CvParams::default().seed, 1);
    assert_eq!(brdf_basis::select::GaParams::default().seed, 1);
    assert_eq!(brdf_basis::cluster::KMedoidsParams::new(3).seed, 1);
    assert_eq!(brdf_basis::cluster::GcukParams::default().seed, 1);
}

/// Before: `cv` accepted a k of the whole training fold for greedy (its training score
/// then had no target) and printed `2.4075e1`-style numbers in its table.
#[test]
fn cv_refuses_k_of_the_whole_training_fold_and_prints_readable_numbers() {
    let d = scratch("cv-k");
    let Some(base) = base_csv(&d, 6, "cv_refuses_k_of_the_whole_training_fold") else {
        return;
    };
    let o = run(&[
        "cv",
        s(&base),
        "--methods",
        "greedy",
        "-k",
        "3",
        "--folds",
        "2",
        "--stride",
        "8",
        "--json",
        s(&d.join("c.json")),
    ]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("leaves no target to score"),
        "{}",
        stderr(&o)
    );
    let md = d.join("c.md");
    let o = run(&[
        "cv",
        s(&base),
        "--methods",
        "greedy,random",
        "-k",
        "2",
        "--folds",
        "2",
        "--stride",
        "8",
        "--render-size",
        "8",
        "--json",
        s(&d.join("c.json")),
        "--markdown",
        s(&md),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&md).unwrap();
    assert!(
        !text.contains("e0 ") && !text.contains("e1 ") && !text.contains("e-1 "),
        "{text}"
    );
    assert!(stdout(&o).contains("| greedy | 2 |"), "{}", stdout(&o));
}

/// Before: "--distances clusters a saved matrix (--method kmedoids or gcuk) and takes no
/// COLLECTION" for a wrong method, when no COLLECTION was given.
#[test]
fn select_distances_with_a_wrong_method_says_so() {
    let d = scratch("distances-method");
    let m = d.join("m.csv");
    std::fs::write(&m, "material,a,b,c\na,0,1,2\nb,1,0,1.5\nc,2,1.5,0\n").unwrap();
    let o = run(&[
        "select",
        "--distances",
        s(&m),
        "--method",
        "greedy",
        "-k",
        "2",
        "--json",
        s(&d.join("g.json")),
    ]);
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(
        e.contains("needs --method kmedoids or gcuk") && !e.contains("COLLECTION"),
        "{e}"
    );
}

/// Before (audit-2 U3): `plan --help` showed "[`super::nielsen`]" and every command's
/// `--backend` help "([`AutoBackend`], [`AUTO_ROUTES`])": rustdoc links in the help text.
#[test]
fn no_help_shows_a_rustdoc_link() {
    let top = stdout(&run(&["--help"]));
    let commands: Vec<&str> = top
        .lines()
        .skip_while(|l| !l.starts_with("Commands:"))
        .skip(1)
        .take_while(|l| !l.trim().is_empty())
        .filter_map(|l| l.split_whitespace().next())
        .filter(|c| *c != "help")
        .collect();
    assert!(commands.len() >= 10, "{commands:?}");
    for c in commands {
        let help = stdout(&run(&[c, "--help"]));
        for bad in ["[`", "`]", "super::", "crate::"] {
            assert!(!help.contains(bad), "`{c} --help` shows `{bad}`:\n{help}");
        }
    }
}
