//! Plots of benchmark runs, drawn only from the runs' `frames.csv` files.
//!
//! Input contract: a run folder holds `frames.csv` whose header contains the columns of
//! [`FRAME_COLUMNS`] (any order, matched by name; extra columns, e.g. a method's own
//! counters, are ignored). Per row:
//! - `method`, `scene`, `path` are free text; `target` is `eps` or `budget`;
//! - `eps_px`, `budget` and the image-metric columns (`psnr_db`, `ssim`, `flip_mean`,
//!   `hole_ratio`, `extra_coverage`) may be empty (no reference for that run);
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
//!   legend entry per run; x is logarithmic when all x > 0 and max/min > 10. Right, the
//!   median `splats_per_s` of each run as a labelled bar. A run is labelled by its method,
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

/// The leading columns of every `frames.csv`, in the order runs write them.
pub const FRAME_COLUMNS: [&str; 21] = [
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
];

/// Size in pixels of `timeline.png` (and of `timeline.svg` in user units).
pub const TIMELINE_SIZE: (u32, u32) = (1280, 1024);

/// Size in pixels of `comparison.png` (and of `comparison.svg` in user units).
pub const COMPARISON_SIZE: (u32, u32) = (1600, 720);

/// The font family every plot uses; the bundled DejaVu Sans is registered under it.
const FONT: &str = "sans-serif";

/// DejaVu Sans, bundled so that plots need no system font.
const FONT_BYTES: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");

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
}

/// Reads `frames.csv` by header name (extra columns ignored). Errors name the file, and for
/// bad values the column and the row. A file without frames is an error.
pub fn read_frames(csv_path: &Path) -> anyhow::Result<Vec<FrameRecord>> {
    read_table(csv_path, &FRAME_COLUMNS, "frames", |row| row.parse())
}

/// Reads a CSV file whose header holds `columns` (any order, extra columns ignored), one
/// `parse` per record. Errors name the file; a file without rows is an error ("no `what` in
/// file").
fn read_table<T>(
    csv_path: &Path,
    columns: &[&str],
    what: &str,
    parse: impl Fn(&Row<'_>) -> anyhow::Result<T>,
) -> anyhow::Result<Vec<T>> {
    let file = csv_path.display();
    let mut reader = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .from_path(csv_path)
        .with_context(|| format!("cannot open {file}"))?;
    let headers = reader
        .headers()
        .with_context(|| format!("cannot read the header of {file}"))?;
    if headers.iter().all(str::is_empty) {
        bail!("no {what} in {file} (the file is empty)");
    }
    let index = columns
        .iter()
        .map(|&column| {
            headers
                .iter()
                .position(|h| h == column)
                .ok_or_else(|| anyhow!("{file}: missing column '{column}'"))
        })
        .collect::<anyhow::Result<Vec<usize>>>()?;
    let mut rows = Vec::new();
    for (n, record) in reader.records().enumerate() {
        let record = record.with_context(|| format!("cannot read {file}"))?;
        let row = Row {
            file: csv_path,
            row: n + 1,
            record: &record,
            columns,
            index: &index,
        };
        rows.push(parse(&row)?);
    }
    if rows.is_empty() {
        bail!("no {what} in {file}");
    }
    Ok(rows)
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
        })
        .collect();
    render_both(
        out_dir,
        "comparison",
        COMPARISON_SIZE,
        &Comparison { runs: series },
    )
}

/// The columns of `sweep.csv`, in file order: one row per target of a sweep, the medians
/// (and some maxima) over that target's run.
pub const SWEEP_COLUMNS: [&str; 17] = [
    "method",
    "params",
    "scene",
    "path",
    "target",
    "value",
    "frames",
    "points_drawn_median",
    "splats_per_s_median",
    "gpu_ms_median",
    "cpu_select_ms_median",
    "flip_mean_median",
    "flip_mean_max",
    "hole_ratio_median",
    "hole_ratio_max",
    "psnr_db_median",
    "rss_bytes_max",
];

/// Size in pixels of `sweep.png` and `sweep-comparison.png` (and of the SVGs in user units).
pub const SWEEP_SIZE: (u32, u32) = (1200, 800);

