//! Slurm, live: a one-node cluster on localhost (munged, slurmctld, slurmd from Debian's
//! packages, a private `slurm.conf` in a temporary directory) runs the repository's
//! scripts `scripts/slurm/distance-array.sbatch` (the tile array, two tiles per task) and
//! `scripts/slurm/merge.sbatch` (after `--dependency=afterok`); the merged matrix and
//! sidecar equal the whole matrix byte for byte. A second submission whose tile 5 cannot
//! be written fails one array task, and the merge never runs; the test names the tile.
//!
//! Needs root and the packages `slurmctld slurmd munge` (`.ci/run` installs them). Outside
//! CI without them it prints `SKIP (no Slurm)`; with `CI=true` it must run.

use crate::common::*;
use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// Tiles of the test matrix, and array tasks computing them (two tiles each).
const TILES: usize = 6;
const TASKS: usize = 3;
/// Options of every `distance` run (small: the embedded collection on a coarse grid).
const OPTS: &str = "--stride 6 --band-rows 8";
/// Bound on the wait for one submission (daemons up, array and merge done).
const WAIT: Duration = Duration::from_secs(240);

/// A program from PATH or the system binary directories.
fn find(name: &str) -> Option<PathBuf> {
    let path = std::env::var_os("PATH").unwrap_or_default();
    std::env::split_paths(&path)
        .chain(["/usr/sbin", "/sbin", "/usr/bin"].map(PathBuf::from))
        .map(|d| d.join(name))
        .find(|p| p.is_file())
}

fn is_root() -> bool {
    Command::new("id")
        .arg("-u")
        .output()
        .is_ok_and(|o| String::from_utf8_lossy(&o.stdout).trim() == "0")
}

/// The daemons and clients, or `None` after printing why the test skips (a failure
/// with `CI=true`).
fn slurm_or_skip(test: &str) -> Option<()> {
    let ci = std::env::var("CI").is_ok_and(|v| v == "true");
    let missing: Vec<&str> = [
        "slurmctld",
        "slurmd",
        "sbatch",
        "squeue",
        "scontrol",
        "munged",
    ]
    .into_iter()
    .filter(|p| find(p).is_none())
    .collect();
    let why = if !missing.is_empty() {
        format!(
            "{} not installed (apt-get install slurmctld slurmd munge)",
            missing.join(", ")
        )
    } else if !is_root() {
        "the daemons must start as root".into()
    } else {
        return Some(());
    };
    if ci {
        panic!("CI=true but the live Slurm test cannot run: {why}");
    }
    eprintln!("SKIP (no Slurm) {test}: {why}");
    None
}

/// A free TCP port on localhost (bound then released).
fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .expect("a free port")
        .port()
}

