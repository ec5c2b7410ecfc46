//! The manual as a test: every `arbor` command line in a fenced block of README.md or
//! docs/*.md.
//!
//! - An `arbor ...` code span in the prose, a synopsis line (with `[optional]` parts,
//!   `...`, or a placeholder such as `SCENE`) and a line marked `# not in CI: WHY` are
//!   parsed only: the subcommand exists and
//!   every flag it shows is one that `arbor SUBCOMMAND --help` lists, so a renamed or
//!   removed flag fails here.
//! - Every other line runs, in a scratch directory, at a small size (`--size` 16x16 or
//!   smaller, at most 2 samples per pixel, one repeat, built-in meshes and `--tris`
//!   divided by 100, and a `bench` that names no structure on two): it must exit 0 and write every file it names (`-o`, `--stats`,
//!   `--aov`, `--json`, `--trace-events`, `--diff`, and a CSV under `--out`). A file
//!   it reads that CI lacks (a mesh of one's own) needs the mark.
//! - The README's synopsis lists exactly the flags that each command's `--help` shows.
//!
//! Not trycmd: trycmd compares a command's output with the text in the manual, and
//! arbor's output is timings and device names, different on every run and machine;
//! what the manual promises is an exit status and files, which this checks.

use crate::common;

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::Command;

/// One command line of the manual: where it is, its words, and the mark if any.
#[derive(Debug)]
struct Line {
    at: String,
    words: Vec<String>,
    not_in_ci: Option<String>,
    /// A `code span` in the prose: parsed, never run.
    inline: bool,
}

fn manual_files() -> Vec<PathBuf> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut files = vec![root.join("README.md")];
    let mut docs: Vec<PathBuf> = std::fs::read_dir(root.join("docs"))
        .expect("docs/")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "md"))
        .collect();
    docs.sort();
    files.extend(docs);
    files
}

/// The `arbor` lines of the fenced blocks of `text` (a `\` at the end of a line continues
/// it; an indented `[` line continues a synopsis).
fn command_lines(name: &str, text: &str) -> Vec<Line> {
    let mut out: Vec<Line> = Vec::new();
    let mut in_block = false;
    let mut pending: Option<(usize, String)> = None;
    for (k, raw) in text.lines().enumerate() {
        if raw.trim_start().starts_with("```") {
            in_block = !in_block;
            continue;
        }
        if !in_block {
            // `arbor ...` code spans in the prose: their flags are checked too.
            for (i, span) in raw.split('`').enumerate() {
                if i % 2 == 1 && span.starts_with("arbor ") {
                    let words = span.split_whitespace().skip(1).map(String::from).collect();
                    out.push(Line { at: format!("{name}:{}", k + 1), words, not_in_ci: None, inline: true });
                }
            }
            continue;
        }
        let line = raw.trim_end();
        let joined = match pending.take() {
            Some((at, head)) => (at, format!("{head} {}", line.trim())),
            None => (k + 1, line.trim().trim_start_matches("$ ").to_string()),
        };
        if let Some(head) = joined.1.strip_suffix('\\') {
            pending = Some((joined.0, head.trim_end().to_string()));
            continue;
        }
        let (at, text) = joined;
        if text.starts_with('[') && raw.starts_with(' ') {
            if let Some(last) = out.last_mut() {
                last.words.extend(text.split_whitespace().map(String::from));
                continue;
            }
        }
        if !text.starts_with("arbor ") && text != "arbor" {
            continue;
        }
        let (command, comment) = match text.split_once(" # ") {
            Some((c, m)) => (c.to_string(), Some(m.trim().to_string())),
            None => (text.clone(), None),
        };
        let not_in_ci = comment.and_then(|m| m.strip_prefix("not in CI:").map(|w| w.trim().to_string()));
        let words = command
            .split_whitespace()
            .skip(1)
            .filter(|w| *w != "&")
            .map(|w| w.trim_matches(|c| c == '\'' || c == '"').to_string())
            .collect();
        out.push(Line { at: format!("{name}:{at}"), words, not_in_ci, inline: false });
    }
    out
}

/// A synopsis rather than a command: optional parts, ellipses or placeholders.
fn is_synopsis(words: &[String]) -> bool {
    words.iter().any(|w| {
        let stem = w.split('.').next().unwrap_or("");
        w.contains('[')
            || w.contains("..")
            || w.contains('|')
            || (stem.len() > 1 && stem.chars().all(|c| c.is_ascii_uppercase() || c == '_'))
    })
}

