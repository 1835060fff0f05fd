//! Sweeps: `sweep.csv` (one row per target) and the FLIP-against-points figure of one sweep
//! or several overlaid.

use super::*;

/// The columns of `sweep.csv`, in file order: one row per target of a sweep, the medians
/// (and some maxima) over that target's run.
pub const SWEEP_COLUMNS: [&str; 22] = [
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
    "popping_flip_median",
    "popping_warped_l1_median",
    "popping_warped_l1_p95",
    "popping_warped_l7_median",
    "popping_warped_l7_p95",
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
    /// Median popping FLIP (empty without a reference or with one frame; see
    /// [`crate::metrics::PathMetrics`]).
    pub popping_flip_median: Option<f64>,
    /// Median warped popping at lag 1 ([`crate::metrics::popping`]; empty without a
    /// reference, with one frame, or in files older than the column).
    pub popping_warped_l1_median: Option<f64>,
    /// Its 95th percentile over the frames.
    pub popping_warped_l1_p95: Option<f64>,
    /// Median warped popping at lag 7 (empty with fewer than 8 frames, and as above).
    pub popping_warped_l7_median: Option<f64>,
    /// Its 95th percentile over the frames.
    pub popping_warped_l7_p95: Option<f64>,
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
        let p95 = |f: fn(&FrameRecord) -> Option<f64>| {
            crate::results::quantile(frames.iter().filter_map(f), 0.95)
        };
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
            popping_flip_median: med(|f| f.popping_flip),
            popping_warped_l1_median: med(|f| f.popping_warped_l1),
            popping_warped_l1_p95: p95(|f| f.popping_warped_l1),
            popping_warped_l7_median: med(|f| f.popping_warped_l7),
            popping_warped_l7_p95: p95(|f| f.popping_warped_l7),
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
            opt(self.popping_flip_median),
            opt(self.popping_warped_l1_median),
            opt(self.popping_warped_l1_p95),
            opt(self.popping_warped_l7_median),
            opt(self.popping_warped_l7_p95),
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
pub(super) fn sweep_series(dirs: &[PathBuf]) -> anyhow::Result<Vec<SweepSeries>> {
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
pub(super) struct SweepSeries {
    /// Legend label.
    pub(super) label: String,
    /// Colour of its line and points.
    pub(super) colour: RGBColor,
    /// Its rows, by points drawn.
    pub(super) rows: Vec<SweepRow>,
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
pub(super) struct SweepFigure {
    /// Figure title.
    pub(super) title: String,
    /// One entry per sweep.
    pub(super) series: Vec<SweepSeries>,
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
pub(super) fn flip_chart<'a, DB, X>(
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
pub(super) fn sweep_panel<DB, X>(
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
    draw_legend(&mut chart, 15)?;
    Ok(())
}

/// The x axis of an error-against-points plot.
pub(super) enum PointsAxis {
    /// Every x > 0 and they span more than a factor 10: logarithmic over this range.
    Log(Range<f64>),
    /// Linear over this range.
    Linear(Range<f64>),
    /// No points.
    Empty,
}

impl PointsAxis {
    /// The axis that shows `xs` (padded a little on both sides).
    pub(super) fn of(xs: impl Iterator<Item = f64>) -> Self {
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
