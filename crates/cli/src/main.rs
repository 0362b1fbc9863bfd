//! The `brdf-basis` command line: parse, run, print the error chain once, exit code.

// Errors carry the file, line and material they name (cold paths).
#![allow(clippy::result_large_err)]

mod cli;
mod layout;
mod plot;

use clap::Parser;

fn main() -> std::process::ExitCode {
    // `brdf-basis info | head -1`: a closed pipe ends the process quietly, as for any
    // Unix filter, instead of a panic in `println!` (Rust ignores SIGPIPE by default).
    #[cfg(unix)]
    // SAFETY: called first in `main`, before any thread exists; restoring the default
    // disposition of a signal has no other effect on this process.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    // Parse first: `--help`, `--version` and usage errors exit here, before anything
    // (the private runtime directory, the signal handler's thread) exists.
    let args = cli::Cli::parse();
    if let Some(w) = brdf_basis::backend::cpu::cap_global_threads() {
        eprintln!("warning: {w}");
    }
    // Removed on every later exit: normal return, error, panic (the guard's drop) and a
    // signal (the handler).
    let runtime = RuntimeDir(private_runtime_dir());
    // SIGINT, SIGTERM, SIGHUP: remove the staged outputs, the directories created for
    // them and the runtime directory, then exit 130 as shells expect after Ctrl-C.
    // A signal ignored at start (SIGINT for a background job of a script, SIGHUP under
    // nohup) stays ignored, as the caller meant.
    #[cfg(unix)]
    let ignored = [libc::SIGINT, libc::SIGHUP].map(|sig| (sig, is_ignored(sig)));
    let handler_dir = runtime.0.clone();
    let _ = ctrlc::set_handler(move || {
        let cleanup = brdf_basis::atomic::remove_pending();
        if let Some(d) = &handler_dir {
            let _ = std::fs::remove_dir_all(d);
        }
        eprintln!("error: {}", cleanup.message());
        std::process::exit(130);
    });
    #[cfg(unix)]
    for (sig, was_ignored) in ignored {
        if was_ignored {
            // SAFETY: still single-threaded apart from ctrlc's waiting thread, which does
            // not touch signal dispositions; SIG_IGN needs no handler.
            unsafe {
                libc::signal(sig, libc::SIG_IGN);
            }
        }
    }
    let code = match cli::run(args) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(_) if brdf_basis::atomic::interrupted() => loop {
            // A signal's handler is removing the outputs and exits with 130: this error
            // is its consequence (a write refused), not the cause.
            std::thread::park();
        },
        Err(e) => {
            eprintln!("error: {}", error_message(&e));
            std::process::ExitCode::FAILURE
        }
    };
    drop(runtime);
    code
}

/// The private runtime directory, removed when dropped.
struct RuntimeDir(Option<std::path::PathBuf>);

impl Drop for RuntimeDir {
    fn drop(&mut self) {
        if let Some(d) = &self.0 {
            let _ = std::fs::remove_dir_all(d);
        }
    }
}

/// Whether `sig` is ignored (SIG_IGN) in this process.
#[cfg(unix)]
fn is_ignored(sig: libc::c_int) -> bool {
    // SAFETY: sigaction with a null new action only reads the current disposition into
    // `old`, a zeroed plain C struct.
    unsafe {
        let mut old: libc::sigaction = std::mem::zeroed();
        libc::sigaction(sig, std::ptr::null(), &mut old) == 0 && old.sa_sigaction == libc::SIG_IGN
    }
}

/// The error chain as one line. A message that already ends with its cause's text (an
/// error formatting `{source}` and also returning it as its source) is not repeated.
fn error_message(e: &anyhow::Error) -> String {
    let mut out = String::new();
    for c in e.chain() {
        let s = c.to_string();
        if out.ends_with(&s) || s.is_empty() {
            continue;
        }
        if !out.is_empty() {
            out.push_str(": ");
        }
        out.push_str(&s);
    }
    out
}

/// When `XDG_RUNTIME_DIR` is unset or not an absolute path to a directory, the Vulkan
/// loader's Wayland probe prints `error: XDG_RUNTIME_DIR is invalid or not set` (twice)
/// on every GPU start, `--quiet` or not. Point it, for this process only, at a private
/// (mode 0700) directory under the temporary directory, removed at exit. Runs in `main`
/// before any thread exists (`set_var`). Returns the directory created.
fn private_runtime_dir() -> Option<std::path::PathBuf> {
    let current = std::env::var_os("XDG_RUNTIME_DIR").map(std::path::PathBuf::from);
    if current.is_some_and(|d| d.is_absolute() && d.is_dir()) {
        return None;
    }
    let dir = std::env::temp_dir().join(format!("brdf-basis-runtime-{}", std::process::id()));
    let mut builder = std::fs::DirBuilder::new();
    #[cfg(unix)]
    std::os::unix::fs::DirBuilderExt::mode(&mut builder, 0o700);
    builder.create(&dir).ok()?;
    std::env::set_var("XDG_RUNTIME_DIR", &dir);
    Some(dir)
}
