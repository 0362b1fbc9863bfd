//! The output layer (issue 15, design item 1), driven through the binary: every
//! subcommand through the same table of hostile output paths, an interrupted
//! `reproduce`, the runtime directory of `--help`, stale exports, foreign sidecars.

use crate::common::*;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

const CSV: &str = "material,d_r,d_g,d_b,s_r,s_g,s_b,F0,n\n\
m1,0.2,0.1,0.1,0.5,0.5,0.5,0.5,50\n\
m2,0.1,0.3,0.1,0.4,0.5,0.6,0.9,100\n\
m3,0.3,0.2,0.1,0.6,0.5,0.4,0.2,20\n\
m4,0.05,0.05,0.3,0.3,0.3,0.3,0.7,300\n\
m5,0.4,0.4,0.4,0.2,0.2,0.2,0.1,10\n\
m6,0.1,0.1,0.1,0.8,0.7,0.6,0.95,1000\n";

/// Runs the binary in `cwd`; panics after 60 s (a hang: e.g. a FIFO opened).
fn run_in(cwd: &Path, args: &[String]) -> Output {
    let mut cmd = bin();
    cmd.args(["--quiet", "--backend", "cpu"])
        .args(args)
        .current_dir(cwd);
    output_within(&mut cmd, Duration::from_secs(60))
        .unwrap_or_else(|| panic!("brdf-basis {args:?} hangs"))
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

/// Every entry under `dir` (not following links) with its kind and content, sorted: a
/// snapshot that any write, replacement or leftover changes.
fn snapshot(dir: &Path) -> Vec<(PathBuf, String)> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).expect("read_dir").flatten() {
            let p = e.path();
            let m = std::fs::symlink_metadata(&p).expect("lstat");
            let t = m.file_type();
            let what = if t.is_symlink() {
                format!(
                    "link -> {}",
                    std::fs::read_link(&p).expect("link").display()
                )
            } else if t.is_dir() {
                stack.push(p.clone());
                format!(
                    "dir {:o}",
                    std::os::unix::fs::PermissionsExt::mode(&m.permissions())
                )
            } else if t.is_file() {
                let bytes = std::fs::read(&p).expect("read");
                format!("file {} {:x}", bytes.len(), fnv(&bytes))
            } else {
                use std::os::unix::fs::FileTypeExt;
                format!(
                    "special char={} fifo={} rdev={}",
                    t.is_char_device(),
                    t.is_fifo(),
                    std::os::unix::fs::MetadataExt::rdev(&m)
                )
            };
            out.push((p.strip_prefix(dir).expect("under").to_path_buf(), what));
        }
    }
    out.sort();
    out
}

fn fnv(b: &[u8]) -> u64 {
    b.iter().fold(0xcbf29ce484222325u64, |h, &x| {
        (h ^ x as u64).wrapping_mul(0x100000001b3)
    })
}

/// One subcommand: its arguments with `{OUT}` (the output under test), `{OUT2}` (a
/// second output, for the duplicate row), `{IN}` (its collection or main input) and the
/// extension its output must have.
struct Cmd {
    name: &'static str,
    args: &'static [&'static str],
    /// Extension of the output (`""`: a directory, `reproduce`).
    ext: &'static str,
    /// Flag naming `{OUT}`.
    flag: &'static str,
    /// Arguments of the duplicate row (two outputs on `{OUT}`) and the two flags its
    /// message must name.
    dup: Option<(&'static [&'static str], [&'static str; 2])>,
}

