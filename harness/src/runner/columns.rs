//! The `frames.csv` columns a method adds and the feedback a frame gets from the last.

use methods::{DrawList, Feedback, LodMethod};
use scenes::View;

use crate::render::{FrameStats, Renderer};

/// Columns appended for methods whose splats pass a vertex-stage interval test (SPT):
/// splats sent, splats that passed (GPU counter), and the fraction culled on the GPU.
pub const INTERVAL_COLUMNS: [&str; 3] = ["prefix_points", "gpu_passed", "gpu_culled_fraction"];

/// Columns appended for occlusion-culled methods ([`LodMethod::occlusion_culled`]): the
/// occlusion queries issued this frame and the candidates they found occluded (at most the
/// threshold's fragments passed). Candidates visible without a query (sphere at the near
/// plane) count in neither.
pub const OCCLUSION_COLUMNS: [&str; 2] = ["clouds_queried", "clouds_occluded"];

/// Columns appended for methods that load chunks, after `chunks_failed`: what their
/// data-access layer did during the frame ([`methods::store::access::Traffic`]): stored
/// bytes its source read, requests queued, queued requests dropped because no frame wanted
/// them any more, fetches that failed (every try), chunks delivered after every frame that
/// wanted them had passed; then the bandwidth it measured over its recent responses at the
/// end of the frame, bytes/s ([`methods::store::access::Throughput`]; 0 before the first
/// response).
pub const TRAFFIC_COLUMNS: [&str; 6] = [
    "bytes_fetched",
    "requests_issued",
    "requests_cancelled",
    "requests_failed",
    "stale_deliveries",
    "bandwidth_est_bytes_per_s",
];

/// The extra `frames.csv` columns for `method`, in order: its own, then the interval columns
/// (interval-tested methods), then the occlusion columns (occlusion-culled methods).
pub fn frame_columns(method: &dyn LodMethod) -> Vec<&'static str> {
    let mut columns: Vec<&'static str> = method.extra_columns().to_vec();
    if method.interval_tested() {
        columns.extend(INTERVAL_COLUMNS);
    }
    if method.occlusion_culled() {
        columns.extend(OCCLUSION_COLUMNS);
    }
    if method.loads_chunks() {
        columns.push("chunks_failed");
        columns.extend(TRAFFIC_COLUMNS);
    }
    columns
}

/// The values of [`frame_columns`] for one frame: the list's counters, then what the
/// renderer counted, then the chunks that have failed to load so far (`failed`) and the
/// frame's traffic (`traffic`: [`Traffic::since`](methods::store::access::Traffic::since)
/// the previous frame) and the method's measured throughput.
pub fn frame_counters(
    method: &dyn LodMethod,
    list: &DrawList,
    stats: &FrameStats,
    failed: usize,
    traffic: methods::store::access::Traffic,
) -> Vec<f64> {
    let mut counters = list.counters.clone();
    if method.interval_tested() {
        let passed = stats.gpu_passed.unwrap_or(0);
        counters.extend([
            stats.points as f64,
            passed as f64,
            if stats.points > 0 {
                1.0 - passed as f64 / stats.points as f64
            } else {
                0.0
            },
        ]);
    }
    if method.occlusion_culled() {
        let o = stats.occlusion.as_ref();
        counters.extend([
            o.map_or(0, |o| o.clouds_queried) as f64,
            o.map_or(0, |o| o.clouds_occluded) as f64,
        ]);
    }
    if method.loads_chunks() {
        counters.push(failed as f64);
        counters.extend(
            [
                traffic.bytes,
                traffic.issued,
                traffic.cancelled,
                traffic.failed,
                traffic.stale,
            ]
            .map(|v| v as f64),
        );
        counters.push(method.throughput().map_or(0.0, |t| t.bytes_per_s));
    }
    counters
}

/// The feedback for frame `frame` at `view`: the renderer's cache, and from the previous
/// frame (`last`: its stats and view) its times, whether the camera moved, and the
/// candidates its occlusion queries found visible (this frame's phase 1) and occluded.
pub fn next_feedback(
    frame: u64,
    renderer: &Renderer<'_>,
    last: Option<&(FrameStats, View)>,
    view: &View,
) -> Feedback {
    let occ = last.and_then(|(s, _)| s.occlusion.as_ref());
    Feedback {
        frame,
        cached: renderer.cached(),
        occluded: occ
            .map(|o| o.occluded.iter().copied().collect())
            .unwrap_or_default(),
        visible: occ
            .map(|o| o.visible.iter().copied().collect())
            .unwrap_or_default(),
        last_gpu_ms: last.and_then(|(s, _)| s.gpu_ms),
        last_wall_ms: last.map(|(s, _)| s.wall_ms),
        camera_still: last.is_some_and(|(_, v)| v.camera == view.camera),
    }
}
