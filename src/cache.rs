//! `splatbench cache`: where the cache is, what it holds, and `--clear`.
//!
//! The cache keeps what is expensive to make and cheap to make again: generated scenes of
//! ≥ 2 M points as column files (`scenes/`), full-resolution reference images (`refs/`) and
//! the reference builds they are drawn from (`full/`). It lives in the platform's user cache
//! directory ([`crate::shared::default_cache`]), not under the directory a command is run
//! from. `--clear` removes exactly those three folders, never anything else a mistyped
//! `--cache` might point at.

use anyhow::Context;
use clap::Args;

use crate::args::CacheArgs;

/// The folders splatbench writes in a cache directory, and what each holds.
pub const ENTRIES: [(&str, &str); 3] = [
    ("scenes", "generated scenes (column files)"),
    ("refs", "reference images"),
    ("full", "reference builds"),
];

#[derive(Args)]
pub struct CacheCommandArgs {
    #[command(flatten)]
    pub cache: CacheArgs,
    /// Remove what splatbench cached (the scenes/, refs/ and full/ folders).
    #[arg(long)]
    pub clear: bool,
}

pub fn main(a: &CacheCommandArgs) -> anyhow::Result<()> {
    let mut total = (0u64, 0u64);
    println!("cache: {}", a.cache.dir.display());
    for (name, what) in ENTRIES {
        let dir = a.cache.dir.join(name);
        let (files, bytes) = harness::results::dir_size(&dir)
            .with_context(|| format!("reading {}", dir.display()))?;
        total = (total.0 + files, total.1 + bytes);
        println!(
            "  {:<8} {:>10}  {files:>6} files  {what}",
            format!("{name}/"),
            mib(bytes)
        );
        if a.clear && dir.exists() {
            std::fs::remove_dir_all(&dir).with_context(|| format!("removing {}", dir.display()))?;
        }
    }
    println!(
        "  {:<8} {:>10}  {:>6} files",
        "total",
        mib(total.1),
        total.0
    );
    if a.clear {
        println!("cleared {} ({} freed)", a.cache.dir.display(), mib(total.1));
    }
    Ok(())
}

fn mib(bytes: u64) -> String {
    format!("{:.1} MiB", bytes as f64 / (1024.0 * 1024.0))
}