/// One row of `sweep.csv`: one target of a sweep, summarised over its run's frames.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepRow {
    /// Method name.
    pub method: String,
    /// The run's method parameters, `key=value` separated by spaces (empty: defaults).
    pub params: String,
    /// Scene name.
    pub scene: String,
    /// Camera path name.
    pub path: String,
    /// `eps` or `budget`.
    pub target: String,
    /// The tolerance in pixels or the budget in points.
    pub value: f64,
    /// Frames in the run.
    pub frames: u64,
    /// Median points drawn per frame.
    pub points_drawn_median: f64,
    /// Median splats per second.
    pub splats_per_s_median: f64,
    /// Median GPU ms (empty without timestamp queries).
    pub gpu_ms_median: Option<f64>,
    /// Median selection ms.
    pub cpu_select_ms_median: f64,
    /// Median of the frames' mean FLIP (empty without a reference).
    pub flip_mean_median: Option<f64>,
    /// Largest mean FLIP of a frame.
    pub flip_mean_max: Option<f64>,
    /// Median hole ratio.
    pub hole_ratio_median: Option<f64>,
    /// Largest hole ratio of a frame.
    pub hole_ratio_max: Option<f64>,
    /// Median PSNR, dB.
    pub psnr_db_median: Option<f64>,
    /// Largest resident set size after a frame, bytes.
    pub rss_bytes_max: u64,
}

impl SweepRow {
    /// The row of one run of a sweep: `frames` as [`read_frames`] returns them, `params` as
    /// recorded, `value` the target's value as given (the CSV's `eps_px` is an `f32` widened,
    /// so 0.1 would read back as 0.10000000149…). Medians are [`crate::results::median`], the
    /// same as `summary.json`'s; empty values are skipped, and a column empty in every frame
    /// stays empty.
    pub fn of_run(frames: &[FrameRecord], params: &str, value: f64) -> anyhow::Result<Self> {
        use crate::results::median;
        let Some(first) = frames.first() else {
            bail!("a run without frames has no sweep row");
        };
        let max = |f: fn(&FrameRecord) -> Option<f64>| frames.iter().filter_map(f).reduce(f64::max);
        let med = |f: fn(&FrameRecord) -> Option<f64>| median(frames.iter().filter_map(f));
        let need = |v: Option<f64>, what: &str| {
            v.ok_or_else(|| anyhow!("no finite {what} in the run's frames"))
        };
        Ok(Self {
            method: first.method.clone(),
            params: params.to_owned(),
            scene: first.scene.clone(),
            path: first.path.clone(),
            target: first.target.clone(),
            value,
            frames: frames.len() as u64,
            points_drawn_median: need(med(|f| Some(f.points_drawn as f64)), "points_drawn")?,
            splats_per_s_median: need(med(|f| Some(f.splats_per_s)), "splats_per_s")?,
            gpu_ms_median: med(|f| f.gpu_ms),
            cpu_select_ms_median: need(med(|f| Some(f.cpu_select_ms)), "cpu_select_ms")?,
            flip_mean_median: med(|f| f.flip_mean),
            flip_mean_max: max(|f| f.flip_mean),
            hole_ratio_median: med(|f| f.hole_ratio),
            hole_ratio_max: max(|f| f.hole_ratio),
            psnr_db_median: med(|f| f.psnr_db),
            rss_bytes_max: frames.iter().map(|f| f.rss_bytes).max().unwrap_or(0),
        })
    }

    /// The row as CSV fields, in [`SWEEP_COLUMNS`] order (`None` → empty field).
    fn fields(&self) -> Vec<String> {
        let opt = |v: Option<f64>| v.map(|v| v.to_string()).unwrap_or_default();
        vec![
            self.method.clone(),
            self.params.clone(),
            self.scene.clone(),
            self.path.clone(),
            self.target.clone(),
            self.value.to_string(),
            self.frames.to_string(),
            self.points_drawn_median.to_string(),
            self.splats_per_s_median.to_string(),
            opt(self.gpu_ms_median),
            self.cpu_select_ms_median.to_string(),
            opt(self.flip_mean_median),
            opt(self.flip_mean_max),
            opt(self.hole_ratio_median),
            opt(self.hole_ratio_max),
            opt(self.psnr_db_median),
            self.rss_bytes_max.to_string(),
        ]
    }

    /// The legend label of a sweep: its method and parameters.
    fn label(&self) -> String {
        if self.params.is_empty() {
            self.method.clone()
        } else {
            format!("{} {}", self.method, self.params)
        }
    }

    /// The target as a point's annotation: "25k" (a budget) or "2 px" (a tolerance).
    fn target_text(&self) -> String {
        match self.target.as_str() {
            "eps" => format!("{} px", self.value),
            _ => si(self.value),
        }
    }
}