/// Asks a process to stop (SIGTERM), waits up to 10 s, then kills it.
fn stop(child: &mut Child) {
    let _ = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status();
    let start = Instant::now();
    while start.elapsed() < Duration::from_secs(10) {
        if let Ok(Some(_)) = child.try_wait() {
            return;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    let _ = child.kill();
    let _ = child.wait();
}

/// A running one-node cluster; dropping it stops the daemons it started (munged only if
/// it was not already running).
struct Cluster {
    dir: PathBuf,
    conf: PathBuf,
    daemons: Vec<(&'static str, Child)>,
}

impl Drop for Cluster {
    fn drop(&mut self) {
        // slurmd, then slurmctld, then munged: the reverse of the start.
        while let Some((_, mut c)) = self.daemons.pop() {
            stop(&mut c);
        }
    }
}

fn munge_works() -> bool {
    let Some(munge) = find("munge") else {
        return false;
    };
    Command::new(munge)
        .arg("-n")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

fn wait_for(what: &str, limit: Duration, mut ok: impl FnMut() -> bool) {
    let start = Instant::now();
    while !ok() {
        assert!(
            start.elapsed() < limit,
            "{what}: not within {} s",
            limit.as_secs()
        );
        std::thread::sleep(Duration::from_millis(250));
    }
}

impl Cluster {
    fn start(dir: &Path) -> Cluster {
        std::fs::create_dir_all(dir).expect("cluster dir");
        let mut c = Cluster {
            dir: dir.to_path_buf(),
            conf: dir.join("slurm.conf"),
            daemons: Vec::new(),
        };
        if !munge_works() {
            if !Path::new("/etc/munge/munge.key").exists() {
                let st = Command::new("runuser")
                    .args(["-u", "munge", "--", "mungekey", "--create"])
                    .status()
                    .expect("mungekey");
                assert!(st.success(), "mungekey --create failed");
            }
            let st = Command::new("install")
                .args([
                    "-d",
                    "-o",
                    "munge",
                    "-g",
                    "munge",
                    "-m",
                    "0755",
                    "/run/munge",
                ])
                .status()
                .expect("install /run/munge");
            assert!(st.success(), "cannot create /run/munge");
            let munged = Command::new("runuser")
                .args(["-u", "munge", "--"])
                .arg(find("munged").expect("munged"))
                .arg("--foreground")
                .stdout(Stdio::null())
                .stderr(std::fs::File::create(dir.join("munged.err")).expect("log"))
                .spawn()
                .expect("start munged");
            c.daemons.push(("munged", munged));
            wait_for("munged answers", Duration::from_secs(20), munge_works);
        }
        // The node as slurmd sees it (`slurmd -C`), so that slurmctld never drains it.
        let node = Command::new(find("slurmd").expect("slurmd"))
            .arg("-C")
            .output()
            .expect("slurmd -C");
        let node = String::from_utf8_lossy(&node.stdout);
        let node = node
            .lines()
            .find(|l| l.starts_with("NodeName="))
            .unwrap_or_else(|| panic!("slurmd -C printed no NodeName: {node}"))
            .to_string();
        let host = node
            .split_whitespace()
            .next()
            .and_then(|w| w.strip_prefix("NodeName="))
            .expect("host")
            .to_string();
        let d = dir.display();
        for sub in ["state", "spool"] {
            std::fs::create_dir_all(dir.join(sub)).expect("dirs");
        }
        let conf = format!(
            "ClusterName=brdftest\nSlurmctldHost={host}\nSlurmUser=root\nSlurmdUser=root\n\
             AuthType=auth/munge\nSlurmctldPort={}\nSlurmdPort={}\n\
             StateSaveLocation={d}/state\nSlurmdSpoolDir={d}/spool\n\
             SlurmctldPidFile={d}/slurmctld.pid\nSlurmdPidFile={d}/slurmd.pid\n\
             SlurmctldLogFile={d}/slurmctld.log\nSlurmdLogFile={d}/slurmd.log\n\
             ProctrackType=proctrack/linuxproc\nTaskPlugin=task/none\n\
             JobAcctGatherType=jobacct_gather/none\nAccountingStorageType=accounting_storage/none\n\
             SelectType=select/cons_tres\nSelectTypeParameters=CR_Core\nReturnToService=2\n\
             MpiDefault=none\nSwitchType=switch/none\n{node} State=UNKNOWN\n\
             PartitionName=test Nodes={host} Default=YES MaxTime=INFINITE State=UP\n",
            free_port(),
            free_port()
        );
        std::fs::write(&c.conf, conf).expect("slurm.conf");
        for daemon in ["slurmctld", "slurmd"] {
            let child = Command::new(find(daemon).expect("daemon"))
                .arg("-D")
                .arg("-f")
                .arg(&c.conf)
                .env("SLURM_CONF", &c.conf)
                .stdout(Stdio::null())
                .stderr(std::fs::File::create(dir.join(format!("{daemon}.err"))).expect("log"))
                .spawn()
                .unwrap_or_else(|e| panic!("start {daemon}: {e}"));
            c.daemons.push((daemon, child));
            if daemon == "slurmctld" {
                wait_for("slurmctld answers", Duration::from_secs(30), || {
                    c.client("scontrol")
                        .arg("ping")
                        .output()
                        .is_ok_and(|o| String::from_utf8_lossy(&o.stdout).contains("UP"))
                });
            }
        }
        wait_for("the node is idle", Duration::from_secs(60), || {
            c.client("sinfo")
                .args(["-h", "-o", "%T"])
                .output()
                .is_ok_and(|o| String::from_utf8_lossy(&o.stdout).trim() == "idle")
        });
        c
    }

    fn client(&self, name: &str) -> Command {
        let mut cmd = Command::new(find(name).unwrap_or_else(|| name.into()));
        cmd.env("SLURM_CONF", &self.conf);
        cmd
    }

    fn log_tail(&self) -> String {
        let mut s = String::new();
        for f in ["slurmctld.log", "slurmd.log", "slurmctld.err", "slurmd.err"] {
            let t = std::fs::read_to_string(self.dir.join(f)).unwrap_or_default();
            let lines: Vec<&str> = t.lines().collect();
            let from = lines.len().saturating_sub(15);
            s += &format!("--- {f}\n{}\n", lines[from..].join("\n"));
        }
        s
    }

    /// `sbatch --parsable` of `script` in `work` with `env`; the job id.
    fn sbatch(
        &self,
        work: &Path,
        args: &[String],
        script: &Path,
        env: &[(&str, String)],
    ) -> String {
        let mut cmd = self.client("sbatch");
        cmd.arg("--parsable")
            .arg(format!("--chdir={}", work.display()));
        cmd.args(args).arg(script);
        for (k, v) in env {
            cmd.env(k, v);
        }
        let o = cmd.output().expect("sbatch");
        assert!(
            o.status.success(),
            "sbatch {}: {}\n{}",
            script.display(),
            String::from_utf8_lossy(&o.stderr),
            self.log_tail()
        );
        let id = String::from_utf8_lossy(&o.stdout).trim().to_string();
        id.split(';').next().expect("id").to_string()
    }

    /// Waits until none of `jobs` is pending or running.
    fn wait(&self, jobs: &[&str]) {
        let list = jobs.join(",");
        let start = Instant::now();
        loop {
            let o = self
                .client("squeue")
                .args(["-h", "-o", "%i %T %r", "-j", &list])
                .output()
                .expect("squeue");
            let text = String::from_utf8_lossy(&o.stdout).to_string();
            // A job pending on a dependency that can never be met is cancelled
            // (--kill-on-invalid-dep=yes); it leaves the queue too.
            if o.status.success() && text.trim().is_empty() {
                return;
            }
            assert!(
                start.elapsed() < WAIT,
                "jobs {list} not done within {} s:\n{text}\n{}",
                WAIT.as_secs(),
                self.log_tail()
            );
            std::thread::sleep(Duration::from_millis(500));
        }
    }

    /// `(array task id or None, state)` of every record of job `id`.
    fn states(&self, id: &str) -> Vec<(Option<usize>, String)> {
        let o = self
            .client("scontrol")
            .args(["show", "job", "-o", id])
            .output()
            .expect("scontrol");
        let field = |line: &str, key: &str| {
            line.split_whitespace()
                .find_map(|w| w.strip_prefix(key))
                .map(str::to_string)
        };
        String::from_utf8_lossy(&o.stdout)
            .lines()
            .filter(|l| l.starts_with("JobId="))
            .map(|l| {
                (
                    field(l, "ArrayTaskId=").and_then(|t| t.parse().ok()),
                    field(l, "JobState=").unwrap_or_default(),
                )
            })
            .collect()
    }
}

/// Submits the tile array and the merge in `work`; returns (array id, merge id).
fn submit(c: &Cluster, work: &Path) -> (String, String) {
    let root = crate::common::repo().join("scripts/slurm");
    let env = [
        ("TILES", TILES.to_string()),
        ("TASKS", TASKS.to_string()),
        ("TILE_DIR", "tiles".to_string()),
        ("DISTANCE_OPTS", OPTS.to_string()),
        ("OUT", "d.npy".to_string()),
        ("BRDF_BASIS", env!("CARGO_BIN_EXE_brdf-basis").to_string()),
        ("BRDF_BASIS_OPTS", "--quiet --backend cpu".to_string()),
    ];
    let array = c.sbatch(
        work,
        &[format!("--array=1-{TASKS}"), "--cpus-per-task=1".into()],
        &root.join("distance-array.sbatch"),
        &env,
    );
    let merge = c.sbatch(
        work,
        &[
            format!("--dependency=afterok:{array}"),
            "--kill-on-invalid-dep=yes".into(),
        ],
        &root.join("merge.sbatch"),
        &env,
    );
    (array, merge)
}

/// The tiles the array's output files report as failed (`tile I/N failed`), with the
/// failed tasks' output.
fn failed_tiles(work: &Path) -> (Vec<String>, String) {
    let mut tiles = Vec::new();
    let mut text = String::new();
    let mut files: Vec<PathBuf> = std::fs::read_dir(work)
        .expect("work dir")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.file_name()
                .is_some_and(|n| n.to_string_lossy().starts_with("slurm-brdf-tiles-"))
        })
        .collect();
    files.sort();
    for f in files {
        let t = std::fs::read_to_string(&f).unwrap_or_default();
        for l in t.lines() {
            // `brdf-tiles: tile 5/6 failed (array task 2)`.
            let tile = l
                .strip_prefix("brdf-tiles: tile ")
                .and_then(|rest| rest.split_once(' '))
                .filter(|(_, rest)| rest.starts_with("failed"));
            if let Some((tile, _)) = tile {
                tiles.push(tile.to_string());
                text += &format!("--- {}\n{t}\n", f.display());
            }
        }
    }
    (tiles, text)
}

/// Asserts every task of the array and the merge completed, else names the failed tiles.
fn assert_all_completed(c: &Cluster, work: &Path, array: &str, merge: &str) {
    let tasks = c.states(array);
    let merge_state = c.states(merge);
    let bad: Vec<String> = tasks
        .iter()
        .filter(|(_, s)| s != "COMPLETED")
        .map(|(t, s)| format!("array task {t:?}: {s}"))
        .collect();
    if !bad.is_empty() || merge_state.iter().any(|(_, s)| s != "COMPLETED") {
        let (tiles, out) = failed_tiles(work);
        panic!(
            "tiles failed: {tiles:?} ({}); merge: {merge_state:?}\n{out}\n{}",
            bad.join(", "),
            c.log_tail()
        );
    }
    assert_eq!(tasks.len(), TASKS, "one record per array task: {tasks:?}");
}

#[test]
fn tile_array_and_merge_on_a_live_slurm_cluster() {
    if slurm_or_skip("tile_array_and_merge_on_a_live_slurm_cluster").is_none() {
        return;
    }
    let dir = tmp();
    let cluster = Cluster::start(&dir.path().join("cluster"));
    // The whole matrix, at once, with the same options.
    let ok = dir.path().join("ok");
    std::fs::create_dir_all(&ok).expect("dir");
    let whole = ok.join("whole.npy");
    let o = bin_cpu()
        .arg("distance")
        .args(OPTS.split(' '))
        .arg("--out")
        .arg(&whole)
        .output()
        .expect("distance");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));

    let (array, merge) = submit(&cluster, &ok);
    cluster.wait(&[&array, &merge]);
    assert_all_completed(&cluster, &ok, &array, &merge);
    for i in 1..=TILES {
        assert!(ok.join(format!("tiles/t{i}.npy")).exists(), "tile {i}");
    }
    assert_eq!(
        std::fs::read(&whole).expect("whole"),
        std::fs::read(ok.join("d.npy")).expect("merged .npy"),
        "merged .npy"
    );
    assert_eq!(
        std::fs::read(ok.join("whole.names.json")).expect("whole sidecar"),
        std::fs::read(ok.join("d.names.json")).expect("merged sidecar"),
        "merged sidecar"
    );

    // Tile 5 cannot be written (a directory stands at its path): array task 2 (tiles 2
    // and 5) fails, the merge is cancelled, and the failed tile is named.
    let bad = dir.path().join("bad");
    std::fs::create_dir_all(bad.join("tiles/t5.npy")).expect("dir");
    let (array, merge) = submit(&cluster, &bad);
    cluster.wait(&[&array, &merge]);
    let (tiles, out) = failed_tiles(&bad);
    assert_eq!(tiles, vec![format!("5/{TILES}")], "the failed tile:\n{out}");
    let tasks = cluster.states(&array);
    let failed: Vec<_> = tasks.iter().filter(|(_, s)| s != "COMPLETED").collect();
    assert_eq!(
        failed,
        vec![&(Some(2), "FAILED".to_string())],
        "array task 2 (tiles 2 and 5) alone fails: {tasks:?}"
    );
    let merge_state = cluster.states(&merge);
    assert_eq!(
        merge_state
            .iter()
            .map(|(_, s)| s.as_str())
            .collect::<Vec<_>>(),
        ["CANCELLED"],
        "the merge never runs after a failed tile"
    );
    assert!(!bad.join("d.npy").exists(), "no merged matrix");
    assert!(
        bad.join("tiles/t2.npy").exists(),
        "the task's tile before the failure"
    );
    drop(cluster);
}
