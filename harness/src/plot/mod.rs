//! Plots of benchmark runs, drawn only from the runs' `frames.csv` files.
//!
//! Input contract: a run folder holds `frames.csv` whose header contains the columns of
//! [`FRAME_COLUMNS`] (any order, matched by name; extra columns, e.g. a method's own
//! counters, are ignored). Per row:
//! - `method`, `scene`, `path` are free text; `target` is `eps` or `budget`;
//! - `eps_px`, `budget` and the image-metric columns (`psnr_db`, `ssim`, `flip_mean`,
//!   `hole_ratio`, `extra_coverage`, `popping_flip`, `popping_warped_l1`,
//!   `popping_warped_l7`) may be empty (no reference for that run; the popping columns also
//!   in the frames before their lag); the popping columns may also be missing from the
//!   header (files written before they existed);
//! - `gpu_ms` may be empty too (an adapter without timestamp queries);
//! - every other column must be a number: integer columns (`frame`, `budget`,
//!   `points_drawn`, `chunks_drawn`, `upload_bytes`, `rss_bytes`, `gpu_cache_bytes`) as
//!   unsigned integers, the others as finite decimals.
//!
//! A missing column, an unparsable or non-finite number, or a file without any frame is an
//! error naming the file (and the column and row, 1-based data row plus file line).
//!
//! Output contract: [`plot_run`] writes `timeline.png` and `timeline.svg` into the run
//! folder, [`plot_comparison`] writes `comparison.png` and `comparison.svg` into its output
//! folder; both return the paths written. Every file is written atomically (temporary file
//! plus rename). PNGs are 8-bit RGB of [`TIMELINE_SIZE`] / [`COMPARISON_SIZE`] pixels; SVGs
//! have the same size in user units.
//!
//! - Timeline: title "method · scene · path", three stacked panels against frame number:
//!   points drawn; `gpu_ms` and `wall_ms`; image error (`flip_mean` and `hole_ratio` on one
//!   0..1 axis). Frames are sorted by frame number; empty values leave gaps.
//! - Comparison: left, per-frame `flip_mean` (y) against `points_drawn` (x), one colour and
//!   legend entry per run; x is logarithmic when all x > 0 and max/min > 10. Right, two bar
//!   panels, one labelled bar per run: the median `splats_per_s` (top) and, below, the
//!   median `popping_flip` (left) and `popping_warped_l1` (right; no bar for a run without
//!   one). A run is labelled by its method,
//!   plus its target when the runs' targets differ, plus its folder name if labels still
//!   collide.
//!
//! Sweeps (`splatbench sweep`): a sweep folder holds `sweep.csv`, header [`SWEEP_COLUMNS`],
//! one row per target ([`SweepRow`], written by [`write_sweep`] atomically, read back by
//! [`read_sweep`] with the same rules and errors as `frames.csv`; `params` may be empty).
//! [`plot_sweep`] writes `sweep.png`/`sweep.svg` into the sweep folder, [`plot_sweeps`]
//! `sweep-comparison.png`/`.svg` into its output folder; both [`SWEEP_SIZE`], one figure:
//! median `flip_mean` (y, from 0) against median `points_drawn` per frame (x, logarithmic by
//! the comparison's rule), one line per sweep through its targets in order of points drawn,
//! each point annotated with its target ("25k", "2 px"). A sweep is labelled by its method and
//! parameters, plus its folder name if labels collide. Targets without a FLIP value (no
//! reference) are left out.
//!
//! Text uses the bundled DejaVu Sans (`assets/DejaVuSans.ttf`, licence beside it),
//! registered once as family "sans-serif" for plotters' `ab_glyph` backend: no system fonts.

use std::collections::HashMap;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use anyhow::{Context, anyhow, bail};
use plotters::coord::Shift;
use plotters::coord::ranged1d::{AsRangedCoord, ValueFormatter};
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crate::image::write_atomically;

mod comparison;
mod sweep;
mod table;
mod timeline;
mod tune;

use comparison::*;
use sweep::*;
pub use sweep::{
    SWEEP_COLUMNS, SWEEP_SIZE, SweepRow, plot_sweep, plot_sweeps, read_sweep, write_sweep,
};
use table::*;
use timeline::*;
pub use tune::{TUNE_SIZE, TuneFigure, plot_tune};