/// Writes `sweep.csv` (header [`SWEEP_COLUMNS`], one line per row) atomically: a temporary
/// file renamed over `path`, so the file is either absent, the previous one, or complete.
pub fn write_sweep(path: &Path, rows: &[SweepRow]) -> anyhow::Result<()> {
    let mut w = csv::Writer::from_writer(Vec::new());
    w.write_record(SWEEP_COLUMNS)?;
    for row in rows {
        w.write_record(row.fields())?;
    }
    let bytes = w
        .into_inner()
        .map_err(|e| anyhow!("cannot format {}: {e}", path.display()))?;
    write_atomically(path, &bytes).with_context(|| format!("cannot write {}", path.display()))
}

/// Reads `sweep.csv` by header name (extra columns ignored). Errors name the file, and for
/// bad values the column and the row; a file without rows is an error.
pub fn read_sweep(csv_path: &Path) -> anyhow::Result<Vec<SweepRow>> {
    read_table(csv_path, &SWEEP_COLUMNS, "sweep rows", |row| {
        row.parse_sweep()
    })
}

/// Plots one sweep: reads `sweep_dir/sweep.csv`, writes `sweep.png` and `sweep.svg` into
/// `sweep_dir`, returns their paths.
pub fn plot_sweep(sweep_dir: &Path) -> anyhow::Result<Vec<PathBuf>> {
    let series = sweep_series(&[sweep_dir.to_path_buf()])?;
    let title = match series.first().and_then(|s| s.rows.first()) {
        Some(r) => format!("{} · {} · {}", r.label(), r.scene, r.path),
        None => String::from("sweep"),
    };
    render_both(
        sweep_dir,
        "sweep",
        SWEEP_SIZE,
        &SweepFigure { title, series },
    )
}

/// Overlays several sweeps (each a `splatbench sweep --out` folder with `sweep.csv`): writes
/// `sweep-comparison.png` and `sweep-comparison.svg` into `out_dir` (created if missing),
/// returns their paths.
pub fn plot_sweeps(sweep_dirs: &[PathBuf], out_dir: &Path) -> anyhow::Result<Vec<PathBuf>> {
    if sweep_dirs.is_empty() {
        bail!("no sweeps to compare");
    }
    let series = sweep_series(sweep_dirs)?;
    let rows = || series.iter().flat_map(|s| s.rows.iter());
    let scenes: std::collections::BTreeSet<_> = rows().map(|r| (&r.scene, &r.path)).collect();
    let title = match scenes.iter().next() {
        Some((scene, path)) if scenes.len() == 1 => {
            format!("image error vs points drawn · {scene} · {path}")
        }
        _ => String::from("image error vs points drawn"),
    };
    render_both(
        out_dir,
        "sweep-comparison",
        SWEEP_SIZE,
        &SweepFigure { title, series },
    )
}

