//! What `--emit-jobs` and the parts it names share (`sweep`, `tune`, `reproduce`): the job
//! lines (the same command, restricted to one part, each writing its own directory
//! `OUT/parts/part-K`), the jobs file, and the output directory's hygiene.
//!
//! A job line is self-contained: the absolute path of this `splatbench` binary and every
//! flag of the command as typed, shell-quoted, with `--part K --out OUT/parts/part-K`. Run
//! the lines from the directory the command was typed in (relative paths in them are
//! relative to it), in any order and on any machine that shares the file system, e.g.
//! `parallel -j 8 < jobs.txt`, `xargs -P 8 -d '\n' -n 1 sh -c < jobs.txt`, or a Slurm array
//! whose task K runs line K + 1 (README); then `splatbench merge OUT/parts/part-* --out OUT`.

use std::path::{Path, PathBuf};

use anyhow::Context as _;
use harness::results::shell_quote;

/// This process's arguments (after the subcommand's program name) without the flags
/// `drop` and their values (`--out DIR` and `--out=DIR` alike) and without the switches
/// (flags with no value) `switches`.
fn args_without(drop: &[&str], switches: &[&str]) -> Vec<String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut out = Vec::new();
    let mut skip_next = false;
    for a in args {
        if skip_next {
            skip_next = false;
            continue;
        }
        if switches.contains(&a.as_str()) {
            continue;
        }
        if drop.contains(&a.as_str()) {
            skip_next = true;
            continue;
        }
        if drop
            .iter()
            .any(|d| a.strip_prefix(d).is_some_and(|rest| rest.starts_with('=')))
        {
            continue;
        }
        out.push(a);
    }
    out
}

/// The command as typed, without the flags `drop` (what a plan records, the same for every
/// part of one experiment).
pub fn command_without(drop: &[&str]) -> String {
    command_without_switches(drop, &[])
}

/// [`command_without`], also without the switches `switches` (`reproduce --resume`: a part
/// resumed is a part of the same reproduction).
pub fn command_without_switches(drop: &[&str], switches: &[&str]) -> String {
    std::iter::once("splatbench".to_string())
        .chain(args_without(drop, switches).iter().map(|a| shell_quote(a)))
        .collect::<Vec<_>>()
        .join(" ")
}

/// One job line: `exe`, the command's arguments without `drop`, then `add`.
fn job_line(exe: &Path, drop: &[&str], add: &[String]) -> String {
    std::iter::once(shell_quote(&exe.display().to_string()))
        .chain(args_without(drop, &[]).iter().map(|a| shell_quote(a)))
        .chain(add.iter().map(|a| shell_quote(a)))
        .collect::<Vec<_>>()
        .join(" ")
}

/// The directory of part `k` of an experiment writing to `out`.
pub fn part_dir(out: &Path, k: usize) -> PathBuf {
    out.join("parts").join(format!("part-{k:03}"))
}

/// The flags a part's job line replaces.
pub const PART_FLAGS: [&str; 3] = ["--part", "--emit-jobs", "--out"];

/// Writes `parts` job lines to `file`, line `k` running part `k` into
/// [`part_dir`]`(out, k)`; returns how many.
pub fn emit(file: &Path, out: &Path, parts: usize) -> anyhow::Result<usize> {
    let exe = std::env::current_exe().context("finding the splatbench binary")?;
    let lines: Vec<String> = (0..parts)
        .map(|k| {
            job_line(
                &exe,
                &PART_FLAGS,
                &[
                    "--part".into(),
                    k.to_string(),
                    "--out".into(),
                    part_dir(out, k).display().to_string(),
                ],
            )
        })
        .collect();
    write_jobs(file, &lines)?;
    Ok(lines.len())
}

/// Writes the job lines to `file` (atomically, one per line).
fn write_jobs(file: &Path, lines: &[String]) -> anyhow::Result<()> {
    if let Some(d) = file.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(d).with_context(|| format!("creating {}", d.display()))?;
    }
    let mut text = lines.join("\n");
    text.push('\n');
    let tmp = file.with_extension(format!("tmp.{}", std::process::id()));
    std::fs::write(&tmp, text).with_context(|| format!("writing {}", tmp.display()))?;
    std::fs::rename(&tmp, file).with_context(|| format!("writing {}", file.display()))
}

/// Makes `out` ready for an experiment whose record file is `marker` (`tune.json`): absent
/// or empty, it is created; holding `marker` (an earlier output of the same command), its
/// entries are removed except `parts/` (the jobs' directories a merge reads) and anything
/// holding `keep` (an existing build given with `--build-dir`); holding only `parts/`, it
/// is used as it is. Anything else is an error: the directory is not ours to empty.
pub fn prepare_out(out: &Path, marker: &str, keep: Option<&Path>) -> anyhow::Result<()> {
    if !out.exists() {
        return std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()));
    }
    let entries: Vec<PathBuf> = std::fs::read_dir(out)
        .with_context(|| format!("reading {}", out.display()))?
        .map(|e| e.map(|e| e.path()))
        .collect::<Result<_, _>>()
        .with_context(|| format!("reading {}", out.display()))?;
    let is_parts = |p: &PathBuf| p.file_name().is_some_and(|n| n == "parts");
    if !out.join(marker).is_file() {
        if entries.iter().all(is_parts) {
            return Ok(());
        }
        anyhow::bail!(
            "--out {}: the directory holds files and is not this command's output (no {marker}): \
             give an empty or new directory",
            out.display()
        );
    }
    for e in entries {
        let kept = keep.is_some_and(|k| {
            let (k, e) = (
                k.canonicalize().unwrap_or(k.to_path_buf()),
                e.canonicalize().unwrap_or(e.clone()),
            );
            k.starts_with(&e)
        });
        if is_parts(&e) || kept {
            continue;
        }
        if e.is_dir() {
            std::fs::remove_dir_all(&e)
        } else {
            std::fs::remove_file(&e)
        }
        .with_context(|| format!("removing the old {}", e.display()))?;
    }
    Ok(())
}
