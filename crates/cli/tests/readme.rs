//! The command transcripts of the README and of `docs/` are run (issue 47: a changed
//! default left the README's `select` transcript stale, and nothing checked it). A
//! transcript is a `$ brdf-basis ...` line in a ```` ```text ```` block of a Markdown
//! file; the lines after it, up to the next `$ ` line or the end of the block, are what
//! the command prints on stdout. Each runs on the embedded default collection, CPU
//! back-end, without progress bars, in a scratch directory, and must print exactly those
//! lines. The slow ones are skipped by name ([`SLOW`]), with a line that says so.

use crate::common::bin_cpu;

/// Transcripts not run by this test (minutes of work on 2 cores), by their command.
const SLOW: &[&str] =
    &["brdf-basis cv --methods greedy,kmedoids,random -k 5 --json cv.json --markdown cv.md"];

/// One transcript: where it is, the command, the stdout it shows.
#[derive(Debug, PartialEq)]
struct Transcript {
    at: String,
    command: String,
    stdout: Vec<String>,
}

/// The transcripts of a Markdown text (`name`: the file, for messages).
fn transcripts(name: &str, md: &str) -> Vec<Transcript> {
    let mut out: Vec<Transcript> = Vec::new();
    let (mut in_text, mut open) = (false, false);
    for (i, line) in md.lines().enumerate() {
        if line.starts_with("```") {
            in_text = !in_text && line.trim() == "```text";
            open = false;
            continue;
        }
        if !in_text {
            continue;
        }
        if let Some(command) = line.strip_prefix("$ ") {
            open = command.starts_with("brdf-basis ");
            if open {
                out.push(Transcript {
                    at: format!("{name}:{}", i + 1),
                    command: command.to_string(),
                    stdout: Vec::new(),
                });
            }
        } else if open {
            if let Some(t) = out.last_mut() {
                t.stdout.push(line.to_string());
            }
        }
    }
    out
}

/// The transcripts of the README and of every `docs/*.md`.
fn all_transcripts() -> Vec<Transcript> {
    let root = crate::common::repo();
    let mut files = vec![root.join("README.md")];
    let mut docs: Vec<_> = std::fs::read_dir(root.join("docs"))
        .expect("docs/")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    docs.sort();
    files.extend(docs);
    files
        .iter()
        .flat_map(|f| {
            let name = f.strip_prefix(root).unwrap_or(f).display().to_string();
            transcripts(&name, &std::fs::read_to_string(f).expect("read"))
        })
        .collect()
}

#[test]
fn the_parser_finds_commands_and_their_output() {
    let md = "x\n```sh\n$ brdf-basis info\n```\n```text\n$ brdf-basis a b\none\ntwo\n$ brdf-basis c\n```\n$ brdf-basis d\n";
    let t = transcripts("m.md", md);
    assert_eq!(
        t,
        [
            Transcript {
                at: "m.md:6".into(),
                command: "brdf-basis a b".into(),
                stdout: vec!["one".into(), "two".into()],
            },
            Transcript {
                at: "m.md:9".into(),
                command: "brdf-basis c".into(),
                stdout: vec![],
            },
        ]
    );
    // The README holds at least its `select` transcript, and every skipped one exists.
    let all = all_transcripts();
    assert!(
        all.iter()
            .any(|t| t.at.starts_with("README.md:") && t.command.starts_with("brdf-basis select")),
        "{all:?}"
    );
    for slow in SLOW {
        assert!(
            all.iter().any(|t| t.command == *slow),
            "no transcript `{slow}`"
        );
    }
}