/// Reads the sweeps in `dirs` and labels them (method and parameters, plus the folder name
/// where labels collide).
fn sweep_series(dirs: &[PathBuf]) -> anyhow::Result<Vec<SweepSeries>> {
    let sweeps = dirs
        .iter()
        .map(|dir| {
            let csv = dir.join("sweep.csv");
            if !csv.is_file() {
                bail!(
                    "{}: no sweep.csv (not a `splatbench sweep --out` folder, or its sweep did \
                     not finish)",
                    dir.display()
                );
            }
            read_sweep(&csv)
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    let mut labels: Vec<String> = sweeps
        .iter()
        .map(|rows| {
            rows.first()
                .map_or_else(|| String::from("?"), SweepRow::label)
        })
        .collect();
    disambiguate(&mut labels, dirs);
    Ok(sweeps
        .into_iter()
        .zip(labels)
        .enumerate()
        .map(|(i, (mut rows, label))| {
            rows.sort_by(|a, b| a.points_drawn_median.total_cmp(&b.points_drawn_median));
            SweepSeries {
                label,
                colour: PALETTE[i % PALETTE.len()],
                rows,
            }
        })
        .collect())
}

/// One sweep as its plot sees it.
struct SweepSeries {
    /// Legend label.
    label: String,
    /// Colour of its line and points.
    colour: RGBColor,
    /// Its rows, by points drawn.
    rows: Vec<SweepRow>,
}

impl SweepSeries {
    /// (median points drawn, median FLIP, target) of the rows that have a FLIP value.
    fn points(&self) -> impl Iterator<Item = (f64, f64, String)> + '_ {
        self.rows
            .iter()
            .filter_map(|r| Some((r.points_drawn_median, r.flip_mean_median?, r.target_text())))
    }
}

/// The figure of one or more sweeps: median FLIP against median points drawn, one line per
/// sweep, each point annotated with its target.
struct SweepFigure {
    /// Figure title.
    title: String,
    /// One entry per sweep.
    series: Vec<SweepSeries>,
}

impl Figure for SweepFigure {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> anyhow::Result<()>
    where
        DB::ErrorType: 'static,
    {
        root.fill(&WHITE)?;
        let root = root.titled(&self.title, (FONT, 26))?;
        let points: Vec<(f64, f64)> = self
            .series
            .iter()
            .flat_map(|s| s.points().map(|(x, y, _)| (x, y)))
            .collect();
        let y = 0.0..nice_top(points.iter().map(|p| p.1).fold(0.0, f64::max) * 1.05);
        let caption = "median FLIP mean vs median points drawn per frame";
        match PointsAxis::of(points.iter().map(|p| p.0)) {
            PointsAxis::Log(x) => {
                let caption = format!("{caption} (log x)");
                sweep_panel(&root, x.log_scale(), y, &self.series, &caption)
            }
            PointsAxis::Linear(x) => sweep_panel(&root, x, y, &self.series, caption),
            PointsAxis::Empty => {
                let caption = format!("{caption} (no reference: not recorded)");
                sweep_panel(&root, 0.0..1.0, 0.0..1.0, &self.series, &caption)
            }
        }
    }
}

/// A chart of image error against points drawn on `area` (x axis `x`, either linear or log),
/// its mesh, SI labels and axis descriptions `desc = (x, y)` drawn: what the scatter and the
/// sweep panels share.
fn flip_chart<'a, DB, X>(
    area: &'a DrawingArea<DB, Shift>,
    (x, y): (X, Range<f64>),
    caption: &str,
    margin: u32,
    desc: (&str, &str),
) -> anyhow::Result<ChartContext<'a, DB, Cartesian2d<X::CoordDescType, RangedCoordf64>>>
where
    DB: DrawingBackend,
    DB::ErrorType: 'static,
    X: AsRangedCoord<Value = f64>,
    X::CoordDescType: ValueFormatter<f64>,
{
    let mut chart = ChartBuilder::on(area)
        .caption(caption, (FONT, 20))
        .margin(margin)
        .x_label_area_size(50)
        .y_label_area_size(80)
        .build_cartesian_2d(x, y)?;
    chart
        .configure_mesh()
        .x_desc(desc.0)
        .y_desc(desc.1)
        .x_label_formatter(&|v| si(*v))
        .y_label_formatter(&|v| si(*v))
        .label_style((FONT, 14))
        .axis_desc_style((FONT, 16))
        .light_line_style(WHITE)
        .draw()?;
    Ok(chart)
}

/// The sweeps' lines on x axis `x`, with a legend.
fn sweep_panel<DB, X>(
    area: &DrawingArea<DB, Shift>,
    x: X,
    y: Range<f64>,
    series: &[SweepSeries],
    caption: &str,
) -> anyhow::Result<()>
where
    DB: DrawingBackend,
    DB::ErrorType: 'static,
    X: AsRangedCoord<Value = f64>,
    X::CoordDescType: ValueFormatter<f64>,
{
    let mut chart = flip_chart(
        area,
        (x, y),
        caption,
        16,
        ("points drawn per frame (median)", "flip_mean (median)"),
    )?;
    let note = TextStyle::from((FONT, 13).into_font()).pos(Pos::new(HPos::Left, VPos::Bottom));
    for s in series {
        let style = s.colour.stroke_width(2);
        let name = if s.points().next().is_none() {
            format!("{} (no data)", s.label)
        } else {
            s.label.clone()
        };
        chart
            .draw_series(LineSeries::new(s.points().map(|(x, y, _)| (x, y)), style))?
            .label(name)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], style));
        chart.draw_series(
            s.points()
                .map(|(x, y, _)| Circle::new((x, y), 4, s.colour.filled())),
        )?;
        chart.draw_series(s.points().map(|(x, y, text)| {
            EmptyElement::at((x, y)) + Text::new(text, (6, -6), note.clone().color(&s.colour))
        }))?;
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK.mix(0.4))
        .label_font((FONT, 15))
        .draw()?;
    Ok(())
}

/// The x axis of an error-against-points plot.
enum PointsAxis {
    /// Every x > 0 and they span more than a factor 10: logarithmic over this range.
    Log(Range<f64>),
    /// Linear over this range.
    Linear(Range<f64>),
    /// No points.
    Empty,
}