/// The flags `arbor CMD --help` lists (long names, `--help` itself left out).
fn help_flags(cmd: &str, cache: &mut BTreeMap<String, BTreeSet<String>>) -> BTreeSet<String> {
    cache
        .entry(cmd.to_string())
        .or_insert_with(|| {
            let out = Command::new(env!("CARGO_BIN_EXE_arbor")).args([cmd, "--help"]).output().expect("run arbor");
            assert!(out.status.success(), "`arbor {cmd} --help` failed: the manual names no subcommand");
            String::from_utf8_lossy(&out.stdout)
                .lines()
                .filter_map(|l| {
                    let l = l.trim_start();
                    let l = if l.starts_with('-') && !l.starts_with("--") { l.split_once(", ")?.1 } else { l };
                    let name = l.strip_prefix("--")?;
                    let name: String = name.chars().take_while(|c| c.is_ascii_alphanumeric() || *c == '-').collect();
                    (name != "help" && !name.is_empty()).then(|| format!("--{name}"))
                })
                .collect()
        })
        .clone()
}

/// The flags a line shows, short ones as their long names.
fn shown_flags(words: &[String]) -> BTreeSet<String> {
    words
        .iter()
        .flat_map(|w| w.split('|'))
        .map(|w| w.trim_matches(|c| c == '[' || c == ']'))
        .filter_map(|w| match w {
            "-o" => Some("--output".to_string()),
            "-q" => Some("--quiet".to_string()),
            w if w.starts_with("--") && w.len() > 2 => {
                Some(w.split('=').next().unwrap_or(w).trim_end_matches(['.', ',']).to_string())
            }
            _ => None,
        })
        .collect()
}

/// A count shrunk for CI: a hundredth, at least 100 and at most 3000.
fn shrink_count(n: &str) -> String {
    n.parse::<u64>().map(|n| (n / 100).clamp(100, 3000).to_string()).unwrap_or_else(|_| n.to_string())
}

/// `builtin:NAME:N` with N shrunk; other scenes as they are.
fn shrink_scene(s: &str) -> String {
    s.split(',')
        .map(|one| match one.rsplit_once(':') {
            Some((head, n)) if one.starts_with("builtin:") && n.parse::<u64>().is_ok() => {
                format!("{head}:{}", shrink_count(n))
            }
            _ => one.to_string(),
        })
        .collect::<Vec<_>>()
        .join(",")
}

/// The line's words for a small run in CI.
fn small(words: &[String]) -> Vec<String> {
    let cmd = words[0].as_str();
    let mut out = vec![cmd.to_string()];
    let mut k = 1;
    while k < words.len() {
        let w = &words[k];
        let value = words.get(k + 1);
        let shrunk = match (w.as_str(), value) {
            ("--size", Some(_)) => Some("16x16".to_string()),
            ("--spp", Some(v)) => Some(v.parse::<u32>().map(|n| n.min(2).to_string()).unwrap_or(v.clone())),
            ("--repeat", Some(_)) => Some("1".to_string()),
            ("--tris", Some(v)) => Some(v.split(',').map(shrink_count).collect::<Vec<_>>().join(",")),
            ("--scene", Some(v)) => Some(shrink_scene(v)),
            _ => None,
        };
        out.push(if shrunk.is_none() { shrink_scene(w) } else { w.clone() });
        if let Some(v) = shrunk {
            out.push(v);
            k += 1;
        }
        k += 1;
    }
    if matches!(cmd, "render" | "bench") {
        if !out.iter().any(|w| w == "--size") {
            out.extend(["--size".into(), "16x16".into()]);
        }
        if cmd == "render" && !out.iter().any(|w| w == "--spp") {
            out.extend(["--spp".into(), "2".into()]);
        }
        if cmd == "bench" && !out.iter().any(|w| w == "--repeat") {
            out.extend(["--repeat".into(), "1".into()]);
        }
        // Every structure is a kernel to compile (twice with two intersection tests):
        // a bench that names none benches two in CI.
        if cmd == "bench" && !out.iter().any(|w| w == "--accel" || w == "--quick") {
            out.extend(["--accel".into(), "lbvh,bvh4".into()]);
        }
    }
    out
}

/// The files a run promises (relative to its directory), and the `--out` directory.
fn promised(words: &[String]) -> (Vec<String>, Option<String>) {
    let mut files = Vec::new();
    let mut out_dir = None;
    for pair in words.windows(2).filter(|p| !p[1].starts_with('-')) {
        match pair[0].as_str() {
            "-o" | "--output" | "--stats" | "--json" | "--trace-events" | "--diff" => files.push(pair[1].clone()),
            "--aov" => files.extend(pair[1].split(',').filter_map(|a| a.split_once('=').map(|x| x.1.to_string()))),
            "--out" => out_dir = Some(pair[1].clone()),
            _ => {}
        }
    }
    if words[0] == "render" && !words.iter().any(|w| w == "-o" || w == "--output") {
        files.push("render.png".into());
    }
    (files, out_dir)
}

/// The input files a run reads that are not built in (scenes, references, parts).
fn inputs(words: &[String]) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    let positional = match words[0].as_str() {
        "render" | "info" => 1,
        "compare" => 2,
        _ => 0,
    };
    out.extend(words.iter().skip(1).take(positional).filter(|w| !w.starts_with('-')).cloned());
    for pair in words.windows(2) {
        if matches!(pair[0].as_str(), "--scene" | "--reference" | "--resume") {
            out.extend(pair[1].split(',').map(String::from));
        }
    }
    out.retain(|w| !w.starts_with("builtin:"));
    out
}

