//! Which figures of a run are compared how: the one place that says what is deterministic.
//!
//! A figure nobody classified is compared exactly: a new column that turns out to vary from
//! run to run fails the check the first time, and is then classified here, with its reason,
//! rather than slipping through unchecked.

/// How `splatbench check` compares one figure.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Class {
    /// Deterministic for a seed, scene, build and path on any adapter (the method's selection
    /// is plain Rust over plain data): compared exactly.
    Exact,
    /// Deterministic on one adapter, but counted by or fed back from the GPU (SPT's interval
    /// test, occlusion queries): compared exactly when the run's adapter is the baseline's,
    /// shown and not compared otherwise.
    Adapter,
    /// An image metric: compared within the baseline's tolerance for the same or another
    /// adapter.
    Image,
    /// A time: reported as the ratio of the medians; fails only with `--timing-gate`.
    Timing,
    /// Depends on the machine or on thread timing (resident memory, the loader's queue):
    /// recorded, never compared.
    Machine,
}

/// What a run is, as far as classification needs: read off its `frames.csv` header and its
/// parameters.
#[derive(Debug, Clone, Copy, Default)]
pub struct RunTraits {
    /// The run's draws pass SPT's interval test on the GPU (`gpu_passed` column): what it
    /// calls `points_drawn` is the GPU's count.
    pub interval_tested: bool,
    /// Occlusion culling (`clouds_queried` column): the queries' answers feed the next
    /// frame's selection, so every selection count is the adapter's.
    pub occlusion_culled: bool,
    /// QSplat's frame-rate control (`target_ms`): the selection follows the last frame's
    /// time, so the counts are the machine's.
    pub time_controlled: bool,
    /// Asynchronous loading without a simulated latency (LPC, MWKD with `delay_frames=0`,
    /// their default): which chunks are in core in a frame depends on how fast the loader
    /// thread decodes, so the selection counts are the machine's. With `delay_frames ≥ 1`
    /// the loader delivers in exactly that many frames and the counts repeat.
    pub timing_loaded: bool,
}

impl RunTraits {
    /// The traits of a run of `method` with `params` whose `frames.csv` has `columns`.
    pub fn of(
        method: &str,
        params: &std::collections::BTreeMap<String, String>,
        columns: &[String],
    ) -> Self {
        let has = |c: &str| columns.iter().any(|x| x == c);
        let param = |k: &str| params.get(k).map(String::as_str);
        let loads = has("chunks_failed");
        let sync = param("load") == Some("sync");
        let delayed = param("delay_frames")
            .and_then(|d| d.parse::<u32>().ok())
            .is_some_and(|d| d >= 1);
        Self {
            interval_tested: has("gpu_passed"),
            occlusion_culled: has("clouds_queried"),
            time_controlled: method == "qsplat" && param("target_ms").is_some(),
            timing_loaded: loads && !sync && !delayed,
        }
    }
}

/// Columns of `frames.csv` that identify a row rather than measure it (aligned by, or part
/// of the run's identity): not compared as figures.
pub const IDENTITY_COLUMNS: [&str; 7] = [
    "frame", "method", "scene", "path", "target", "eps_px", "budget",
];

/// The class of `frames.csv` column `column` in a run with `traits`.
pub fn column_class(column: &str, traits: RunTraits) -> Class {
    match column {
        "gpu_ms" | "wall_ms" | "cpu_select_ms" | "splats_per_s" | "metrics_ms" => Class::Timing,
        "psnr_db" | "ssim" | "flip_mean" | "hole_ratio" | "extra_coverage" | "popping_flip" => {
            Class::Image
        }
        // Warped popping: FLIP maps and the reference's depth, as the image metrics.
        c if c.starts_with("warped_")
            || c.starts_with("popping_warped_")
            || c.starts_with("pop_events_")
            || c.starts_with("warp_valid_") =>
        {
            Class::Image
        }
        // Resident memory is the machine's; the loader's queue length is thread timing; the
        // bandwidth estimate is bytes over the loader's measured busy time.
        "rss_bytes" | "loader_pending" | "bandwidth_est_bytes_per_s" => Class::Machine,
        // Counted on the GPU.
        "gpu_passed" | "gpu_culled_fraction" | "clouds_queried" | "clouds_occluded" => {
            Class::Adapter
        }
        // A chunk that failed to load is never expected: compared exactly in every run.
        "chunks_failed" => Class::Exact,
        // SPT's prefix is chosen on the CPU; the interval test that thins it runs on the GPU.
        "points_drawn" if traits.interval_tested => Class::Adapter,
        _ if traits.time_controlled || traits.timing_loaded => Class::Machine,
        _ if traits.occlusion_culled => Class::Adapter,
        _ => Class::Exact,
    }
}