impl PointsAxis {
    /// The axis that shows `xs` (padded a little on both sides).
    fn of(xs: impl Iterator<Item = f64>) -> Self {
        let (lo, hi) = xs.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| {
            (lo.min(x), hi.max(x))
        });
        if lo > hi {
            Self::Empty
        } else if lo > 0.0 && hi / lo > 10.0 {
            Self::Log(lo / 1.25..hi * 1.25)
        } else {
            let span = (hi - lo).max(hi.abs() * 0.1).max(1.0);
            Self::Linear((lo - 0.05 * span).max(0.0)..hi + 0.05 * span)
        }
    }
}

/// One run as the comparison plot sees it.
struct RunSeries {
    /// Legend label.
    label: String,
    /// Colour of its points and bar.
    colour: RGBColor,
    /// (points_drawn, flip_mean) per frame that has a FLIP value.
    flip_vs_points: Vec<(f64, f64)>,
    /// Median splats per second over all frames.
    median_splats_per_s: f64,
}

/// One CSV record being parsed, with what error messages need.
struct Row<'a> {
    /// The CSV file.
    file: &'a Path,
    /// 1-based data row.
    row: usize,
    /// The record.
    record: &'a csv::StringRecord,
    /// The columns read (e.g. [`FRAME_COLUMNS`]).
    columns: &'a [&'a str],
    /// Position in the record of each of `columns`.
    index: &'a [usize],
}

impl Row<'_> {
    /// The trimmed text of column `name` (one of `columns`).
    fn text(&self, name: &str) -> &str {
        self.columns
            .iter()
            .position(|&c| c == name)
            .and_then(|c| self.record.get(self.index[c]))
            .unwrap_or("")
    }

    /// An error about column `name` of this row.
    fn error(&self, name: &str, what: &str) -> anyhow::Error {
        let line = self
            .record
            .position()
            .map_or(String::new(), |p| format!(" (line {})", p.line()));
        anyhow!(
            "{}: row {}{line}, column '{name}': {what}",
            self.file.display(),
            self.row,
        )
    }

    /// Column `name` as text, which must not be empty.
    fn string(&self, name: &str) -> anyhow::Result<String> {
        match self.text(name) {
            "" => Err(self.error(name, "empty")),
            s => Ok(s.to_owned()),
        }
    }

    /// Column `name` as a finite number, or `None` when empty.
    fn opt_f64(&self, name: &str) -> anyhow::Result<Option<f64>> {
        let s = self.text(name);
        if s.is_empty() {
            return Ok(None);
        }
        match s.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(Some(v)),
            _ => Err(self.error(name, &format!("\"{s}\" is not a finite number"))),
        }
    }

    /// Column `name` as an unsigned integer, or `None` when empty.
    fn opt_u64(&self, name: &str) -> anyhow::Result<Option<u64>> {
        let s = self.text(name);
        if s.is_empty() {
            return Ok(None);
        }
        s.parse::<u64>()
            .map(Some)
            .map_err(|_| self.error(name, &format!("\"{s}\" is not an unsigned integer")))
    }

    /// Column `name` as a finite number; empty is an error.
    fn f64(&self, name: &str) -> anyhow::Result<f64> {
        self.opt_f64(name)?
            .ok_or_else(|| self.error(name, "empty, a number is required"))
    }

    /// Column `name` as an unsigned integer; empty is an error.
    fn u64(&self, name: &str) -> anyhow::Result<u64> {
        self.opt_u64(name)?
            .ok_or_else(|| self.error(name, "empty, an integer is required"))
    }

    /// Column `target`: `eps` or `budget`.
    fn target(&self) -> anyhow::Result<String> {
        let target = self.string("target")?;
        if target != "eps" && target != "budget" {
            return Err(self.error(
                "target",
                &format!("\"{target}\" is neither \"eps\" nor \"budget\""),
            ));
        }
        Ok(target)
    }

    /// The whole record, as a frame of `frames.csv`.
    fn parse(&self) -> anyhow::Result<FrameRecord> {
        let target = self.target()?;
        Ok(FrameRecord {
            frame: self.u64("frame")?,
            method: self.string("method")?,
            scene: self.string("scene")?,
            path: self.string("path")?,
            target,
            eps_px: self.opt_f64("eps_px")?,
            budget: self.opt_u64("budget")?,
            points_drawn: self.u64("points_drawn")?,
            chunks_drawn: self.u64("chunks_drawn")?,
            gpu_ms: self.opt_f64("gpu_ms")?,
            wall_ms: self.f64("wall_ms")?,
            cpu_select_ms: self.f64("cpu_select_ms")?,
            upload_bytes: self.u64("upload_bytes")?,
            splats_per_s: self.f64("splats_per_s")?,
            rss_bytes: self.u64("rss_bytes")?,
            gpu_cache_bytes: self.u64("gpu_cache_bytes")?,
            psnr_db: self.opt_f64("psnr_db")?,
            ssim: self.opt_f64("ssim")?,
            flip_mean: self.opt_f64("flip_mean")?,
            hole_ratio: self.opt_f64("hole_ratio")?,
            extra_coverage: self.opt_f64("extra_coverage")?,
        })
    }

    /// The whole record, as a row of `sweep.csv`.
    fn parse_sweep(&self) -> anyhow::Result<SweepRow> {
        Ok(SweepRow {
            method: self.string("method")?,
            params: self.text("params").to_owned(),
            scene: self.string("scene")?,
            path: self.string("path")?,
            target: self.target()?,
            value: self.f64("value")?,
            frames: self.u64("frames")?,
            points_drawn_median: self.f64("points_drawn_median")?,
            splats_per_s_median: self.f64("splats_per_s_median")?,
            gpu_ms_median: self.opt_f64("gpu_ms_median")?,
            cpu_select_ms_median: self.f64("cpu_select_ms_median")?,
            flip_mean_median: self.opt_f64("flip_mean_median")?,
            flip_mean_max: self.opt_f64("flip_mean_max")?,
            hole_ratio_median: self.opt_f64("hole_ratio_median")?,
            hole_ratio_max: self.opt_f64("hole_ratio_max")?,
            psnr_db_median: self.opt_f64("psnr_db_median")?,
            rss_bytes_max: self.u64("rss_bytes_max")?,
        })
    }
}