const CMDS: &[Cmd] = &[
    Cmd {
        name: "tabulate",
        args: &["tabulate", "{IN}", "--material", "m1", "--out", "{OUT}"],
        ext: "binary",
        flag: "--out",
        dup: None,
    },
    Cmd {
        name: "distance",
        args: &["distance", "{IN}", "--stride", "16", "--out", "{OUT}"],
        ext: "npy",
        flag: "--out",
        dup: None,
    },
    Cmd {
        name: "select",
        args: &[
            "select", "{IN}", "--method", "kmedoids", "-k", "2", "--runs", "2", "--stride", "16",
            "--json", "{OUT}",
        ],
        ext: "json",
        flag: "--json",
        dup: None,
    },
    Cmd {
        name: "fit",
        args: &[
            "fit",
            "{IN}",
            "--basis",
            "m1,m2",
            "--targets",
            "m3",
            "--stride",
            "16",
            "--json",
            "{OUT}",
        ],
        ext: "json",
        flag: "--json",
        dup: Some((
            &[
                "fit",
                "{IN}",
                "--basis",
                "m1,m2",
                "--targets",
                "m3",
                "--stride",
                "16",
                "--json",
                "{OUT}",
                "--export",
                "{OUT}",
            ],
            ["--json", "--export"],
        )),
    },
    Cmd {
        name: "render",
        args: &[
            "render",
            "{IN}",
            "--material",
            "m1",
            "--size",
            "8",
            "--out",
            "{OUT}",
        ],
        ext: "exr",
        flag: "--out",
        dup: Some((
            &[
                "render",
                "{IN}",
                "--material",
                "m3",
                "--size",
                "8",
                "--fit",
                "f.json",
                "--out",
                "r.exr",
                "--png",
                "{OUT}",
                "--heatmap",
                "{OUT}",
            ],
            ["--png", "--heatmap"],
        )),
    },
    Cmd {
        name: "reproduce",
        args: &[
            "reproduce",
            "--no-appearance",
            "{IN}",
            "--runs",
            "1",
            "--stride",
            "16",
            "--k-min",
            "2",
            "--k-max",
            "2",
            "--gcuk-k-max",
            "3",
            "--render-size",
            "8",
            "--cv-folds",
            "0",
            "--no-selection",
            "--out",
            "{OUT}",
        ],
        ext: "",
        flag: "--out",
        dup: None,
    },
    Cmd {
        name: "cv",
        args: &[
            "cv",
            "{IN}",
            "--methods",
            "kmedoids",
            "-k",
            "2",
            "--folds",
            "2",
            "--runs",
            "1",
            "--stride",
            "16",
            "--render-size",
            "8",
            "--json",
            "{OUT}",
        ],
        ext: "json",
        flag: "--json",
        dup: Some((
            &[
                "cv",
                "{IN}",
                "--methods",
                "kmedoids",
                "-k",
                "2",
                "--folds",
                "2",
                "--runs",
                "1",
                "--stride",
                "16",
                "--render-size",
                "8",
                "--json",
                "{OUT}",
                "--markdown",
                "{OUT}",
            ],
            ["--json", "--markdown"],
        )),
    },
    Cmd {
        name: "plan",
        args: &[
            "plan",
            "{IN}",
            "--basis",
            "m1,m2",
            "-n",
            "3",
            "--criterion",
            "condition",
            "--candidates-per-step",
            "50",
            "--out",
            "{OUT}",
        ],
        ext: "csv",
        flag: "--out",
        dup: Some((
            &[
                "plan",
                "{IN}",
                "--basis",
                "m1,m2",
                "-n",
                "3",
                "--criterion",
                "condition",
                "--candidates-per-step",
                "50",
                "--out",
                "{OUT}",
                "--json",
                "{OUT}",
            ],
            ["--out", "--json"],
        )),
    },
    Cmd {
        name: "plot",
        args: &["plot", "{IN}", "--material", "m1", "--out", "{OUT}"],
        ext: "svg",
        flag: "--out",
        dup: None,
    },
    Cmd {
        name: "merge",
        args: &["merge", "t1.npy", "t2.npy", "--out", "{OUT}"],
        ext: "npy",
        flag: "--out",
        dup: None,
    },
];

/// A work directory with the collection `c.csv`, a `fit` JSON `f.json` and the two tiles
/// of its matrix `t1.npy`, `t2.npy` (with sidecars), copied from one made once.
fn workdir() -> tempfile::TempDir {
    static TEMPLATE: std::sync::OnceLock<tempfile::TempDir> = std::sync::OnceLock::new();
    let t = TEMPLATE.get_or_init(make_workdir);
    let d = tmp();
    for e in std::fs::read_dir(t.path()).expect("ls").flatten() {
        std::fs::copy(e.path(), d.path().join(e.file_name())).expect("copy");
    }
    d
}

fn make_workdir() -> tempfile::TempDir {
    let d = tmp();
    std::fs::write(d.path().join("c.csv"), CSV).expect("write");
    let ok = |args: &[&str]| {
        let o = run_in(
            d.path(),
            &args.iter().map(|s| s.to_string()).collect::<Vec<_>>(),
        );
        assert!(o.status.success(), "{args:?}: {}", text(&o.stderr));
    };
    ok(&[
        "fit",
        "c.csv",
        "--basis",
        "m1,m2",
        "--targets",
        "m3",
        "--stride",
        "16",
        "--json",
        "f.json",
    ]);
    for t in ["1", "2"] {
        ok(&[
            "distance",
            "c.csv",
            "--stride",
            "16",
            "--band-rows",
            "4",
            "--tile",
            &format!("{t}/2"),
            "--out",
            &format!("t{t}.npy"),
        ]);
    }
    d
}