/// The leading columns of every `frames.csv`, in the order runs write them.
pub const FRAME_COLUMNS: [&str; 24] = [
    "frame",
    "method",
    "scene",
    "path",
    "target",
    "eps_px",
    "budget",
    "points_drawn",
    "chunks_drawn",
    "gpu_ms",
    "wall_ms",
    "cpu_select_ms",
    "upload_bytes",
    "splats_per_s",
    "rss_bytes",
    "gpu_cache_bytes",
    "psnr_db",
    "ssim",
    "flip_mean",
    "hole_ratio",
    "extra_coverage",
    "popping_flip",
    "popping_warped_l1",
    "popping_warped_l7",
];

/// Size in pixels of `timeline.png` (and of `timeline.svg` in user units).
pub const TIMELINE_SIZE: (u32, u32) = (1280, 1024);

/// Size in pixels of `comparison.png` (and of `comparison.svg` in user units).
pub const COMPARISON_SIZE: (u32, u32) = (1600, 720);

/// The font family every plot uses; the bundled DejaVu Sans is registered under it.
pub(crate) const FONT: &str = "sans-serif";

/// DejaVu Sans, bundled so that plots need no system font.
const FONT_BYTES: &[u8] = include_bytes!("../../assets/DejaVuSans.ttf");

/// Tableau 10 colours, for runs and series.
const PALETTE: [RGBColor; 10] = [
    RGBColor(0x4E, 0x79, 0xA7),
    RGBColor(0xF2, 0x8E, 0x2B),
    RGBColor(0xE1, 0x57, 0x59),
    RGBColor(0x76, 0xB7, 0xB2),
    RGBColor(0x59, 0xA1, 0x4F),
    RGBColor(0xED, 0xC9, 0x48),
    RGBColor(0xB0, 0x7A, 0xA1),
    RGBColor(0xFF, 0x9D, 0xA7),
    RGBColor(0x9C, 0x75, 0x5F),
    RGBColor(0xBA, 0xB0, 0xAC),
];

/// One row of `frames.csv` (its leading columns), as read back for plots and reports.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameRecord {
    /// Frame number along the camera path.
    pub frame: u64,
    /// Method name.
    pub method: String,
    /// Scene name.
    pub scene: String,
    /// Camera path name.
    pub path: String,
    /// `eps` (screen-space error target) or `budget` (point budget target).
    pub target: String,
    /// Screen-space error tolerance in pixels, when the target is `eps`.
    pub eps_px: Option<f64>,
    /// Point budget, when the target is `budget`.
    pub budget: Option<u64>,
    /// Points (splats) drawn this frame.
    pub points_drawn: u64,
    /// Chunks / nodes drawn this frame.
    pub chunks_drawn: u64,
    /// GPU time in ms (empty when the adapter has no timestamp queries).
    pub gpu_ms: Option<f64>,
    /// Wall-clock frame time in ms.
    pub wall_ms: f64,
    /// CPU selection (traversal) time in ms.
    pub cpu_select_ms: f64,
    /// Bytes uploaded to the GPU this frame.
    pub upload_bytes: u64,
    /// Throughput, splats per second.
    pub splats_per_s: f64,
    /// Resident set size of the process in bytes.
    pub rss_bytes: u64,
    /// Bytes held in the method's GPU cache.
    pub gpu_cache_bytes: u64,
    /// PSNR against the reference, dB.
    pub psnr_db: Option<f64>,
    /// Mean SSIM against the reference.
    pub ssim: Option<f64>,
    /// Mean FLIP error against the reference.
    pub flip_mean: Option<f64>,
    /// Hole ratio against the reference.
    pub hole_ratio: Option<f64>,
    /// Extra coverage against the reference.
    pub extra_coverage: Option<f64>,
    /// Popping FLIP ([`crate::metrics::PathMetrics`]); empty for frame 0, without a
    /// reference, and in files written before the column existed.
    pub popping_flip: Option<f64>,
    /// Warped popping at lag 1 ([`crate::metrics::popping`]); empty for frame 0, without a
    /// reference, and in files written before the column existed.
    pub popping_warped_l1: Option<f64>,
    /// Warped popping at lag 7; empty for frames 0–6 and as above.
    pub popping_warped_l7: Option<f64>,
}

/// Reads `frames.csv` by header name (extra columns ignored). Errors name the file, and for
/// bad values the column and the row. A file without frames is an error.
pub fn read_frames(csv_path: &Path) -> anyhow::Result<Vec<FrameRecord>> {
    read_table(csv_path, &FRAME_COLUMNS, "frames", |row| row.parse())
}

