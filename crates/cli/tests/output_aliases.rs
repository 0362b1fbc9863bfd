//! Property (issue 36): for every command that writes outputs (select, distance,
//! tabulate, fit, fit --samples, plan, cv, cv --acquisition, reproduce), no output path
//! that names one of its inputs under another spelling (`./`, `a/../a`, `a//b`, `a/./b`,
//! absolute, a case variant where the file system ignores case), through a link (a
//! symbolic link to the file or to its directory, a hard link), or that holds an input
//! (`reproduce --out`) is accepted, and every input stays byte-identical. Spellings are
//! drawn from a fixed seed; the binary runs every case (each is refused before any work,
//! so the whole table takes seconds), and [`OutputPlan`], which every command plans its
//! outputs with, is checked on many more.

use crate::common::*;
use brdf_basis::atomic::OutputPlan;
use rand::Rng;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Duration;

const CSV: &str = "material,d_r,d_g,d_b,s_r,s_g,s_b,F0,n\n\
    plastic,0.2,0.1,0.05,0.3,0.3,0.3,0.04,120\n\
    metal,0,0,0,0.9,0.7,0.4,0.8,2500\n\
    satin,0.05,0.05,0.08,0.2,0.25,0.3,0.1,15\n\
    target,0.12,0.07,0.06,0.5,0.4,0.3,0.2,400\n";

/// One command: its arguments (`{C}` the collection, `{S}` a samples file, `{K}` a
/// candidates file, `{M}` a saved matrix), its inputs (placeholders) and its output flags.
struct Cmd {
    args: &'static [&'static str],
    inputs: &'static [&'static str],
    outputs: &'static [&'static str],
    /// The output the command requires, and a fresh name for it (when another is tested).
    required: (&'static str, &'static str),
}

const CMDS: &[Cmd] = &[
    Cmd {
        args: &[
            "select", "{C}", "--method", "kmedoids", "-k", "2", "--runs", "2", "--stride", "16",
        ],
        inputs: &["{C}"],
        outputs: &["--json"],
        required: ("--json", "fresh.json"),
    },
    Cmd {
        args: &[
            "select",
            "--distances",
            "{M}",
            "--method",
            "kmedoids",
            "-k",
            "2",
            "--runs",
            "2",
        ],
        inputs: &["{M}", "in/m.names.json"],
        outputs: &["--json"],
        required: ("--json", "fresh.json"),
    },
    Cmd {
        args: &["distance", "{C}", "--stride", "16"],
        inputs: &["{C}"],
        outputs: &["--out"],
        required: ("--out", "fresh.npy"),
    },
    Cmd {
        args: &["tabulate", "{C}", "--material", "plastic"],
        inputs: &["{C}"],
        outputs: &["--out"],
        required: ("--out", "fresh.binary"),
    },
    Cmd {
        args: &["fit", "{C}", "--basis", "plastic,metal", "--stride", "16"],
        inputs: &["{C}"],
        outputs: &["--json"],
        required: ("--json", "fresh.json"),
    },
    Cmd {
        args: &["fit", "{C}", "--basis", "plastic,metal", "--samples", "{S}"],
        inputs: &["{C}", "{S}"],
        outputs: &["--json"],
        required: ("--json", "fresh.json"),
    },
    Cmd {
        args: &[
            "plan",
            "{C}",
            "--basis",
            "plastic,metal",
            "--targets",
            "satin,target",
            "-n",
            "2",
            "--candidates",
            "{K}",
        ],
        inputs: &["{C}", "{K}"],
        outputs: &["--out", "--json"],
        required: ("--out", "fresh.csv"),
    },
    Cmd {
        args: &[
            "cv",
            "{C}",
            "--methods",
            "random",
            "-k",
            "1",
            "--stride",
            "16",
        ],
        inputs: &["{C}"],
        outputs: &["--json", "--markdown"],
        required: ("--json", "fresh.json"),
    },
    Cmd {
        args: &["cv", "{C}", "--acquisition", "-n", "2", "--stride", "16"],
        inputs: &["{C}"],
        outputs: &["--json", "--markdown", "--figure"],
        required: ("--json", "fresh.json"),
    },
    Cmd {
        args: &["reproduce", "{C}"],
        inputs: &["{C}"],
        outputs: &["--out"],
        required: ("--out", "fresh"),
    },
];

