//! The command line's test helpers: the binary as a command, a run with a time limit,
//! and every helper of the library's tests (tests/common/mod.rs, shared).

// Each test binary uses part of the shared helpers.
#[allow(dead_code)]
#[path = "../../../../tests/common/mod.rs"]
mod shared;
pub(crate) use shared::*;

use std::process::Command;
use std::sync::OnceLock;

/// The `brdf-basis` binary built for these tests, as a command.
pub(crate) fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_brdf-basis"))
}

/// [`bin`] with `--quiet`.
pub(crate) fn bin_quiet() -> Command {
    let mut c = bin();
    c.arg("--quiet");
    c
}

/// [`bin`] with `--quiet --backend cpu`.
pub(crate) fn bin_cpu() -> Command {
    let mut c = bin();
    c.args(["--quiet", "--backend", "cpu"]);
    c
}

/// Runs `cmd` (stdin closed, stdout and stderr captured while it runs, so a chatty child
/// never blocks on a full pipe) and returns its output, or `None` after killing it when
/// it runs longer than `limit`.
pub(crate) fn output_within(
    cmd: &mut Command,
    limit: std::time::Duration,
) -> Option<std::process::Output> {
    use std::io::Read;
    use std::process::Stdio;
    let mut child = cmd
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn");
    let drain = |mut r: Box<dyn Read + Send>| {
        std::thread::spawn(move || {
            let mut v = Vec::new();
            let _ = r.read_to_end(&mut v);
            v
        })
    };
    let out = drain(Box::new(child.stdout.take().expect("stdout")));
    let err = drain(Box::new(child.stderr.take().expect("stderr")));
    let start = std::time::Instant::now();
    let status = loop {
        if let Some(st) = child.try_wait().expect("wait") {
            break Some(st);
        }
        if start.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            break None;
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    };
    let (stdout, stderr) = (out.join().expect("stdout"), err.join().expect("stderr"));
    status.map(|status| std::process::Output {
        status,
        stdout,
        stderr,
    })
}

/// Whether the binary's figures get text (a font was found): `brdf-basis info` names
/// the figure font, asked once per test run.
pub(crate) fn with_text() -> bool {
    static TEXT: OnceLock<bool> = OnceLock::new();
    *TEXT.get_or_init(|| {
        let o = bin_cpu().arg("info").output().expect("info");
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let out = String::from_utf8_lossy(&o.stdout).into_owned();
        let line = out
            .lines()
            .find_map(|l| l.strip_prefix("figure font: "))
            .unwrap_or_else(|| panic!("no `figure font:` line in\n{out}"));
        !line.starts_with("none")
    })
}