/// Plots one run: reads `run_dir/frames.csv`, writes `timeline.png` and `timeline.svg` into
/// `run_dir`, returns their paths.
pub fn plot_run(run_dir: &Path) -> anyhow::Result<Vec<PathBuf>> {
    let mut frames = read_frames(&run_dir.join("frames.csv"))?;
    frames.sort_by_key(|f| f.frame);
    let first = frames
        .first()
        .ok_or_else(|| anyhow!("no frames in {}", run_dir.join("frames.csv").display()))?;
    let title = format!("{} · {} · {}", first.method, first.scene, first.path);
    render_both(
        run_dir,
        "timeline",
        TIMELINE_SIZE,
        &Timeline {
            title,
            frames: &frames,
        },
    )
}

/// Plots several runs against each other: writes `comparison.png` and `comparison.svg` into
/// `out_dir`, returns their paths.
pub fn plot_comparison(run_dirs: &[PathBuf], out_dir: &Path) -> anyhow::Result<Vec<PathBuf>> {
    if run_dirs.is_empty() {
        bail!("no runs to compare");
    }
    let runs = run_dirs
        .iter()
        .map(|dir| read_frames(&dir.join("frames.csv")))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let labels = run_labels(run_dirs, &runs);
    let series: Vec<RunSeries> = runs
        .iter()
        .zip(labels)
        .enumerate()
        .map(|(i, (frames, label))| RunSeries {
            label,
            colour: PALETTE[i % PALETTE.len()],
            flip_vs_points: frames
                .iter()
                .filter_map(|f| Some((f.points_drawn as f64, f.flip_mean?)))
                .collect(),
            median_splats_per_s: median(frames.iter().map(|f| f.splats_per_s).collect()),
            median_popping_flip: crate::results::median(
                frames.iter().filter_map(|f| f.popping_flip),
            ),
            median_popping_warped_l1: crate::results::median(
                frames.iter().filter_map(|f| f.popping_warped_l1),
            ),
        })
        .collect();
    render_both(
        out_dir,
        "comparison",
        COMPARISON_SIZE,
        &Comparison { runs: series },
    )
}

/// Registers the bundled font as "sans-serif", once per process.
pub(crate) fn ensure_font() -> anyhow::Result<()> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        plotters::style::register_font(FONT, FontStyle::Normal, FONT_BYTES).is_ok()
    });
    if ok {
        Ok(())
    } else {
        bail!("the bundled font assets/DejaVuSans.ttf is not a valid font")
    }
}

/// A figure that can be drawn on any plotters backend.
trait Figure {
    /// Draws the whole figure on `root`.
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> anyhow::Result<()>
    where
        DB::ErrorType: 'static;
}

/// Draws `figure` twice, into a PNG and an SVG named `stem` in `dir`, each written
/// atomically; returns both paths.
fn render_both(
    dir: &Path,
    stem: &str,
    size: (u32, u32),
    figure: &impl Figure,
) -> anyhow::Result<Vec<PathBuf>> {
    ensure_font()?;
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let png_path = dir.join(format!("{stem}.png"));
    let svg_path = dir.join(format!("{stem}.svg"));

    let mut rgb = vec![0u8; size.0 as usize * size.1 as usize * 3];
    {
        let area = BitMapBackend::with_buffer(&mut rgb, size).into_drawing_area();
        figure
            .draw(&area)
            .with_context(|| format!("cannot draw {}", png_path.display()))?;
        area.present()
            .with_context(|| format!("cannot draw {}", png_path.display()))?;
    }
    let mut png = Vec::new();
    ::image::ImageEncoder::write_image(
        ::image::codecs::png::PngEncoder::new(&mut png),
        &rgb,
        size.0,
        size.1,
        ::image::ExtendedColorType::Rgb8,
    )
    .with_context(|| format!("cannot encode {}", png_path.display()))?;
    write_atomically(&png_path, &png)
        .with_context(|| format!("cannot write {}", png_path.display()))?;

    let mut svg = String::new();
    {
        let area = SVGBackend::with_string(&mut svg, size).into_drawing_area();
        figure
            .draw(&area)
            .with_context(|| format!("cannot draw {}", svg_path.display()))?;
        area.present()
            .with_context(|| format!("cannot draw {}", svg_path.display()))?;
    }
    write_atomically(&svg_path, svg.as_bytes())
        .with_context(|| format!("cannot write {}", svg_path.display()))?;
    Ok(vec![png_path, svg_path])
}

/// Draws `chart`'s legend the way every figure does: upper right, on a translucent white
/// box with a grey border, labels in the bundled font at `size` points.
fn draw_legend<'a, DB, CT>(chart: &mut ChartContext<'a, DB, CT>, size: u32) -> anyhow::Result<()>
where
    DB: DrawingBackend + 'a,
    DB::ErrorType: 'static,
    CT: CoordTranslate,
{
    draw_legend_at(chart, size, SeriesLabelPosition::UpperRight)
}