/// The work directory: inputs under `in/`, with `lin` a symbolic link to `in`.
fn workdir() -> tempfile::TempDir {
    let dir = tmp();
    let d = dir.path();
    let i = d.join("in");
    std::fs::create_dir(&i).expect("mkdir");
    write(&i, "c.csv", CSV);
    let mut s = String::from("theta_i,phi_i,theta_o,phi_o,r,g,b\n");
    for (ti, to) in [(10, 20), (20, 25), (30, 31), (40, 45), (50, 10), (60, 70)] {
        s += &format!("{ti},0,{to},180,0.2,0.1,0.1\n");
    }
    write(&i, "s.csv", &s);
    write(
        &i,
        "k.csv",
        "theta_i,phi_i,theta_o,phi_o\n10,0,20,180\n30,0,40,180\n50,0,20,180\n",
    );
    let o = run(
        d,
        &[
            "distance", "in/c.csv", "--stride", "16", "--out", "in/m.npy",
        ],
    );
    assert!(o.status.success(), "{}", text(&o.stderr));
    std::os::unix::fs::symlink("in", d.join("lin")).expect("symlink");
    dir
}

fn run(dir: &Path, args: &[&str]) -> std::process::Output {
    let mut cmd = bin();
    cmd.args(["--quiet", "--backend", "cpu"])
        .args(args)
        .current_dir(dir);
    output_within(&mut cmd, Duration::from_secs(120))
        .unwrap_or_else(|| panic!("brdf-basis {args:?} hangs"))
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

/// Every entry under `dir` (links not followed) with its content: any write shows.
fn snapshot(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(p) = stack.pop() {
        for e in std::fs::read_dir(&p).expect("read_dir") {
            let e = e.expect("entry");
            let (path, ty) = (e.path(), e.file_type().expect("type"));
            let rel = path.strip_prefix(dir).expect("under").to_path_buf();
            if ty.is_dir() {
                out.insert(rel, b"dir".to_vec());
                stack.push(path);
            } else if ty.is_symlink() {
                let t = std::fs::read_link(&path).expect("link");
                out.insert(rel, t.as_os_str().as_encoded_bytes().to_vec());
            } else {
                out.insert(rel, std::fs::read(&path).expect("read"));
            }
        }
    }
    out
}

/// Whether the file system of `dir` ignores case.
fn case_insensitive(dir: &Path) -> bool {
    let p = dir.join("CaseProbe");
    std::fs::write(&p, "x").expect("probe");
    let r = dir.join("caseprobe").exists();
    std::fs::remove_file(p).expect("probe");
    r
}

/// Other spellings of `rel` (a file `in/NAME` or the directory `in`), relative to `d`:
/// the fixed ones, then `random` ones drawn from `rng` (`.` and `x/..` segments and
/// doubled slashes inserted between components).
fn spellings(d: &Path, rel: &str, rng: &mut impl Rng, random: usize) -> Vec<String> {
    let mut v = vec![
        rel.to_string(),
        format!("./{rel}"),
        format!("in/../{rel}"),
        rel.replacen("in", "in/.", 1),
        rel.replacen("in", "in/", 1),
        d.join(rel).display().to_string(),
        rel.replacen("in", "lin", 1),
    ];
    if rel == "in" {
        v.extend(["in/".into(), "in/.".into(), "./in//".into()]);
    }
    if case_insensitive(d) {
        v.push(rel.to_uppercase());
    }
    let parts: Vec<&str> = rel.split('/').collect();
    for _ in 0..random {
        let mut s = String::new();
        for (i, p) in parts.iter().enumerate() {
            if i > 0 {
                s += if rng.random_bool(0.3) { "//" } else { "/" };
            }
            if rng.random_bool(0.5) {
                s += "./";
            }
            if rng.random_bool(0.4) {
                s += &format!("{}/../", ["in", "lin", "zz"][rng.random_range(0..3)]);
            }
            s += p;
        }
        v.push(s);
    }
    v
}

/// Links to the file `rel` in `d`, named with its extension: a symbolic and a hard link.
fn links(d: &Path, rel: &str, tag: &str) -> Vec<String> {
    let name = Path::new(rel).file_name().expect("name").to_string_lossy();
    let (sym, hard) = (format!("sym-{tag}-{name}"), format!("hard-{tag}-{name}"));
    std::os::unix::fs::symlink(rel, d.join(&sym)).expect("symlink");
    std::fs::hard_link(d.join(rel), d.join(&hard)).expect("hard link");
    vec![sym, hard]
}

fn input_path(placeholder: &str) -> String {
    placeholder
        .replace("{C}", "in/c.csv")
        .replace("{S}", "in/s.csv")
        .replace("{K}", "in/k.csv")
        .replace("{M}", "in/m.npy")
}

/// The binary refuses every aliased output of every command, naming the flag, and
/// leaves the work directory as it was.
#[cfg(unix)]
#[test]
fn no_command_accepts_an_output_that_is_one_of_its_inputs() {
    let work = workdir();
    let d = work.path();
    let mut rng = rng(36);
    let mut cases = 0;
    let mut failures = Vec::new();
    for (ci, cmd) in CMDS.iter().enumerate() {
        for flag in cmd.outputs {
            let targets: Vec<String> = if *flag == "--out" && cmd.args[0] == "reproduce" {
                spellings(d, "in", &mut rng, 3)
            } else {
                let mut t = Vec::new();
                for (k, inp) in cmd.inputs.iter().enumerate() {
                    let rel = input_path(inp);
                    t.extend(spellings(d, &rel, &mut rng, 3));
                    t.extend(links(
                        d,
                        &rel,
                        &format!("{ci}-{k}-{}", flag.trim_start_matches('-')),
                    ));
                }
                t
            };
            for out in targets {
                let before = snapshot(d);
                let mut args: Vec<String> = cmd.args.iter().map(|a| input_path(a)).collect();
                args.extend([flag.to_string(), out.clone()]);
                if *flag != cmd.required.0 {
                    args.extend([cmd.required.0.to_string(), cmd.required.1.to_string()]);
                }
                let a: Vec<&str> = args.iter().map(String::as_str).collect();
                let o = run(d, &a);
                cases += 1;
                let e = text(&o.stderr);
                let after = snapshot(d);
                if o.status.code() != Some(1) || e.contains("panicked") || !e.contains(flag) {
                    failures.push(format!("{a:?}: {:?}: {e}", o.status));
                } else if before != after {
                    let changed: Vec<_> = after
                        .iter()
                        .filter(|(k, v)| before.get(*k) != Some(*v))
                        .map(|(k, _)| k)
                        .collect();
                    failures.push(format!("{a:?}: the work directory changed: {changed:?}"));
                }
            }
        }
    }
    eprintln!("{cases} aliased outputs refused");
    assert!(
        failures.is_empty(),
        "{} of {cases}:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

/// [`OutputPlan`] refuses, for file inputs, directory inputs and a saved matrix (with its
/// sidecar), every spelling and link of an input as a file output, a `.binary`, `.bsdf`
/// or `.npy` inside an input directory, and a tree (`reproduce --out`) holding an input;
/// a fresh name beside them is accepted (the check is not a blanket refusal).
#[cfg(unix)]
#[test]
fn output_plans_refuse_inputs_under_every_spelling() {
    let work = workdir();
    let d = work.path();
    let i = d.join("in");
    std::fs::create_dir(i.join("coll")).expect("mkdir");
    write(&i.join("coll"), "m.binary", b"not read here");
    let mut rng = rng(3636);
    let mut cases = 0;
    for round in 0..4 {
        let mut plan = OutputPlan::new(&[i.join("c.csv"), i.join("coll")]);
        plan.input_named(&i.join("s.csv"), "samples file");
        plan.input_named(&i.join("m.npy"), "distance matrix");
        for rel in ["in/c.csv", "in/s.csv", "in/m.npy", "in/m.names.json"] {
            let mut all = spellings(d, rel, &mut rng, 8);
            all.extend(links(d, rel, &format!("p{round}")));
            for s in all {
                cases += 1;
                assert!(plan.file(&d.join(&s), "--out").is_err(), "{s} accepted");
            }
        }
        for inside in ["m2.binary", "x.npy", "y.BSDF"] {
            for s in spellings(d, "in", &mut rng, 4) {
                let s = format!("{}/coll/{inside}", s.trim_end_matches('/'));
                cases += 1;
                assert!(plan.file(&d.join(&s), "--out").is_err(), "{s} accepted");
            }
        }
        for s in spellings(d, "in", &mut rng, 4) {
            cases += 1;
            let r = plan.tree(&d.join(&s), "--out", true, |_| true);
            assert!(r.is_err(), "tree {s} accepted");
        }
        assert!(plan
            .file(&i.join(format!("fresh{round}.json")), "--json")
            .is_ok());
    }
    eprintln!("{cases} aliased outputs refused by the plan");
}
