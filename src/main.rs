//! The `arbor` command line: render, info, devices, calibrate, bench, compare, merge. This file
//! parses the arguments, hands each command to its module under `src/cli/` and turns
//! an error into one line and an exit status; it also sets up the allocator.

use anyhow::Result;
use clap::Parser;

#[path = "cli/args.rs"]
mod args;
#[path = "cli/bench.rs"]
mod bench;
#[path = "cli/calibrate.rs"]
mod calibrate;
#[path = "cli/common.rs"]
mod common;
#[path = "cli/compare.rs"]
mod compare;
#[path = "cli/devices.rs"]
mod devices;
#[path = "cli/farm_bench.rs"]
mod farm_bench;
#[path = "cli/info.rs"]
mod info;
#[path = "cli/interrupt.rs"]
mod interrupt;
#[path = "cli/merge.rs"]
mod merge;
#[path = "cli/progress.rs"]
mod progress;
#[path = "cli/render.rs"]
mod render;

use args::{Cli, Command};

// The kd-tree builder allocates many short-lived vectors; mimalloc builds the 75k
// benchmark tree about 25% faster than glibc malloc here. It is built with `no_thp` (it
// never asks for transparent huge pages; the system's policy decides) and told by
// `keep_freed_memory` not to give freed memory back: docs/build-notes.md, "Host memory".
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

/// mimalloc v3's `mi_option_purge_delay` (its place in `mi_option_e`, mimalloc.h; the
/// `libmimalloc-sys` crate names no constant for it). Its default is 1000 (ms), which
/// `purge_delay_option_is_the_one_meant` checks.
const MI_OPTION_PURGE_DELAY: libmimalloc_sys::mi_option_t = 15;

/// Keep the memory arbor frees for its own reuse instead of returning it to the OS a
/// second later (mimalloc's default). Builds then reuse pages the scene loading or an
/// earlier structure freed instead of faulting in fresh ones: on the development VM a
/// 1M-triangle LBVH built after other structures took 71-85 ms with purging and 60-66
/// without, as long as a repeated build. `MIMALLOC_PURGE_DELAY`, when set, still wins.
fn keep_freed_memory() {
    if std::env::var_os("MIMALLOC_PURGE_DELAY").is_none() {
        // SAFETY: the one `unsafe` outside src/gpu besides this file's test (docs/build-notes.md,
        // "Host memory"). `mi_option_set` stores an integer in mimalloc's option table; it is
        // called before any thread is started, and -1 ("never purge") is a documented
        // value of this option.
        #[allow(unsafe_code)]
        unsafe {
            libmimalloc_sys::mi_option_set(MI_OPTION_PURGE_DELAY, -1)
        }
    }
}

fn main() {
    keep_freed_memory();
    let cli = Cli::try_parse().unwrap_or_else(|e| clap_error(e));
    match run(cli) {
        Ok(()) => {}
        // A reader that stopped early (`arbor bench | head -1`) is a normal end.
        Err(e) if is_broken_pipe(&e) => {}
        Err(e) => {
            eprintln!("arbor: error: {e:#}");
            std::process::exit(exit_status(&e));
        }
    }
}

/// Prints a command-line error as one line, like every other error (clap's first line
/// without its prefix; a missing argument by name), and exits with 2. `--help` and
/// `--version` print as clap formats them, to stdout; `arbor` alone prints the usage.
fn clap_error(e: clap::Error) -> ! {
    use clap::error::{ContextKind, ContextValue, ErrorKind};
    if !e.use_stderr() {
        let _ = e.print();
        std::process::exit(0);
    }
    if e.kind() == ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand {
        let _ = e.print();
        std::process::exit(2);
    }
    let text = e.render().to_string();
    // "Usage: arbor info [OPTIONS] <SCENE>" names the (sub)command.
    let command = text
        .lines()
        .find_map(|l| l.trim().strip_prefix("Usage: "))
        .map(|u| u.split_whitespace().take_while(|w| !w.starts_with(['[', '<', '-'])).collect::<Vec<_>>().join(" "))
        .filter(|c| !c.is_empty())
        .unwrap_or_else(|| "arbor".into());
    let what = match (e.kind(), e.get(ContextKind::InvalidArg)) {
        (ErrorKind::MissingRequiredArgument, Some(ContextValue::Strings(args))) => {
            format!("missing {}", args.join(", "))
        }
        _ => text.lines().next().unwrap_or("invalid arguments").trim_start_matches("error: ").to_string(),
    };
    eprintln!("arbor: error: {what} (see {command} --help)");
    std::process::exit(2);
}

/// The exit status of an error, one rule for every command: 2 for a mistake on the
/// command line (a flag's value included: `arbor::Error::Usage` anywhere in the chain),
/// 1 for a failure reading, building or rendering. An interruption exits with 130 where
/// it is caught (cli/interrupt.rs); clap's own errors exit with 2 (`clap_error`).
fn exit_status(e: &anyhow::Error) -> i32 {
    let usage = e.chain().any(|c| matches!(c.downcast_ref::<arbor::Error>(), Some(arbor::Error::Usage(_))));
    if usage {
        2
    } else {
        1
    }
}

/// Whether `e` comes from writing to a pipe whose reader has gone.
fn is_broken_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        let io = match c.downcast_ref::<arbor::Error>() {
            Some(arbor::Error::Io { cause, .. }) => Some(cause),
            _ => c.downcast_ref::<std::io::Error>(),
        };
        io.is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
    })
}

/// Runs the command; each lives in its own module under `src/cli/`.
fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Render(args) => render::run(&args),
        Command::Info(args) => info::run(&args),
        Command::Devices => devices::run(),
        Command::Calibrate(args) => calibrate::run(&args),
        Command::Bench(args) => bench::run(&args),
        Command::Compare(args) => compare::run(&args),
        Command::Merge(args) => merge::run(&args),
    }
}

#[cfg(test)]
mod tests {
    /// Option 15 is the purge delay (its default, 1000 ms, is no other option's), and
    /// `keep_freed_memory` turns purging off.
    #[test]
    fn purge_delay_option_is_the_one_meant() {
        // SAFETY: reads an integer from mimalloc's option table.
        #[allow(unsafe_code)]
        let get = || unsafe { libmimalloc_sys::mi_option_get(super::MI_OPTION_PURGE_DELAY) };
        if std::env::var_os("MIMALLOC_PURGE_DELAY").is_some() {
            return;
        }
        assert_eq!(get(), 1000, "option {} is not mimalloc's purge delay", super::MI_OPTION_PURGE_DELAY);
        super::keep_freed_memory();
        assert_eq!(get(), -1);
    }
}