/// [`draw_legend`] at corner `at`.
fn draw_legend_at<'a, DB, CT>(
    chart: &mut ChartContext<'a, DB, CT>,
    size: u32,
    at: SeriesLabelPosition,
) -> anyhow::Result<()>
where
    DB: DrawingBackend + 'a,
    DB::ErrorType: 'static,
    CT: CoordTranslate,
{
    chart
        .configure_series_labels()
        .position(at)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK.mix(0.4))
        .label_font((FONT, size))
        .draw()?;
    Ok(())
}

/// Median of `values` (mean of the middle two for an even count; 0 when empty).
fn median(mut values: Vec<f64>) -> f64 {
    values.sort_by(f64::total_cmp);
    let n = values.len();
    match n {
        0 => 0.0,
        _ if n % 2 == 1 => values[n / 2],
        _ => 0.5 * (values[n / 2 - 1] + values[n / 2]),
    }
}

/// `lo..hi` with 2 % of the span (at least 0.25) added on each side, so that end points and
/// single frames are not drawn on the axis.
fn padded(lo: f64, hi: f64) -> Range<f64> {
    let pad = ((hi - lo) * 0.02).max(0.25);
    lo - pad..hi + pad
}

/// A top for an axis starting at 0 that shows `max` (1 when there is nothing to show).
fn nice_top(max: f64) -> f64 {
    if max > 0.0 && max.is_finite() {
        max * 1.08
    } else {
        1.0
    }
}