/// Every transcript prints what it shows (the slow ones aside).
#[test]
fn the_transcripts_print_what_they_show() {
    let mut failures = Vec::new();
    for t in all_transcripts() {
        if SLOW.contains(&t.command.as_str()) {
            println!("SKIP (slow): {} `{}`", t.at, t.command);
            continue;
        }
        assert!(
            !t.command.contains(['"', '\'', '\\', '|', '>', '<', '*']),
            "{}: a transcript is a plain command, without quotes or shell syntax",
            t.at
        );
        let dir = tempfile::tempdir().expect("tmp");
        let args: Vec<&str> = t.command.split_whitespace().skip(1).collect();
        let o = bin_cpu()
            .args(&args)
            .current_dir(dir.path())
            .output()
            .expect("run brdf-basis");
        let got = String::from_utf8_lossy(&o.stdout);
        let got: Vec<&str> = got.lines().collect();
        if !o.status.success() || got != t.stdout {
            failures.push(format!(
                "{}: `{}` (exit {:?}) printed\n{}\nnot\n{}\nstderr: {}",
                t.at,
                t.command,
                o.status.code(),
                got.join("\n"),
                t.stdout.join("\n"),
                String::from_utf8_lossy(&o.stderr)
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n\n"));
}

/// The commands of the ```` ```sh ```` blocks of a Markdown text (`name`: the file): each
/// `brdf-basis ...` line (after an optional `$ `), its `\` continuations joined and its
/// trailing `# ...` comment removed, with where it starts.
fn sh_commands(name: &str, md: &str) -> Vec<(String, String)> {
    let mut out = Vec::new();
    let (mut in_sh, mut open): (bool, Option<(String, String)>) = (false, None);
    for (i, line) in md.lines().enumerate() {
        if line.starts_with("```") {
            in_sh = !in_sh && matches!(line.trim(), "```sh" | "```bash" | "```shell");
            open = None;
            continue;
        }
        if !in_sh {
            continue;
        }
        let code = line.split(" #").next().unwrap_or("").trim_end();
        let (text, more) = match code.strip_suffix('\\') {
            Some(t) => (t.trim_end(), true),
            None => (code, false),
        };
        let cmd = match open.take() {
            Some((at, c)) => Some((at, format!("{c} {}", text.trim()))),
            None => {
                let t = text.trim_start();
                let t = t.strip_prefix("$ ").unwrap_or(t);
                t.starts_with("brdf-basis ")
                    .then(|| (format!("{name}:{}", i + 1), t.to_string()))
            }
        };
        if let Some(c) = cmd {
            if more {
                open = Some(c);
            } else {
                out.push(c);
            }
        }
    }
    out
}

/// Whether the binary's parser takes `command` (every flag known, every value of the
/// right kind): the command is parsed with `--help` added, which prints the command's
/// help instead of running it; an unknown flag or a bad value fails first.
fn parses(command: &str) -> Result<(), String> {
    let args: Vec<&str> = command.split_whitespace().skip(1).collect();
    let o = bin_cpu()
        .args(&args)
        .arg("--help")
        .output()
        .expect("run brdf-basis");
    match o.status.success() {
        true => Ok(()),
        false => Err(String::from_utf8_lossy(&o.stderr).into_owned()),
    }
}

/// The commands the README and `docs/` show without their output (```` ```sh ```` blocks)
/// are ones the binary takes: a renamed or removed flag, or a value it no longer accepts,
/// cannot stay in them (the transcripts above are run whole).
#[test]
fn the_documented_commands_parse() {
    let md = "```sh\nbrdf-basis a --b 1   # c\n$ brdf-basis d \\\n  --e f\necho brdf-basis g\n```\n```text\nbrdf-basis h\n```\n";
    assert_eq!(
        sh_commands("m.md", md),
        [
            ("m.md:2".to_string(), "brdf-basis a --b 1".to_string()),
            ("m.md:3".to_string(), "brdf-basis d --e f".to_string()),
        ]
    );
    // The check can fail: a flag the command lacks and a value it refuses.
    assert!(parses("brdf-basis select --method greedy --no-such-flag").is_err());
    assert!(parses("brdf-basis select --method bogus").is_err());
    assert!(parses("brdf-basis select --method greedy -k 5 --stride 0").is_err());
    let root = crate::common::repo();
    let mut files = vec![root.join("README.md")];
    for e in std::fs::read_dir(root.join("docs")).expect("docs/") {
        let p = e.expect("entry").path();
        if p.extension().is_some_and(|e| e == "md") {
            files.push(p);
        }
    }
    let mut commands = Vec::new();
    for f in &files {
        let name = f.strip_prefix(root).unwrap_or(f).display().to_string();
        commands.extend(sh_commands(
            &name,
            &std::fs::read_to_string(f).expect("read"),
        ));
    }
    assert!(
        commands
            .iter()
            .any(|(at, c)| at.starts_with("README.md:") && c.starts_with("brdf-basis select")),
        "{commands:?}"
    );
    let failures: Vec<String> = commands
        .iter()
        .filter_map(|(at, c)| parses(c).err().map(|e| format!("{at}: `{c}`\n{e}")))
        .collect();
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