/// Registers the bundled font as "sans-serif", once per process.
fn ensure_font() -> anyhow::Result<()> {
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

/// The timeline figure of one run.
struct Timeline<'a> {
    /// "method · scene · path".
    title: String,
    /// The run's frames, sorted by frame number.
    frames: &'a [FrameRecord],
}

/// A named line of a timeline panel, split into segments at missing values.
struct Line {
    /// Legend name (the CSV column).
    name: &'static str,
    /// Line colour.
    colour: RGBColor,
    /// Runs of consecutive frames that have a value.
    segments: Vec<Vec<(f64, f64)>>,
}

impl Line {
    /// The line of `value` over `frames`, broken where `value` is `None`.
    fn new(
        name: &'static str,
        colour: RGBColor,
        frames: &[FrameRecord],
        value: impl Fn(&FrameRecord) -> Option<f64>,
    ) -> Self {
        let mut segments: Vec<Vec<(f64, f64)>> = Vec::new();
        let mut open = false;
        for f in frames {
            match value(f) {
                Some(v) => {
                    if !open {
                        segments.push(Vec::new());
                        open = true;
                    }
                    if let Some(seg) = segments.last_mut() {
                        seg.push((f.frame as f64, v));
                    }
                }
                None => open = false,
            }
        }
        Self {
            name,
            colour,
            segments,
        }
    }

    /// All points of all segments.
    fn points(&self) -> impl Iterator<Item = (f64, f64)> + '_ {
        self.segments.iter().flatten().copied()
    }

    /// Largest value, or `None` without data.
    fn max(&self) -> Option<f64> {
        self.points().map(|p| p.1).reduce(f64::max)
    }
}

impl Figure for Timeline<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> anyhow::Result<()>
    where
        DB::ErrorType: 'static,
    {
        root.fill(&WHITE)?;
        let root = root.titled(&self.title, (FONT, 28))?;
        let panels = root.split_evenly((3, 1));
        let frames = self.frames;
        let (first, last) = match (frames.first(), frames.last()) {
            (Some(first), Some(last)) => (first.frame as f64, last.frame as f64),
            _ => bail!("no frames to plot"),
        };
        let x = padded(first, last);

        let points = Line::new("points_drawn", PALETTE[0], frames, |f| {
            Some(f.points_drawn as f64)
        });
        let top = nice_top(points.max().unwrap_or(0.0));
        line_panel(
            &panels[0],
            "points drawn",
            "points",
            x.clone(),
            0.0..top,
            &[points],
            None,
        )?;

        let times = [
            Line::new("gpu_ms", PALETTE[1], frames, |f| f.gpu_ms),
            Line::new("wall_ms", PALETTE[0], frames, |f| Some(f.wall_ms)),
        ];
        // Headroom above the lines for the legend.
        let top = 1.2 * nice_top(times.iter().filter_map(Line::max).fold(0.0, f64::max));
        line_panel(
            &panels[1],
            "frame time",
            "ms",
            x.clone(),
            0.0..top,
            &times,
            None,
        )?;

        let errors = [
            Line::new("flip_mean", PALETTE[2], frames, |f| f.flip_mean),
            Line::new("hole_ratio", PALETTE[6], frames, |f| f.hole_ratio),
        ];
        let caption = if errors.iter().all(|l| l.segments.is_empty()) {
            "image error (no reference: not recorded)"
        } else {
            "image error vs reference"
        };
        line_panel(
            &panels[2],
            caption,
            "error (0..1)",
            x,
            0.0..1.0,
            &errors,
            Some("frame"),
        )?;
        Ok(())
    }
}