fn is_root() -> bool {
    // SAFETY: geteuid has no preconditions and cannot fail.
    unsafe { libc::geteuid() == 0 }
}

/// A directory where creating a file fails even as root: `/sys` (sysfs) as root, a
/// mode-0555 directory otherwise; `None` (with a message) when neither refuses.
fn unwritable_dir(work: &Path) -> Option<PathBuf> {
    let d = if is_root() {
        PathBuf::from("/sys")
    } else {
        let d = work.join("ro");
        std::fs::create_dir(&d).expect("mkdir");
        std::fs::set_permissions(&d, std::os::unix::fs::PermissionsExt::from_mode(0o555))
            .expect("chmod");
        d
    };
    let probe = d.join("brdf-basis-outputs-probe");
    if std::fs::write(&probe, "x").is_ok() {
        let _ = std::fs::remove_file(&probe);
        eprintln!(
            "SKIP unwritable-parent row: {} is writable here",
            d.display()
        );
        return None;
    }
    Some(d)
}

/// A hostile output: how to make it, relative to the work directory.
enum Hostile {
    Device,
    Fifo,
    Directory,
    LinkToInput,
    Input,
    MissingParent,
    Unwritable,
    Duplicate,
}

const ROWS: &[(&str, Hostile)] = &[
    ("device node", Hostile::Device),
    ("FIFO", Hostile::Fifo),
    ("directory", Hostile::Directory),
    ("symlink to an input", Hostile::LinkToInput),
    ("an input", Hostile::Input),
    ("missing parent", Hostile::MissingParent),
    ("unwritable parent", Hostile::Unwritable),
    ("two outputs on one path", Hostile::Duplicate),
];

/// Sets up `row` for `cmd` in `work`; returns `(output path, input argument)`, or `None`
/// when the row does not apply (printed).
fn set_up(cmd: &Cmd, row: &Hostile, work: &Path) -> Option<(String, String)> {
    let name = |stem: &str| {
        if cmd.ext.is_empty() {
            stem.to_string()
        } else {
            format!("{stem}.{}", cmd.ext)
        }
    };
    let input = if cmd.name == "merge" {
        "t1.npy"
    } else {
        "c.csv"
    };
    match row {
        Hostile::Device => {
            let p = name("dev");
            let st = Command::new("mknod")
                .arg(work.join(&p))
                .args(["c", "1", "3"])
                .stderr(Stdio::null())
                .status();
            if !st.is_ok_and(|s| s.success()) {
                eprintln!("SKIP device row of {}: mknod failed (not root?)", cmd.name);
                return None;
            }
            Some((p, "c.csv".into()))
        }
        Hostile::Fifo => {
            let p = name("fifo");
            let st = Command::new("mkfifo")
                .arg(work.join(&p))
                .status()
                .expect("mkfifo");
            assert!(st.success());
            Some((p, "c.csv".into()))
        }
        Hostile::Directory => {
            let p = name("dir");
            std::fs::create_dir(work.join(&p)).expect("mkdir");
            std::fs::write(work.join(&p).join("keep"), "mine").expect("write");
            Some((p, "c.csv".into()))
        }
        Hostile::LinkToInput => {
            let p = name("link");
            std::os::unix::fs::symlink(input, work.join(&p)).expect("symlink");
            Some((p, "c.csv".into()))
        }
        Hostile::Input => match cmd.name {
            "merge" => Some(("./t2.npy".into(), "c.csv".into())),
            "render" | "plot" | "tabulate" => {
                // A fixed extension: a directory collection of that name (tabulate: a
                // .binary inside it).
                let dir = name("coll");
                std::fs::create_dir(work.join(&dir)).expect("mkdir");
                let o = run_in(
                    work,
                    &[
                        "tabulate".into(),
                        "c.csv".into(),
                        "--material".into(),
                        "m1".into(),
                        "--out".into(),
                        format!("{dir}/m1.binary"),
                    ],
                );
                assert!(o.status.success(), "{}", text(&o.stderr));
                let out = if cmd.name == "tabulate" {
                    format!("{dir}/m1.binary")
                } else {
                    dir.clone()
                };
                Some((out, format!("{dir}/")))
            }
            // The output takes any name (or is a directory): the collection file itself.
            _ => Some(("./c.csv".into(), "c.csv".into())),
        },
        Hostile::MissingParent => Some((
            if cmd.ext.is_empty() {
                "nope/a/b".into()
            } else {
                format!("nope/{}", name("x"))
            },
            "c.csv".into(),
        )),
        Hostile::Unwritable => {
            let d = unwritable_dir(work)?;
            Some((d.join(name("x")).display().to_string(), "c.csv".into()))
        }
        Hostile::Duplicate => {
            if cmd.dup.is_none() {
                eprintln!("n/a duplicate row of {}: a single output", cmd.name);
                return None;
            }
            // render's two outputs here are its PNGs (--png, --heatmap).
            let same = if cmd.name == "render" {
                "same.png".to_string()
            } else {
                name("same")
            };
            Some((same, "c.csv".into()))
        }
    }
}

