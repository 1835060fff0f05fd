//! `summary.json`: what a run reports once, beside `frames.csv`.

use methods::{BuildStats, Params, Target};
use scenes::Aabb;

use crate::gpu::AdapterDesc;
use crate::render::Kernel;
use crate::results::{FrameRow, median};

/// A chunk that failed to load during a run.
#[derive(Debug, Clone, serde::Serialize)]
pub struct FailedChunk {
    /// Chunk (LPC cloud, MWKD node) id.
    pub id: methods::ChunkId,
    /// The first frame in which the failure was seen.
    pub frame: u64,
    /// The error, naming the file and the chunk.
    pub error: String,
}

/// `summary.json`.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Summary {
    /// False until the run finished.
    pub complete: bool,
    /// Adapter.
    pub adapter: AdapterDesc,
    /// Git commit of the binary (`-dirty` when built from a modified tree).
    pub git_commit: String,
    /// The command line of the process that ran it ([`crate::results::invocation`]).
    pub command: String,
    /// Seed.
    pub seed: u64,
    /// Resolution.
    pub width: u32,
    /// Resolution.
    pub height: u32,
    /// Method.
    pub method: String,
    /// Method parameters as given.
    pub params: Params,
    /// Target.
    pub target: Target,
    /// Kernel.
    pub kernel: Kernel,
    /// Rasteriser (`quads` or `compute`).
    pub raster: crate::render::Raster,
    /// The reference images' rasteriser (the run's unless `--reference-raster`).
    pub reference_raster: crate::render::Raster,
    /// The reference images' splat kernel (the run's unless `--reference-kernel`; square
    /// with the compute rasteriser).
    pub reference_kernel: crate::render::Kernel,
    /// The shading drawn (`--shading`, with `auto` resolved for the scene).
    pub shading: crate::render::Shading,
    /// Camera path.
    pub path: String,
    /// Frames.
    pub frames: usize,
    /// GPU cache budget, bytes.
    pub gpu_cache_budget_bytes: u64,
    /// The scene.
    pub scene: SceneStats,
    /// The build.
    pub build: BuildStats,
    /// `gpu_ms` or `wall_ms`: what `splats_per_s` divides by.
    pub splats_per_s_basis: &'static str,
    /// Medians over the frames.
    pub medians: Medians,
    /// 95th percentiles over the frames (popping).
    pub p95: Tails,
    /// Chunks that failed to load: the frames drew without them, so they are not a
    /// faithful measurement (the run fails unless `--allow-missing-chunks`).
    pub failed_chunks: Vec<FailedChunk>,
    /// Methods that load chunks: their data-access layer's totals over the frames (the
    /// sums of the `frames.csv` traffic columns).
    pub traffic: Option<TrafficTotals>,
    /// Peak resident set size of the process.
    pub peak_rss_bytes: u64,
    /// What the method holds in memory after the last frame, mapped files excluded
    /// ([`methods::MethodStats::resident_bytes`]: its index, decoding tables, decoded caches).
    pub method_resident_bytes: u64,
    /// The largest resident set of each kind seen at the end of a frame (Linux; absent
    /// elsewhere): what the peak is made of (anonymous, file-backed, shared memory).
    pub rss_max: Option<crate::rss::Breakdown>,
    /// Wall time of the whole run, s.
    pub run_seconds: f64,
    /// The documented effect that dominates this run's result and the parameter that
    /// changes it ([`methods::MethodKind::known_effect`]), if one does.
    pub known_effect: Option<methods::KnownEffect>,
}

/// A run's data traffic in `summary.json` ([`methods::store::access::Traffic`] over the
/// recorded frames; frame 0's share includes the untimed warm-up frame's).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct TrafficTotals {
    /// Stored bytes read from the repository.
    pub bytes_fetched: u64,
    /// Requests queued.
    pub requests_issued: u64,
    /// Queued requests dropped because no frame wanted them any more.
    pub requests_cancelled: u64,
    /// Fetches that failed, every try counted.
    pub requests_failed: u64,
    /// Chunks delivered after every frame that wanted them had passed.
    pub stale_deliveries: u64,
    /// The measured bandwidth at the end of the run, bytes/s (`None`: no response).
    pub bandwidth_est_bytes_per_s: Option<f64>,
}

impl TrafficTotals {
    /// Totals for `traffic` (since the method was opened) and its last `throughput`.
    pub fn of(
        traffic: &methods::store::access::Traffic,
        throughput: Option<methods::store::access::Throughput>,
    ) -> Self {
        Self {
            bytes_fetched: traffic.bytes,
            requests_issued: traffic.issued,
            requests_cancelled: traffic.cancelled,
            requests_failed: traffic.failed,
            stale_deliveries: traffic.stale,
            bandwidth_est_bytes_per_s: throughput.map(|t| t.bytes_per_s),
        }
    }
}

