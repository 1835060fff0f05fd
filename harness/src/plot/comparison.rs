//! The comparison of several runs: FLIP against points drawn, median splats per second and
//! median popping, as drawn and with the motion removed.

use super::*;

/// One run as the comparison plot sees it.
pub(super) struct RunSeries {
    /// Legend label.
    pub(super) label: String,
    /// Colour of its points and bar.
    pub(super) colour: RGBColor,
    /// (points_drawn, flip_mean) per frame that has a FLIP value.
    pub(super) flip_vs_points: Vec<(f64, f64)>,
    /// Median splats per second over all frames.
    pub(super) median_splats_per_s: f64,
    /// Median popping FLIP over the frames that have one (`None`: no reference, one frame,
    /// or a `frames.csv` older than the column).
    pub(super) median_popping_flip: Option<f64>,
    /// Median warped popping at lag 1 ([`crate::metrics::popping`]; `None` as above).
    pub(super) median_popping_warped_l1: Option<f64>,
}

/// The comparison figure of several runs.
pub(super) struct Comparison {
    /// One entry per run, in the order given.
    pub(super) runs: Vec<RunSeries>,
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
        let (_, height) = right.dim_in_pixel();
        let (top, bottom) = right.split_vertically(height / 2);
        let splats: Vec<Option<f64>> = self
            .runs
            .iter()
            .map(|r| Some(r.median_splats_per_s))
            .collect();
        bar_panel(&top, &self.runs, &splats, "median splats/s", "splats/s", si)?;
        // Popping twice: frame to frame as drawn (dominated by the motion), and with the
        // motion removed by exact reprojection (lag 1); each minus the reference's.
        let (width, _) = bottom.dim_in_pixel();
        let (plain, warped) = bottom.split_horizontally(width / 2);
        let panels = [
            (
                &plain,
                self.runs
                    .iter()
                    .map(|r| r.median_popping_flip)
                    .collect::<Vec<_>>(),
                "median popping FLIP (unwarped)",
                "popping_flip",
            ),
            (
                &warped,
                self.runs
                    .iter()
                    .map(|r| r.median_popping_warped_l1)
                    .collect(),
                "median popping, motion removed (lag 1)",
                "popping_warped_l1",
            ),
        ];
        for (area, values, caption, desc) in panels {
            let caption = if values.iter().all(Option::is_none) {
                format!("{caption}: not recorded")
            } else {
                caption.to_string()
            };
            bar_panel(area, &self.runs, &values, &caption, desc, |v| {
                format!("{v:.4}")
            })?;
        }
        Ok(())
    }
}

/// Scatter of per-frame FLIP against points drawn, one colour per run, on x axis `x`.
pub(super) fn scatter_panel<DB, X>(
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
    draw_legend(&mut chart, 15)?;
    Ok(())
}

/// One bar per run of `values` (in run order; `None` draws no bar), from 0 (the axis spans
/// negative values too when one is), each value written at its bar's end by `label`.
pub(super) fn bar_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    runs: &[RunSeries],
    values: &[Option<f64>],
    caption: &str,
    y_desc: &str,
    label: fn(f64) -> String,
) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    let present = || values.iter().flatten().copied();
    let top = nice_top(present().fold(0.0, f64::max) * 1.12);
    let low = present().fold(0.0, f64::min);
    let bottom = if low < 0.0 {
        -nice_top(-low * 1.12)
    } else {
        0.0
    };
    // Keep a visible range when every value is 0.
    let top = if top <= bottom { bottom + 1.0 } else { top };
    let labels: Vec<&str> = runs.iter().map(|r| r.label.as_str()).collect();
    let mut chart = ChartBuilder::on(area)
        .caption(caption, (FONT, 20))
        .margin(12)
        .x_label_area_size(50)
        .y_label_area_size(80)
        // Integer ranges are inclusive once segmented: 0..n-1 gives exactly n bars.
        .build_cartesian_2d(
            (0..runs.len().saturating_sub(1)).into_segmented(),
            bottom..top,
        )?;
    chart
        .configure_mesh()
        .disable_x_mesh()
        .x_labels(runs.len())
        .x_label_formatter(&|v| match v {
            SegmentValue::CenterOf(i) => labels.get(*i).map_or(String::new(), |l| (*l).to_owned()),
            _ => String::new(),
        })
        .y_label_formatter(&|v| label(*v))
        .y_desc(y_desc)
        .label_style((FONT, 14))
        .axis_desc_style((FONT, 16))
        .light_line_style(WHITE)
        .draw()?;
    // Bars take 60 % of their slot (the y label area and margins take about 110 px).
    let slot_px = area.dim_in_pixel().0.saturating_sub(110) / runs.len().max(1) as u32;
    let side_margin = (slot_px / 5).max(4);
    let bars = || {
        runs.iter()
            .zip(values)
            .enumerate()
            .filter_map(|(i, (run, v))| Some((i, run, (*v)?)))
    };
    chart.draw_series(bars().map(|(i, run, v)| {
        let corners = [
            (SegmentValue::Exact(i), 0.0),
            (SegmentValue::Exact(i + 1), v),
        ];
        let mut bar = Rectangle::new(corners, run.colour.filled());
        bar.set_margin(0, 0, side_margin, side_margin);
        bar
    }))?;
    chart.draw_series(bars().map(|(i, _, v)| {
        let v_pos = if v < 0.0 { VPos::Top } else { VPos::Bottom };
        let style = TextStyle::from((FONT, 15).into_font()).pos(Pos::new(HPos::Center, v_pos));
        Text::new(label(v), (SegmentValue::CenterOf(i), v), style)
    }))?;
    Ok(())
}

/// Legend labels: the method, plus the target when the runs' targets differ, plus the run
/// folder's name when labels still collide.
pub(super) fn run_labels(run_dirs: &[PathBuf], runs: &[Vec<FrameRecord>]) -> Vec<String> {
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
pub(super) fn disambiguate(labels: &mut [String], dirs: &[PathBuf]) {
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
