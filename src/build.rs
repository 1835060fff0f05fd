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