/// Scene facts in `summary.json`.
#[derive(Debug, Clone, serde::Serialize)]
pub struct SceneStats {
    /// Label.
    pub label: String,
    /// Spec as given.
    pub spec: String,
    /// Samples.
    pub points: u64,
    /// Attributes.
    pub attributes: String,
    /// Local bounds of every sample.
    pub bounds: Aabb,
    /// What the camera paths frame: the bounds without far outliers ([`scenes::framing`]).
    pub framed_bounds: Aabb,
    /// Samples outside the framed box (still drawn, not framed).
    pub outside_frame: u64,
    /// Samples of the reference whose k-NN leaf radius was capped as isolated
    /// ([`methods::leaf`]); `None` without metrics.
    pub reference_radii_capped: Option<u64>,
    /// World origin.
    pub origin: [f64; 3],
    /// Content hash (hex).
    pub content_hash: String,
    /// What the reader dropped or ignored (attributes, invalid points) and what the framing
    /// left out, one sentence each (also printed as warnings).
    pub warnings: Vec<String>,
}

/// Medians over a run's frames.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct Medians {
    /// Splats drawn.
    pub points_drawn: Option<f64>,
    /// GPU ms.
    pub gpu_ms: Option<f64>,
    /// Wall ms.
    pub wall_ms: Option<f64>,
    /// Selection ms.
    pub cpu_select_ms: Option<f64>,
    /// Splats/s.
    pub splats_per_s: Option<f64>,
    /// PSNR dB.
    pub psnr_db: Option<f64>,
    /// SSIM.
    pub ssim: Option<f64>,
    /// Mean FLIP.
    pub flip_mean: Option<f64>,
    /// Hole ratio.
    pub hole_ratio: Option<f64>,
    /// Extra coverage.
    pub extra_coverage: Option<f64>,
    /// Popping FLIP.
    pub popping_flip: Option<f64>,
    /// Warped popping at lag 1 (`popping_warped_l1`).
    pub popping_warped_l1: Option<f64>,
    /// Warped popping at lag 7.
    pub popping_warped_l7: Option<f64>,
    /// Pop events at lag 1.
    pub pop_events_l1: Option<f64>,
    /// Pop events at lag 7.
    pub pop_events_l7: Option<f64>,
    /// Image-metrics time per frame, ms.
    pub metrics_ms: Option<f64>,
}

/// 95th percentiles over the frames of the figures whose tail matters: popping comes in
/// bursts, which a median hides.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct Tails {
    /// Popping FLIP (lag 1, unwarped).
    pub popping_flip: Option<f64>,
    /// Warped popping at lag 1.
    pub popping_warped_l1: Option<f64>,
    /// Warped popping at lag 7.
    pub popping_warped_l7: Option<f64>,
    /// Pop events at lag 1.
    pub pop_events_l1: Option<f64>,
    /// Pop events at lag 7.
    pub pop_events_l7: Option<f64>,
}

impl Tails {
    pub(super) fn of(rows: &[FrameRow]) -> Self {
        let p = |f: fn(&FrameRow) -> Option<f64>| {
            crate::results::quantile(rows.iter().filter_map(f), 0.95)
        };
        Self {
            popping_flip: p(|r| r.popping_flip),
            popping_warped_l1: p(|r| r.popping_warped_l1),
            popping_warped_l7: p(|r| r.popping_warped_l7),
            pop_events_l1: p(|r| r.pop_events_l1.map(|n| n as f64)),
            pop_events_l7: p(|r| r.pop_events_l7.map(|n| n as f64)),
        }
    }
}

impl Medians {
    pub(super) fn of(rows: &[FrameRow]) -> Self {
        let m = |f: fn(&FrameRow) -> Option<f64>| median(rows.iter().filter_map(f));
        Self {
            points_drawn: m(|r| Some(r.points_drawn as f64)),
            gpu_ms: m(|r| r.gpu_ms),
            wall_ms: m(|r| Some(r.wall_ms)),
            cpu_select_ms: m(|r| Some(r.cpu_select_ms)),
            splats_per_s: m(|r| Some(r.splats_per_s)),
            psnr_db: m(|r| r.psnr_db),
            ssim: m(|r| r.ssim),
            flip_mean: m(|r| r.flip_mean),
            hole_ratio: m(|r| r.hole_ratio),
            extra_coverage: m(|r| r.extra_coverage),
            popping_flip: m(|r| r.popping_flip),
            popping_warped_l1: m(|r| r.popping_warped_l1),
            popping_warped_l7: m(|r| r.popping_warped_l7),
            pop_events_l1: m(|r| r.pop_events_l1.map(|n| n as f64)),
            pop_events_l7: m(|r| r.pop_events_l7.map(|n| n as f64)),
            metrics_ms: m(|r| r.metrics_ms),
        }
    }
}