fn every_line() -> Vec<Line> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut lines = Vec::new();
    for f in manual_files() {
        let text = std::fs::read_to_string(&f).expect("read the manual");
        let name = f.strip_prefix(root).unwrap_or(&f).display().to_string();
        lines.extend(command_lines(&name, &text));
    }
    lines
}

/// Every flag the manual shows exists; every runnable command runs and writes what
/// it promises.
#[test]
fn every_command_of_the_manual_parses_and_runs() {
    let lines = every_line();
    assert!(lines.len() >= 15, "the manual's command lines were not found: {lines:?}");
    let mut help = BTreeMap::new();
    let mut problems = Vec::new();
    let gpu = common::has_gpu();
    let mut ran = 0;
    for line in &lines {
        let Some(cmd) = line.words.first() else { continue };
        if cmd.chars().all(|c| c.is_ascii_uppercase()) {
            continue; // `arbor COMMAND --help`
        }
        let flags = help_flags(cmd, &mut help);
        let unknown: Vec<_> = shown_flags(&line.words).difference(&flags).cloned().collect();
        if !unknown.is_empty() {
            problems.push(format!("{}: `arbor {cmd}` has no {unknown:?}", line.at));
        }
        if line.inline || is_synopsis(&line.words) || line.not_in_ci.is_some() || !gpu {
            continue;
        }
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        if let Some(missing) = inputs(&line.words).into_iter().find(|f| !root.join(f).exists()) {
            problems.push(format!("{}: reads {missing}, which CI lacks: mark it `# not in CI: WHY`", line.at));
            continue;
        }
        let args = small(&line.words);
        let dir = tempfile::tempdir().expect("tempdir");
        let started = std::time::Instant::now();
        let out = Command::new(env!("CARGO_BIN_EXE_arbor")).args(&args).current_dir(dir.path()).output().expect("run");
        eprintln!("manual: {:.1} s: arbor {}", started.elapsed().as_secs_f64(), args.join(" "));
        ran += 1;
        if !out.status.success() {
            problems.push(format!(
                "{}: `arbor {}` exited {:?}: {}",
                line.at,
                args.join(" "),
                out.status.code(),
                String::from_utf8_lossy(&out.stderr).trim()
            ));
            continue;
        }
        let (files, out_dir) = promised(&args);
        for f in files.iter().filter(|f| !dir.path().join(f).is_file()) {
            problems.push(format!("{}: `arbor {}` did not write {f}", line.at, args.join(" ")));
        }
        if let Some(d) = out_dir {
            let csv = std::fs::read_dir(dir.path().join(&d))
                .map(|r| r.filter_map(|e| e.ok()).any(|e| e.path().extension().is_some_and(|x| x == "csv")))
                .unwrap_or(false);
            if !csv {
                problems.push(format!("{}: `arbor {}` wrote no CSV under --out {d}", line.at, args.join(" ")));
            }
        }
    }
    eprintln!("manual: {} command lines, {ran} run", lines.len());
    assert!(problems.is_empty(), "the manual and the program disagree:\n{}", problems.join("\n"));
}

/// The README's synopsis shows each command with exactly the flags its `--help` lists.
#[test]
fn the_readme_synopsis_is_the_clis() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(root.join("README.md")).expect("README");
    let synopsis: Vec<Line> = command_lines("README.md", &text)
        .into_iter()
        .filter(|l| !l.inline && !l.words.is_empty() && is_synopsis(&l.words))
        .collect();
    let commands: BTreeSet<&str> = synopsis.iter().map(|l| l.words[0].as_str()).collect();
    let out = Command::new(env!("CARGO_BIN_EXE_arbor")).arg("--help").output().expect("run arbor");
    let listed: BTreeSet<String> = String::from_utf8_lossy(&out.stdout)
        .lines()
        .skip_while(|l| !l.starts_with("Commands:"))
        .skip(1)
        .take_while(|l| l.starts_with("  "))
        .filter_map(|l| l.split_whitespace().next().map(String::from))
        .filter(|c| c != "help")
        .collect();
    for c in &listed {
        assert!(commands.contains(c.as_str()) || c == "devices", "the README synopsis lacks `arbor {c}`");
    }
    let mut help = BTreeMap::new();
    let mut problems = Vec::new();
    for line in &synopsis {
        let cmd = &line.words[0];
        let flags = help_flags(cmd, &mut help);
        let shown = shown_flags(&line.words);
        let missing: Vec<_> = flags.difference(&shown).collect();
        let extra: Vec<_> = shown.difference(&flags).collect();
        if !missing.is_empty() || !extra.is_empty() {
            problems.push(format!("{}: `arbor {cmd}` lacks {missing:?}, shows unknown {extra:?}", line.at));
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}