/// Runs one row; returns a description of what went wrong, if anything.
fn check_row(cmd: &Cmd, label: &str, row: &Hostile) -> Option<String> {
    let work = workdir();
    let (out, input) = set_up(cmd, row, work.path())?;
    let before = snapshot(work.path());
    let (template, flags) = match row {
        Hostile::Duplicate => {
            let (args, flags) = cmd.dup.expect("dup");
            (args, flags.to_vec())
        }
        _ => (cmd.args, vec![cmd.flag]),
    };
    let args: Vec<String> = template
        .iter()
        .map(|a| a.replace("{OUT}", &out).replace("{IN}", &input))
        .collect();
    let o = run_in(work.path(), &args);
    let err = text(&o.stderr);
    let after = snapshot(work.path());
    let base = Path::new(&out)
        .file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let mut problems = Vec::new();
    if o.status.success() {
        problems.push("exit 0".to_string());
    }
    if err.contains("panicked") {
        problems.push("panic".into());
    }
    if !flags.iter().all(|f| err.contains(f)) || !err.contains(&base) {
        problems.push(format!("message does not name {flags:?} and `{base}`"));
    }
    if before != after {
        problems.push(format!(
            "the work directory changed:\n  before {before:?}\n  after  {after:?}"
        ));
    }
    if !problems.is_empty() {
        return Some(format!(
            "{} / {label} ({}): {}; stderr: {}",
            cmd.name,
            args.join(" "),
            problems.join("; "),
            err.trim()
        ));
    }
    None
}