/// Compact number for labels, with at most 3 significant digits and an SI suffix:
/// 1.5k, 12M, 0.25, 175M.
fn si(v: f64) -> String {
    let a = v.abs();
    let (scaled, suffix) = if a >= 1e9 {
        (v / 1e9, "G")
    } else if a >= 1e6 {
        (v / 1e6, "M")
    } else if a >= 1e3 {
        (v / 1e3, "k")
    } else {
        (v, "")
    };
    let digits_before_point = if scaled == 0.0 {
        1
    } else {
        scaled.abs().log10().floor() as i32 + 1
    };
    let decimals = (3 - digits_before_point).clamp(0, 6) as usize;
    let mut text = format!("{scaled:.decimals$}");
    if text.contains('.') {
        let trimmed = text.trim_end_matches('0').trim_end_matches('.').len();
        text.truncate(trimmed);
    }
    if text == "-0" {
        text = String::from("0");
    }
    text + suffix
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn si_labels() {
        assert_eq!(si(175_489_000.0), "175M");
        assert_eq!(si(6_352_000.0), "6.35M");
        assert_eq!(si(1500.0), "1.5k");
        assert_eq!(si(0.05), "0.05");
        assert_eq!(si(4.5), "4.5");
        assert_eq!(si(0.0), "0");
        assert_eq!(si(-0.0001), "-0.0001");
        assert_eq!(si(2e9), "2G");
    }

    fn frame(frame: u64, points: u64, flip: Option<f64>, rss: u64) -> FrameRecord {
        FrameRecord {
            frame,
            method: "mwkd".into(),
            scene: "statue:5000:1".into(),
            path: "orbit".into(),
            target: "eps".into(),
            eps_px: Some(0.1f32 as f64),
            budget: None,
            points_drawn: points,
            chunks_drawn: 1,
            gpu_ms: None,
            wall_ms: 1.0,
            cpu_select_ms: 0.5,
            upload_bytes: 0,
            splats_per_s: points as f64 * 1e3,
            rss_bytes: rss,
            gpu_cache_bytes: 0,
            psnr_db: Some(30.0),
            ssim: None,
            flip_mean: flip,
            hole_ratio: Some(0.0),
            extra_coverage: None,
            popping_flip: flip.map(|f| f / 10.0),
            popping_warped_l1: flip.map(|f| f / 20.0),
            popping_warped_l7: flip.map(|f| f / 5.0),
        }
    }

    #[test]
    fn sweep_rows_summarise_and_round_trip() {
        let frames = [
            frame(0, 100, Some(0.2), 10),
            frame(1, 300, None, 30),
            frame(2, 200, Some(0.4), 20),
        ];
        let row = SweepRow::of_run(&frames, "vbo=400 fanout=6", 0.1).unwrap();
        assert_eq!(row.points_drawn_median, 200.0);
        assert!(
            (row.flip_mean_median.unwrap() - 0.3).abs() < 1e-12,
            "{row:?}"
        );
        assert_eq!(row.flip_mean_max, Some(0.4));
        assert_eq!(row.gpu_ms_median, None);
        assert_eq!(row.rss_bytes_max, 30);
        assert_eq!(
            (row.target.as_str(), row.value, row.frames),
            ("eps", 0.1, 3)
        );
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("sweep.csv");
        let mut other = row.clone();
        other.params = String::new();
        write_sweep(&path, &[row.clone(), other.clone()]).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.starts_with(&SWEEP_COLUMNS.join(",")), "{text}");
        assert!(text.contains(",eps,0.1,3,200,"), "{text}");
        assert_eq!(read_sweep(&path).unwrap(), vec![row, other]);
        let leftovers = std::fs::read_dir(dir.path()).unwrap().count();
        assert_eq!(leftovers, 1, "no temporary file left");
        assert!(SweepRow::of_run(&[], "", 1.0).is_err());
    }

    #[test]
    fn sweep_files_errors_name_file_column_row() {
        let dir = tempfile::tempdir().unwrap();
        let e = format!(
            "{:#}",
            plot_sweeps(&[dir.path().to_path_buf()], dir.path()).unwrap_err()
        );
        assert!(e.contains("no sweep.csv"), "{e}");
        let path = dir.path().join("sweep.csv");
        std::fs::write(&path, SWEEP_COLUMNS.join(",") + "\n").unwrap();
        let e = format!("{:#}", read_sweep(&path).unwrap_err());
        assert!(e.contains("no sweep rows in"), "{e}");
        std::fs::write(&path, "method,params\nmwkd,\n").unwrap();
        let e = format!("{:#}", read_sweep(&path).unwrap_err());
        assert!(e.contains("missing column 'scene'"), "{e}");
        let mut fields: Vec<&str> = vec!["lpc", "", "s", "orbit", "budget", "500", "2"];
        fields.extend(vec!["x"; SWEEP_COLUMNS.len() - 7]);
        let bad = format!("{}\n{}\n", SWEEP_COLUMNS.join(","), fields.join(","));
        std::fs::write(&path, bad).unwrap();
        let e = format!("{:#}", read_sweep(&path).unwrap_err());
        assert!(
            e.contains("row 1") && e.contains("points_drawn_median"),
            "{e}"
        );
    }

    /// Files written before the popping columns existed still read, as if they were empty.
    #[test]
    fn files_without_the_popping_columns_still_read() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("sweep.csv");
        let row = SweepRow::of_run(&[frame(0, 100, Some(0.25), 1)], "", 100.0).unwrap();
        assert_eq!(row.popping_flip_median, Some(0.025));
        write_sweep(&path, std::slice::from_ref(&row)).unwrap();
        assert_eq!(row.popping_warped_l1_median, Some(0.0125));
        // Drop the popping columns (each added after files were committed) from the header
        // and the row.
        let text = std::fs::read_to_string(&path).unwrap();
        let mut at: Vec<usize> = (0..SWEEP_COLUMNS.len())
            .filter(|&i| SWEEP_COLUMNS[i].starts_with("popping_"))
            .collect();
        assert_eq!(at.len(), 5);
        at.reverse();
        let old: String = text
            .lines()
            .map(|l| {
                let mut f: Vec<&str> = l.split(',').collect();
                for &i in &at {
                    f.remove(i);
                }
                f.join(",") + "\n"
            })
            .collect();
        std::fs::write(&path, old).unwrap();
        let read = read_sweep(&path).unwrap();
        assert_eq!(read[0].popping_flip_median, None);
        assert_eq!(read[0].popping_warped_l1_median, None);
        assert_eq!(read[0].popping_warped_l7_p95, None);
        assert_eq!(read[0].flip_mean_median, Some(0.25));
        // Other columns stay required.
        std::fs::write(&path, "method,params\nmwkd,\n").unwrap();
        assert!(read_sweep(&path).is_err());
    }

    #[test]
    fn points_axis_is_log_past_a_factor_ten() {
        assert!(matches!(
            PointsAxis::of([10.0, 1000.0].into_iter()),
            PointsAxis::Log(_)
        ));
        assert!(matches!(
            PointsAxis::of([10.0, 90.0].into_iter()),
            PointsAxis::Linear(_)
        ));
        assert!(matches!(
            PointsAxis::of([0.0, 90.0].into_iter()),
            PointsAxis::Linear(_)
        ));
        assert!(matches!(
            PointsAxis::of(std::iter::empty()),
            PointsAxis::Empty
        ));
    }

    #[test]
    fn medians() {
        assert_eq!(median(vec![3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(vec![4.0, 1.0, 2.0, 3.0]), 2.5);
        assert_eq!(median(Vec::new()), 0.0);
    }
}
