//! `splatbench export`: a scene written to a LAS/LAZ, PLY or column file.

use std::path::{Path, PathBuf};

use anyhow::{Context as _, bail};
use clap::Args;

use crate::args::{CacheArgs, SceneArgs};

#[derive(Args, Clone)]
pub struct ExportArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Output file.
    #[arg(long)]
    pub out: PathBuf,
    #[command(flatten)]
    pub cache: CacheArgs,
}

/// `splatbench export`.
pub fn main(a: &ExportArgs) -> anyhow::Result<()> {
    export(&a.scene, &a.out, &a.cache.dir)
}

fn export(s: &SceneArgs, out: &Path, cache: &Path) -> anyhow::Result<()> {
    let ext = out
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    if !matches!(ext.as_str(), "las" | "laz" | "ply" | "sbc") {
        bail!(
            "--out {}: the extension must be .las, .laz, .ply or .sbc",
            out.display()
        );
    }
    let spec = s.spec()?;
    let cloud = spec
        .load(Some(cache), &harness::progress::Bar::new())
        .with_context(|| format!("loading scene '{}'", s.scene))?
        .warn();
    let mut written = cloud.attributes();
    let bytes = match ext.as_str() {
        "las" | "laz" => {
            // LAS has no place for normals or radii: say what the file holds.
            written.normals = false;
            written.radii = false;
            scenes::las::write(out, &cloud)?
        }
        "ply" => scenes::ply::write(out, &cloud, scenes::ply::PlyFormat::BinaryLittleEndian)?,
        _ => scenes::colfile::write(out, &cloud)?,
    };
    println!(
        "wrote {} ({} points, {written}, {bytes} bytes)",
        out.display(),
        cloud.len(),
    );
    Ok(())
}