/// One panel of lines against frame number, with a legend when there is more than one line.
fn line_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    caption: &str,
    y_desc: &str,
    x: Range<f64>,
    y: Range<f64>,
    lines: &[Line],
    x_desc: Option<&str>,
) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    let mut chart = ChartBuilder::on(area)
        .caption(caption, (FONT, 20))
        .margin(10)
        .x_label_area_size(if x_desc.is_some() { 50 } else { 30 })
        .y_label_area_size(80)
        .build_cartesian_2d(x, y)?;
    let mut mesh = chart.configure_mesh();
    mesh.y_desc(y_desc)
        .x_label_formatter(&|v| {
            if v.abs() < 0.5 {
                String::from("0")
            } else {
                format!("{v:.0}")
            }
        })
        .y_label_formatter(&|v| si(*v))
        .label_style((FONT, 14))
        .axis_desc_style((FONT, 16))
        .light_line_style(WHITE);
    if let Some(desc) = x_desc {
        mesh.x_desc(desc);
    }
    mesh.draw()?;
    for line in lines {
        let style = line.colour.stroke_width(2);
        let name = if line.segments.is_empty() {
            format!("{} (no data)", line.name)
        } else {
            line.name.to_owned()
        };
        let mut legend = Some(name);
        for segment in &line.segments {
            let annotation = chart.draw_series(LineSeries::new(segment.iter().copied(), style))?;
            if let Some(name) = legend.take() {
                annotation
                    .label(name)
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], style));
            }
        }
        if let Some(name) = legend.take() {
            chart
                .draw_series(LineSeries::new(std::iter::empty(), style))?
                .label(name)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], style));
        }
        if line.points().count() <= 200 {
            chart.draw_series(
                line.points()
                    .map(|p| Circle::new(p, 3, line.colour.filled())),
            )?;
        }
    }
    if lines.len() > 1 {
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK.mix(0.4))
            .label_font((FONT, 14))
            .draw()?;
    }
    Ok(())
}

/// The comparison figure of several runs.
struct Comparison {
    /// One entry per run, in the order given.
    runs: Vec<RunSeries>,
}

impl Figure for Comparison {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> anyhow::Result<()>
    where
        DB::ErrorType: 'static,
    {
        root.fill(&WHITE)?;
        let root = root.titled("image error and throughput per run", (FONT, 28))?;
        let (width, _) = root.dim_in_pixel();
        let (left, right) = root.split_horizontally(width * 62 / 100);

        let points: Vec<(f64, f64)> = self
            .runs
            .iter()
            .flat_map(|r| r.flip_vs_points.iter().copied())
            .collect();
        let y_top = nice_top(points.iter().map(|p| p.1).fold(0.0, f64::max) * 1.05);
        match PointsAxis::of(points.iter().map(|p| p.0)) {
            PointsAxis::Log(x) => {
                let caption = "FLIP mean vs points drawn (log x)";
                scatter_panel(&left, x.log_scale(), 0.0..y_top, &self.runs, caption)?;
            }
            PointsAxis::Linear(x) => {
                let caption = "FLIP mean vs points drawn";
                scatter_panel(&left, x, 0.0..y_top, &self.runs, caption)?;
            }
            PointsAxis::Empty => {
                let caption = "FLIP mean vs points drawn (no reference: not recorded)";
                scatter_panel(&left, 0.0..1.0, 0.0..1.0, &self.runs, caption)?;
            }
        }
        throughput_panel(&right, &self.runs)
    }
}

/// Scatter of per-frame FLIP against points drawn, one colour per run, on x axis `x`.
fn scatter_panel<DB, X>(
    area: &DrawingArea<DB, Shift>,
    x: X,
    y: Range<f64>,
    runs: &[RunSeries],
    caption: &str,
) -> anyhow::Result<()>
where
    DB: DrawingBackend,
    DB::ErrorType: 'static,
    X: AsRangedCoord<Value = f64>,
    X::CoordDescType: ValueFormatter<f64>,
{
    let mut chart = flip_chart(area, (x, y), caption, 12, ("points drawn", "flip_mean"))?;
    for run in runs {
        let colour = run.colour;
        chart
            .draw_series(
                run.flip_vs_points
                    .iter()
                    .map(|&p| Circle::new(p, 4, colour.mix(0.75).filled())),
            )?
            .label(run.label.as_str())
            .legend(move |(x, y)| Circle::new((x + 10, y), 5, colour.filled()));
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK.mix(0.4))
        .label_font((FONT, 15))
        .draw()?;
    Ok(())
}