#[cfg(unix)]
#[test]
fn every_subcommand_refuses_every_hostile_output_path() {
    let mut failures = Vec::new();
    for cmd in CMDS {
        for (label, row) in ROWS {
            failures.extend(check_row(cmd, label, row));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n\n"));
}

/// `info` writes no file: it takes no output option, and leaves the work directory as it
/// was (the row table does not apply).
#[test]
fn info_writes_nothing() {
    let work = tmp();
    let before = snapshot(work.path());
    let o = run_in(work.path(), &["info".into()]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let o = run_in(work.path(), &["info".into(), "--out".into(), "x".into()]);
    assert!(!o.status.success());
    assert_eq!(snapshot(work.path()), before);
}

/// `distance m.csv --out m.csv` used to overwrite its input (exit 0).
#[test]
fn distance_never_overwrites_its_input() {
    let work = tmp();
    std::fs::write(work.path().join("m.csv"), CSV).expect("write");
    let o = run_in(
        work.path(),
        &["distance", "m.csv", "--stride", "16", "--out", "m.csv"].map(String::from),
    );
    assert!(!o.status.success());
    assert!(text(&o.stderr).contains("would overwrite the input collection m.csv"));
    assert_eq!(
        std::fs::read_to_string(work.path().join("m.csv")).expect("read"),
        CSV
    );
}

/// `distance --out x.npy` replaces an earlier sidecar of ours but never a user's
/// `x.names.json`.
#[test]
fn a_sidecar_replaces_only_a_sidecar() {
    let work = tmp();
    std::fs::write(work.path().join("c.csv"), CSV).expect("write");
    std::fs::write(work.path().join("x.names.json"), "{\"mine\": true}\n").expect("write");
    let args = ["distance", "c.csv", "--stride", "16", "--out", "x.npy"].map(String::from);
    let o = run_in(work.path(), &args);
    let e = text(&o.stderr);
    assert!(!o.status.success(), "{e}");
    assert!(
        e.contains("x.names.json") && e.contains("not a matrix sidecar"),
        "{e}"
    );
    assert!(!work.path().join("x.npy").exists());
    assert_eq!(
        std::fs::read_to_string(work.path().join("x.names.json")).expect("read"),
        "{\"mine\": true}\n"
    );
    std::fs::remove_file(work.path().join("x.names.json")).expect("rm");
    for _ in 0..2 {
        // The second run replaces the pair it wrote first.
        let o = run_in(work.path(), &args);
        assert!(o.status.success(), "{}", text(&o.stderr));
        let out = text(&o.stdout);
        assert!(
            out.contains("wrote x.npy") && out.contains("wrote x.names.json"),
            "{out}"
        );
    }
    let mut names: Vec<String> = std::fs::read_dir(work.path())
        .expect("ls")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names, ["c.csv", "x.names.json", "x.npy"]);
}

/// `fit --export DIR` into an earlier export: the files the earlier index listed and
/// this export does not write are removed; files the command does not own are kept, and
/// never replaced.
#[test]
fn an_export_replaces_an_earlier_export_and_nothing_else() {
    let work = tmp();
    std::fs::write(work.path().join("c.csv"), CSV).expect("write");
    let fit = |targets: &str| {
        run_in(
            work.path(),
            &[
                "fit",
                "c.csv",
                "--basis",
                "m1,m2",
                "--targets",
                targets,
                "--stride",
                "16",
                "--json",
                "f.json",
                "--export",
                "out",
            ]
            .map(String::from),
        )
    };
    let o = fit("m3,m4,m5");
    assert!(o.status.success(), "{}", text(&o.stderr));
    std::fs::write(work.path().join("out/notes.txt"), "mine").expect("write");
    let o = fit("m3");
    assert!(o.status.success(), "{}", text(&o.stderr));
    // Audit 2, U10: what the export removed is said, not done silently.
    let said = text(&o.stdout);
    for gone in ["m4.binary", "m5.binary"] {
        let line = format!(
            "removed {}",
            std::path::Path::new("out").join(gone).display()
        );
        assert!(said.contains(&line), "{said}");
    }
    assert!(!said.contains("removed out/m3"), "{said}");
    let mut names: Vec<String> = std::fs::read_dir(work.path().join("out"))
        .expect("ls")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names, ["index.csv", "m3.binary", "notes.txt"]);
    let index = std::fs::read_to_string(work.path().join("out/index.csv")).expect("index");
    assert_eq!(index, "material,file\nm3,m3.binary\n");
    // A .binary the index does not list is a user's file: refused, not replaced.
    std::fs::write(work.path().join("out/m6.binary"), "mine").expect("write");
    let o = fit("m6");
    let e = text(&o.stderr);
    assert!(!o.status.success());
    assert!(e.contains("m6.binary") && e.contains("--export"), "{e}");
    assert_eq!(
        std::fs::read_to_string(work.path().join("out/m6.binary")).expect("read"),
        "mine"
    );
    assert!(work.path().join("out/m3.binary").exists());
}

/// `reproduce --out FILE` and `--out /nonexistent/a/b`: refused with a plain message,
/// nothing created.
#[test]
fn reproduce_refuses_a_file_and_a_missing_parent() {
    let work = tmp();
    std::fs::write(work.path().join("file"), "mine").expect("write");
    let args = |out: &str| {
        [
            "reproduce",
            "--no-appearance",
            "--runs",
            "1",
            "--stride",
            "16",
            "--out",
            out,
        ]
        .map(String::from)
    };
    let o = run_in(work.path(), &args("file"));
    let e = text(&o.stderr);
    assert!(!o.status.success());
    assert!(e.contains("--out") && e.contains("not a directory"), "{e}");
    assert!(!e.contains("os error 17"), "{e}");
    let o = run_in(work.path(), &args("nope/a/b"));
    let e = text(&o.stderr);
    assert!(!o.status.success());
    assert!(e.contains("nope/a") && e.contains("does not exist"), "{e}");
    assert!(!work.path().join("nope").exists());
}

/// `--help`, `--version` and a usage error leave no `brdf-basis-runtime-PID` directory.
#[test]
fn help_and_usage_errors_leave_no_runtime_directory() {
    let tmpdir = tmp();
    for args in [
        &["--help"][..],
        &["--version"],
        &["no-such-command"],
        &["info"],
    ] {
        let o = bin()
            .args(args)
            .env_remove("XDG_RUNTIME_DIR")
            .env("TMPDIR", tmpdir.path())
            .output()
            .expect("run");
        let left: Vec<_> = std::fs::read_dir(tmpdir.path())
            .expect("ls")
            .map(|e| e.expect("entry").file_name())
            .collect();
        assert!(
            left.is_empty(),
            "{args:?} left {left:?}: {}",
            text(&o.stderr)
        );
    }
}

/// SIGTERM while `reproduce` writes its files: exit 130, nothing left (not the directory
/// it created, no hidden file), and the plain rerun then works; its matrices carry their
/// sidecar, so `select --distances` reads them.
#[cfg(unix)]
#[test]
fn an_interrupted_reproduce_leaves_nothing_and_a_rerun_works() {
    let work = tmp();
    let args = [
        "--quiet",
        "--backend",
        "cpu",
        "reproduce",
        "--no-appearance",
        "--runs",
        "2",
        "--stride",
        "8",
        "--render-size",
        "24",
        "--cv-folds",
        "0",
        "--no-selection",
        "--out",
        "r",
    ];
    let mut caught = false;
    for attempt in 0..3 {
        let mut child = bin()
            .args(args)
            .current_dir(work.path())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("spawn");
        let start = Instant::now();
        let mut signalled = false;
        while child.try_wait().expect("wait").is_none() {
            let files = count_files(&work.path().join("r"));
            if files >= 3 {
                let st = Command::new("kill")
                    .args(["-TERM", &child.id().to_string()])
                    .status()
                    .expect("kill");
                assert!(st.success());
                signalled = true;
                break;
            }
            assert!(
                start.elapsed() < Duration::from_secs(120),
                "no file written"
            );
            std::thread::sleep(Duration::from_millis(1));
        }
        let o = child.wait_with_output().expect("wait");
        if !signalled {
            eprintln!("attempt {attempt}: finished before the signal");
            std::fs::remove_dir_all(work.path().join("r")).expect("rm");
            continue;
        }
        assert_eq!(o.status.code(), Some(130), "{}", text(&o.stderr));
        assert!(
            snapshot(work.path()).is_empty(),
            "left behind: {:?}",
            snapshot(work.path())
        );
        caught = true;
        break;
    }
    assert!(caught, "reproduce always finished before the signal");
    let o = bin()
        .args(args)
        .current_dir(work.path())
        .output()
        .expect("rerun");
    assert!(o.status.success(), "{}", text(&o.stderr));
    let out = text(&o.stdout);
    assert!(out.contains("wrote r/report.md"), "{out}");
    let top: Vec<String> = snapshot(work.path())
        .into_iter()
        .map(|(p, _)| p.display().to_string())
        .filter(|p| p.starts_with("r/.") || p.contains("/.brdf-basis") || p.contains(".tmp-"))
        .collect();
    assert!(top.is_empty(), "hidden leftovers: {top:?}");
    let o = bin()
        .args(["--quiet", "select", "--distances", "r/distance-brdf-it.npy"])
        .args([
            "--method", "kmedoids", "-k", "2", "--runs", "2", "--json", "s.json",
        ])
        .current_dir(work.path())
        .output()
        .expect("select");
    assert!(o.status.success(), "{}", text(&o.stderr));
}

/// Regular files under `dir`, recursively (0 when it does not exist).
fn count_files(dir: &Path) -> usize {
    let Ok(rd) = std::fs::read_dir(dir) else {
        return 0;
    };
    rd.flatten()
        .map(|e| {
            let p = e.path();
            if p.is_dir() {
                count_files(&p)
            } else {
                1
            }
        })
        .sum()
}

/// `plan` replaces a regular file it wrote before (atomically: nothing else appears in the
/// directory), and its CSV is the samples-file header plus one row per sample.
#[test]
fn plan_replaces_its_earlier_output_and_leaves_nothing_else() {
    let work = tmp();
    std::fs::write(work.path().join("c.csv"), CSV).expect("write");
    let args: Vec<String> = [
        "plan",
        "c.csv",
        "--basis",
        "m1,m2",
        "-n",
        "3",
        "--criterion",
        "condition",
        "--candidates-per-step",
        "50",
        "--out",
        "p.csv",
        "--json",
        "p.json",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    let o = run_in(work.path(), &args);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let first = std::fs::read_to_string(work.path().join("p.csv")).expect("csv");
    assert!(
        first.starts_with("theta_i,phi_i,theta_o,phi_o\n"),
        "{first}"
    );
    assert_eq!(first.lines().count(), 4, "{first}");
    let o = run_in(work.path(), &args);
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert_eq!(
        std::fs::read_to_string(work.path().join("p.csv")).expect("csv"),
        first
    );
    let names: Vec<String> = snapshot(work.path())
        .into_iter()
        .map(|(p, _)| p.display().to_string())
        .collect();
    assert_eq!(names, ["c.csv", "p.csv", "p.json"], "{names:?}");
    // The peer baseline is cv --acquisition's, not plan's (SPEC-cli lists three criteria).
    let mut bad = args.clone();
    bad[7] = "nielsen".into();
    let o = run_in(work.path(), &bad);
    assert!(!o.status.success());
    assert!(
        text(&o.stderr).contains("cv --acquisition"),
        "{}",
        text(&o.stderr)
    );
}

/// Issue 36, N1-N3: an output that names a file the command reads besides the collection
/// (plan's candidates, fit's samples), under another spelling too, or that would add a
/// file the collection reads to an input directory, is refused before any work, and the
/// inputs stay byte-identical.
#[test]
fn outputs_never_replace_candidates_samples_or_files_of_an_input_directory() {
    let dir = workdir();
    let d = dir.path();
    let coll = write(d, "c.csv", CSV);
    let samples = write(
        d,
        "s.csv",
        "theta_i,phi_i,theta_o,phi_o,r,g,b\n10,0,20,180,0.1,0.1,0.1\n30,0,40,180,0.2,0.2,0.2\n",
    );
    let before = |p: &Path| std::fs::read(p).expect("input");
    let refused = |args: &[&str], input: &Path, noun: &str| {
        let keep = before(input);
        let o = bin_quiet().current_dir(d).args(args).output().expect("run");
        let err = String::from_utf8_lossy(&o.stderr).to_string();
        assert!(!o.status.success(), "{args:?} was accepted");
        assert!(err.contains(noun), "{args:?}: {err}");
        assert_eq!(before(input), keep, "{args:?} changed {}", input.display());
    };
    let c = coll.to_str().expect("utf-8");
    // N1: plan's candidates file, as --out and --json, under two spellings.
    for out in ["s.csv", "./s.csv"] {
        refused(
            &[
                "plan",
                c,
                "--basis",
                "m1,m2",
                "-n",
                "2",
                "--candidates",
                "s.csv",
                "--out",
                out,
            ],
            &samples,
            "candidates file",
        );
        refused(
            &[
                "plan",
                c,
                "--basis",
                "m1,m2",
                "-n",
                "2",
                "--candidates",
                "s.csv",
                "--out",
                "p.csv",
                "--json",
                out,
            ],
            &samples,
            "candidates file",
        );
    }
    // N2: fit --samples writing its JSON over the samples file.
    for out in ["s.csv", "./s.csv"] {
        refused(
            &[
                "fit",
                c,
                "--basis",
                "m1,m2",
                "--samples",
                "s.csv",
                "--json",
                out,
            ],
            &samples,
            "samples file",
        );
    }
    // N3: a .npy (or .bsdf, .binary) written into an input directory the collection reads.
    let cdir = d.join("coll");
    std::fs::create_dir(&cdir).expect("dir");
    for m in ["m1", "m2"] {
        let o = bin_quiet()
            .current_dir(d)
            .args([
                "tabulate",
                c,
                "--material",
                m,
                "--out",
                &format!("coll/{m}.binary"),
            ])
            .output()
            .expect("tabulate");
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let snap = snapshot(&cdir);
    for out in ["coll/d.npy", "coll/../coll/d.NPY", "./coll/e.npy"] {
        let o = bin_quiet()
            .current_dir(d)
            .args(["distance", "coll", "--out", out])
            .output()
            .expect("distance");
        let err = String::from_utf8_lossy(&o.stderr).to_string();
        assert!(
            !o.status.success() && err.contains("input collection directory"),
            "{out}: {err}"
        );
        assert_eq!(snapshot(&cdir), snap, "{out} changed the directory");
    }
    // Beside the directory, the same command is fine.
    let o = bin_quiet()
        .current_dir(d)
        .args(["distance", "coll", "--out", "d.npy"])
        .output()
        .expect("distance");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}
