//! `splatbench sampling`: how regularly scenes sample their surfaces — the spread of the
//! nearest-neighbour distance and the bare fraction that discs of the average spacing leave
//! ([`scenes::regularity`]), one row per scene.

use anyhow::{Context as _, bail};
use clap::Args;

use crate::args::CacheArgs;

#[derive(Args, Clone)]
pub struct SamplingArgs {
    /// Scenes to measure (any `--scene` value: `statue:1M:1:even`, `bunny.ply`, …).
    #[arg(required = true)]
    pub scenes: Vec<String>,
    /// Test points per scene, for its area and bare fraction: independent area-uniform
    /// points of the scene's surface — for a generated scene its generator's (same seed,
    /// random streams no scene uses), for a PLY mesh the mesh resampled (seed 7); other
    /// files have no surface to draw them from and get no bare fraction.
    #[arg(long, default_value_t = 1_000_000)]
    pub test_points: usize,
    /// Print JSON lines instead of the table.
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub cache: CacheArgs,
}

/// `splatbench sampling`.
pub fn main(a: &SamplingArgs) -> anyhow::Result<()> {
    if a.test_points < 7 {
        bail!("--test-points {}: at least 7 are needed", a.test_points);
    }
    if !a.json {
        println!(
            "| scene | samples | mean NN distance | NN CV | bare fraction at √(A/πN) | test points |"
        );
        println!("|---|---|---|---|---|---|");
    }
    for text in &a.scenes {
        let spec =
            scenes::SceneSpec::parse(text, None, 1).with_context(|| format!("scene '{text}'"))?;
        let cloud = spec
            .load(Some(&a.cache.dir), &scenes::NoProgress)
            .with_context(|| format!("loading scene '{text}'"))?
            .warn();
        let (test, what) = test_points(&spec, a.test_points)
            .with_context(|| format!("test points of '{text}'"))?;
        let r = scenes::regularity::regularity(
            cloud.positions(),
            test.as_ref().map_or(&[][..], |t| t.positions()),
        );
        if a.json {
            println!(
                "{}",
                serde_json::json!({"scene": spec.label(), "test_points": what, "regularity": r})
            );
        } else {
            let bare = if r.bare_fraction.is_nan() {
                "—".to_string()
            } else {
                format!("{:.3}", r.bare_fraction)
            };
            println!(
                "| {} | {} | {:.4e} | {:.3} | {bare} | {what} |",
                spec.label(),
                r.samples,
                r.nn_mean,
                r.nn_cv,
            );
        }
    }
    Ok(())
}

/// Independent area-uniform points of a scene's surface, and how they were made.
fn test_points(
    spec: &scenes::SceneSpec,
    n: usize,
) -> anyhow::Result<(Option<scenes::PointCloud>, String)> {
    use scenes::spec::SceneSource;
    Ok(match &spec.source {
        SceneSource::Generator {
            generator, seed, ..
        } => (
            Some(generator.test_points(n, *seed)?),
            format!("{n} of {}'s surface (seed {seed})", generator.name()),
        ),
        SceneSource::Ply { path, .. } => {
            let opts = scenes::ply::PlyOptions {
                sample: Some(n),
                seed: 7,
            };
            match scenes::ply::read_noted(path, &opts) {
                Ok((cloud, _)) => (Some(cloud.with_up(spec.up)?), format!("{n} of the mesh")),
                Err(e) if e.to_string().contains("face") => (None, "— (no faces)".into()),
                Err(e) => return Err(e.into()),
            }
        }
        _ => (None, "— (no surface)".into()),
    })
}
