//! `splatbench build`: a method's representation of a scene, written into a directory.

use std::path::{Path, PathBuf};

use anyhow::Context as _;
use clap::Args;

use crate::args::{CacheArgs, MethodArgs, SceneArgs};

#[derive(Args, Clone)]
pub struct BuildArgs {
    #[command(flatten)]
    pub method: MethodArgs,
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Output directory.
    #[arg(long)]
    pub out: PathBuf,
    #[command(flatten)]
    pub cache: CacheArgs,
}

/// The least build memory (`--param mem_mb`, MiB) for which `build` keeps freed heap memory
/// (`keep_freed_heap_memory` in `main.rs`). The policy's retained free blocks cost ≈ 20 MB of
/// peak RSS on a 1 M-sample SPT build told to use 16 MiB (75 MB against 55 MB: more than its
/// budget again); a build told to use little memory keeps glibc's default, and its budget
/// bounds its resident set as `tests/build_memory.rs` checks. Every default `mem_mb` is at
/// least this.
pub const KEEP_FREED_FROM_MB: u64 = 256;

/// Whether `build`'s heap policy applies to this build: unless a `mem_mb` below
/// [`KEEP_FREED_FROM_MB`] is given. Parameters read as the build reads them
/// ([`methods::Params::parse`]); ones that do not parse are the build's error to report, and
/// the policy then does not matter.
pub fn keeps_freed_memory(a: &BuildArgs) -> bool {
    let Ok(params) = methods::Params::parse(&a.method.params) else {
        return true;
    };
    params
        .0
        .get("mem_mb")
        .is_none_or(|v| v.parse::<u64>().map_or(true, |mb| mb >= KEEP_FREED_FROM_MB))
}

/// `splatbench build`: builds and prints `build.json`.
pub fn main(a: &BuildArgs) -> anyhow::Result<()> {
    let stats = build(&a.method, &a.scene, &a.out, &a.cache.dir)?;
    println!("{}", serde_json::to_string_pretty(&stats)?);
    Ok(())
}

/// Loads the scene and builds the method into `out` (`sweep` builds through it too);
/// `build.json`'s `extra` records the process's peak RSS (`peak_rss_bytes`) and the wall
/// seconds of every progress phase in order, the scene's load included (`phases`: a list of
/// `{"phase", "seconds"}`).
pub fn build(
    m: &MethodArgs,
    s: &SceneArgs,
    out: &Path,
    cache: &Path,
) -> anyhow::Result<methods::BuildStats> {
    let params = crate::args::method_params(m.method, &m.params)?;
    let spec = s.spec()?;
    let bar = harness::progress::Bar::new();
    let cloud = spec
        .load(Some(cache), &bar)
        .with_context(|| format!("loading scene '{}'", s.scene))?
        .warn();
    let mut stats = m.method.build(&cloud, &params, &spec.label(), out, &bar)?;
    // The process's peak memory: the scene's load and the build (a `tune` builds in a
    // process of its own, so this is the build's).
    stats.extra.insert(
        "peak_rss_bytes".into(),
        serde_json::Value::from(harness::rss::peak_bytes()),
    );
    let phases: Vec<serde_json::Value> = bar
        .phases()
        .into_iter()
        .map(|(phase, seconds)| serde_json::json!({ "phase": phase, "seconds": seconds }))
        .collect();
    stats.extra.insert("phases".into(), phases.into());
    stats.write(out)?;
    Ok(stats)
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        build: BuildArgs,
    }

    fn keeps(params: &[&str]) -> bool {
        let mut args = vec!["x", "--method", "spt", "--scene", "statue:10", "--out", "o"];
        for p in params {
            args.extend(["--param", p]);
        }
        keeps_freed_memory(&Cli::parse_from(args).build)
    }

    #[test]
    fn a_small_build_memory_keeps_the_default_heap_policy() {
        assert!(keeps(&[]));
        assert!(keeps(&["mem_mb=256"]));
        assert!(keeps(&["overlap=1", "mem_mb=4096"]));
        assert!(!keeps(&["mem_mb=16"]));
        assert!(!keeps(&["mem_mb=255"]));
        // Spaces around the key and the value, as the build reads them.
        assert!(!keeps(&[" mem_mb = 16"]));
        // Not a number, or a key given twice: the build reports it; the policy does not
        // matter.
        assert!(keeps(&["mem_mb=lots"]));
        assert!(keeps(&["mem_mb=1024", "mem_mb=16"]));
    }
}