/// The class of a number of `build.json` (its top-level fields and its `extra`): times
/// (`seconds`, `*_seconds`) and rates (`*_per_s`) are timings, the process's peak memory is
/// the machine's, everything else (sizes, counts, the estimates the build made) is exact.
pub fn build_class(key: &str) -> Class {
    if is_rate(key) || key == "seconds" || key.ends_with("_seconds") {
        Class::Timing
    } else if key == "peak_rss_bytes" {
        Class::Machine
    } else {
        Class::Exact
    }
}

/// True for a rate (`points_per_s`): larger is faster.
pub fn is_rate(key: &str) -> bool {
    key.ends_with("_per_s")
}

/// The class of a number of `summary.json` outside the frames and the build.
pub fn process_class(key: &str) -> Class {
    match key {
        "run_seconds" => Class::Timing,
        _ => Class::Machine,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cols(c: &[&str]) -> Vec<String> {
        c.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn selection_counts_are_exact_unless_fed_back() {
        let none = RunTraits::default();
        assert_eq!(column_class("points_drawn", none), Class::Exact);
        assert_eq!(column_class("front_nodes", none), Class::Exact);
        assert_eq!(column_class("flip_mean", none), Class::Image);
        assert_eq!(column_class("popping_flip", none), Class::Image);
        for c in crate::results::FrameRow::COLUMNS
            .iter()
            .filter(|c| c.contains("_l1") || c.contains("_l7"))
        {
            assert_eq!(column_class(c, none), Class::Image, "{c}");
        }
        assert_eq!(column_class("gpu_ms", none), Class::Timing);
        assert_eq!(
            column_class("bandwidth_est_bytes_per_s", none),
            Class::Machine,
            "a rate the loader measures from its thread's timing"
        );
        assert_eq!(column_class("rss_bytes", none), Class::Machine);
        let spt = RunTraits::of("spt", &Default::default(), &cols(&["gpu_passed"]));
        assert_eq!(column_class("points_drawn", spt), Class::Adapter);
        assert_eq!(column_class("prefix_points", spt), Class::Exact);
        let occ = RunTraits::of("lpc", &Default::default(), &cols(&["clouds_queried"]));
        assert_eq!(column_class("chunks_drawn", occ), Class::Adapter);
        assert_eq!(column_class("chunks_failed", occ), Class::Exact);
    }

    #[test]
    fn loading_is_deterministic_only_with_a_simulated_latency() {
        let loads = cols(&["chunks_failed"]);
        let p = |kv: &[(&str, &str)]| {
            kv.iter()
                .map(|(k, v)| (k.to_string(), v.to_string()))
                .collect()
        };
        let async0 = RunTraits::of("lpc", &p(&[]), &loads);
        assert_eq!(column_class("points_drawn", async0), Class::Machine);
        let delayed = RunTraits::of("lpc", &p(&[("delay_frames", "1")]), &loads);
        assert_eq!(column_class("points_drawn", delayed), Class::Exact);
        let sync = RunTraits::of("mwkd", &p(&[("load", "sync")]), &loads);
        assert_eq!(column_class("points_drawn", sync), Class::Exact);
        let qs = RunTraits::of("qsplat", &p(&[("target_ms", "40")]), &[]);
        assert_eq!(column_class("points_drawn", qs), Class::Machine);
    }

    #[test]
    fn build_times_and_rates_are_timings() {
        for k in ["seconds", "points_per_s", "split_seconds", "tree_seconds"] {
            assert_eq!(build_class(k), Class::Timing, "{k}");
        }
        for k in [
            "bytes_out",
            "bits_per_sample",
            "nodes",
            "input_spacing",
            "repo_bytes",
        ] {
            assert_eq!(build_class(k), Class::Exact, "{k}");
        }
        assert_eq!(build_class("peak_rss_bytes"), Class::Machine);
    }
}