/// One bar per run: its median splats per second, value written above the bar.
fn throughput_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    runs: &[RunSeries],
) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    let top = nice_top(
        runs.iter()
            .map(|r| r.median_splats_per_s)
            .fold(0.0, f64::max)
            * 1.12,
    );
    let labels: Vec<&str> = runs.iter().map(|r| r.label.as_str()).collect();
    let mut chart = ChartBuilder::on(area)
        .caption("median splats/s", (FONT, 20))
        .margin(12)
        .x_label_area_size(50)
        .y_label_area_size(80)
        // Integer ranges are inclusive once segmented: 0..n-1 gives exactly n bars.
        .build_cartesian_2d((0..runs.len().saturating_sub(1)).into_segmented(), 0.0..top)?;
    chart
        .configure_mesh()
        .disable_x_mesh()
        .x_labels(runs.len())
        .x_label_formatter(&|v| match v {
            SegmentValue::CenterOf(i) => labels.get(*i).map_or(String::new(), |l| (*l).to_owned()),
            _ => String::new(),
        })
        .y_label_formatter(&|v| si(*v))
        .y_desc("splats/s")
        .label_style((FONT, 14))
        .axis_desc_style((FONT, 16))
        .light_line_style(WHITE)
        .draw()?;
    // Bars take 60 % of their slot (the y label area and margins take about 110 px).
    let slot_px = area.dim_in_pixel().0.saturating_sub(110) / runs.len().max(1) as u32;
    let side_margin = (slot_px / 5).max(4);
    chart.draw_series(runs.iter().enumerate().map(|(i, run)| {
        let corners = [
            (SegmentValue::Exact(i), 0.0),
            (SegmentValue::Exact(i + 1), run.median_splats_per_s),
        ];
        let mut bar = Rectangle::new(corners, run.colour.filled());
        bar.set_margin(0, 0, side_margin, side_margin);
        bar
    }))?;
    let value_style =
        TextStyle::from((FONT, 15).into_font()).pos(Pos::new(HPos::Center, VPos::Bottom));
    chart.draw_series(runs.iter().enumerate().map(|(i, run)| {
        let at = (SegmentValue::CenterOf(i), run.median_splats_per_s);
        Text::new(si(run.median_splats_per_s), at, value_style.clone())
    }))?;
    Ok(())
}

/// Legend labels: the method, plus the target when the runs' targets differ, plus the run
/// folder's name when labels still collide.
fn run_labels(run_dirs: &[PathBuf], runs: &[Vec<FrameRecord>]) -> Vec<String> {
    let first = |frames: &Vec<FrameRecord>| frames.first().cloned();
    let targets_differ = runs
        .iter()
        .filter_map(|r| first(r).map(|f| f.target))
        .collect::<std::collections::BTreeSet<_>>()
        .len()
        > 1;
    let mut labels: Vec<String> = runs
        .iter()
        .map(|frames| match frames.first() {
            Some(f) if targets_differ => format!("{} · {}", f.method, f.target),
            Some(f) => f.method.clone(),
            None => String::from("?"),
        })
        .collect();
    disambiguate(&mut labels, run_dirs);
    labels
}

/// Appends the folder's name to every label that more than one folder has.
fn disambiguate(labels: &mut [String], dirs: &[PathBuf]) {
    let mut counts: HashMap<String, usize> = HashMap::new();
    for label in labels.iter() {
        *counts.entry(label.clone()).or_default() += 1;
    }
    for (label, dir) in labels.iter_mut().zip(dirs) {
        if counts.get(label).copied().unwrap_or(0) > 1 {
            let name = dir.file_name().map_or_else(
                || dir.display().to_string(),
                |n| n.to_string_lossy().into_owned(),
            );
            *label = format!("{label} ({name})");
        }
    }
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
        fields.extend(["x"; 10]);
        let bad = format!("{}\n{}\n", SWEEP_COLUMNS.join(","), fields.join(","));
        std::fs::write(&path, bad).unwrap();
        let e = format!("{:#}", read_sweep(&path).unwrap_err());
        assert!(
            e.contains("row 1") && e.contains("points_drawn_median"),
            "{e}"
        );
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
