//! `cargo run --release -p fuzz -- TARGET --iters N [--seed S]`: runs a target (or `all`) and
//! prints executions and findings; exits non-zero when anything was found.

use std::path::PathBuf;
use std::time::Duration;

use clap::Parser;
use fuzz::run::{self, Options, Report};
use fuzz::targets::{ALL, Target};

/// Mutation fuzzer for splatbench's readers and method repository decoders.
#[derive(Parser, Debug)]
#[command(name = "fuzz")]
struct Cli {
    /// A target name, `all`, or `list` to show the targets.
    target: String,
    /// Inputs per target.
    #[arg(long, default_value_t = 1000)]
    iters: u64,
    /// Random stream: input i depends on (seed, i) only.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Seconds one input may take before it counts as a hang.
    #[arg(long, default_value_t = 30)]
    timeout_s: u64,
    /// Address-space limit of the child process in MiB (0 = none).
    #[arg(long, default_value_t = 4096)]
    mem_mb: u64,
    /// Where reproducers are written.
    #[arg(long)]
    crashes: Option<PathBuf>,
    /// Run one saved input in this process instead of fuzzing.
    #[arg(long)]
    replay: Option<PathBuf>,
    /// First iteration (used by the supervising parent when it restarts a child).
    #[arg(long, default_value_t = 0, hide = true)]
    start: u64,
}

fn print_reports(reports: &[Report]) {
    println!(
        "{:<12} {:>8} {:>9} {:>9} {:>9} {:>7} {:>7} {:>7}",
        "target", "execs", "accepted", "seconds", "execs/s", "panics", "crashes", "hangs"
    );
    for r in reports {
        let count = |k| {
            r.findings
                .iter()
                .filter(|f| f.kind == k)
                .map(|f| f.hits)
                .sum::<u64>()
        };
        println!(
            "{:<12} {:>8} {:>9} {:>9.1} {:>9.0} {:>7} {:>7} {:>7}",
            r.target.name(),
            r.execs,
            r.accepted,
            r.seconds,
            r.execs as f64 / r.seconds.max(1e-9),
            count(run::Kind::Panic),
            count(run::Kind::Crash),
            count(run::Kind::Hang)
        );
    }
    for r in reports {
        for f in &r.findings {
            println!(
                "FINDING {} {} (iteration {}, {} inputs): {}\n  reproducer: {}",
                r.target.name(),
                f.kind,
                f.iteration,
                f.hits,
                f.message,
                f.reproducer
                    .as_ref()
                    .map_or_else(|| "(not saved)".into(), |p| p.display().to_string())
            );
        }
    }
}

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    if cli.target == "list" {
        for t in ALL {
            println!("{:<12} {}", t.name(), t.describe());
        }
        return std::process::ExitCode::SUCCESS;
    }
    let targets: Vec<Target> = if cli.target == "all" {
        ALL.to_vec()
    } else if let Some(t) = Target::from_name(&cli.target) {
        vec![t]
    } else {
        let names: Vec<&str> = ALL.iter().map(|t| t.name()).collect();
        eprintln!(
            "Error: unknown target '{}' (known: all, list, {})",
            cli.target,
            names.join(", ")
        );
        return std::process::ExitCode::from(2);
    };
    let opts = Options {
        iters: cli.iters,
        seed: cli.seed,
        timeout: Duration::from_secs(cli.timeout_s.max(1)),
        mem_mb: cli.mem_mb,
        crashes: cli
            .crashes
            .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("crashes")),
    };
    if std::env::var_os(run::CHILD_ENV).is_some() {
        return match run::child(targets[0], &opts, cli.start) {
            Ok(()) => std::process::ExitCode::SUCCESS,
            Err(e) => {
                eprintln!("Error: {e}");
                std::process::ExitCode::FAILURE
            }
        };
    }
    if let Some(file) = &cli.replay {
        return match run::replay(targets[0], file) {
            Ok(Ok(())) => {
                println!("decoded without error");
                std::process::ExitCode::SUCCESS
            }
            Ok(Err(e)) => {
                println!("decoder error (not a finding): {e}");
                std::process::ExitCode::SUCCESS
            }
            Err(e) => {
                eprintln!("Error: {e}");
                std::process::ExitCode::FAILURE
            }
        };
    }
    let mut reports = Vec::new();
    for t in targets {
        match run::supervise(t, &opts) {
            Ok(r) => {
                eprintln!(
                    "{}: {} inputs in {:.1} s, {} findings",
                    t.name(),
                    r.execs,
                    r.seconds,
                    r.findings.len()
                );
                reports.push(r);
            }
            Err(e) => {
                eprintln!("Error: {e}");
                return std::process::ExitCode::FAILURE;
            }
        }
    }
    print_reports(&reports);
    if reports.iter().any(|r| !r.findings.is_empty()) {
        std::process::ExitCode::FAILURE
    } else {
        std::process::ExitCode::SUCCESS
    }
}
