//! A tune's figure: error against cost, one line per setting through its targets, the
//! Pareto front ringed and joined by a dashed black line. Plain data in, so that the plot
//! knows nothing of tunes.

use super::*;

/// Size in pixels of `tune.png` (and of `tune.svg` in user units).
pub const TUNE_SIZE: (u32, u32) = (1200, 800);

/// What a tune figure shows.
#[derive(Debug, Clone, Default)]
pub struct TuneFigure {
    /// Title.
    pub title: String,
    /// The x axis' description.
    pub x_desc: String,
    /// One line per setting: its label and `(cost, FLIP)` per target.
    pub lines: Vec<(String, Vec<(f64, f64)>)>,
    /// The points on the Pareto front.
    pub front: Vec<(f64, f64)>,
}

/// Draws `figure` into `dir/tune.png` and `dir/tune.svg`; returns their paths.
pub fn plot_tune(figure: &TuneFigure, dir: &Path) -> anyhow::Result<Vec<PathBuf>> {
    render_both(dir, "tune", TUNE_SIZE, figure)
}

impl Figure for TuneFigure {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> anyhow::Result<()>
    where
        DB::ErrorType: 'static,
    {
        root.fill(&WHITE)?;
        let root = root.titled(&self.title, (FONT, 26))?;
        let all = || self.lines.iter().flat_map(|(_, p)| p.iter().copied());
        let y = 0.0..nice_top(all().map(|p| p.1).fold(0.0, f64::max) * 1.05);
        let caption = "median FLIP mean vs cost; the Pareto front ringed";
        match PointsAxis::of(all().map(|p| p.0)) {
            PointsAxis::Log(x) => {
                self.panel(&root, x.log_scale(), y, &format!("{caption} (log x)"))
            }
            PointsAxis::Linear(x) => self.panel(&root, x, y, caption),
            PointsAxis::Empty => self.panel(&root, 0.0..1.0, 0.0..1.0, caption),
        }
    }
}

impl TuneFigure {
    fn panel<DB, X>(
        &self,
        area: &DrawingArea<DB, Shift>,
        x: X,
        y: Range<f64>,
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
            (&self.x_desc, "flip_mean (median)"),
        )?;
        for (i, (label, points)) in self.lines.iter().enumerate() {
            let colour = PALETTE[i % PALETTE.len()];
            let style = colour.stroke_width(2);
            let mut pts = points.clone();
            pts.sort_by(|a, b| a.0.total_cmp(&b.0));
            // Past the palette's ten colours, lines are dashed so that no two look alike.
            if i < PALETTE.len() {
                chart
                    .draw_series(LineSeries::new(pts.iter().copied(), style))?
                    .label(label.as_str())
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], style));
            } else {
                chart
                    .draw_series(DashedLineSeries::new(pts.iter().copied(), 10, 5, style))?
                    .label(format!("{label} (dashed)"))
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 10, y)], style));
            }
            chart.draw_series(pts.iter().map(|&p| Circle::new(p, 4, colour.filled())))?;
        }
        let mut front = self.front.clone();
        front.sort_by(|a, b| a.0.total_cmp(&b.0));
        if !front.is_empty() {
            chart
                .draw_series(DashedLineSeries::new(
                    front.iter().copied(),
                    6,
                    4,
                    BLACK.stroke_width(1),
                ))?
                .label("Pareto front")
                .legend(|(x, y)| {
                    PathElement::new(vec![(x, y), (x + 24, y)], BLACK.stroke_width(1))
                });
            chart.draw_series(
                front
                    .iter()
                    .map(|&p| Circle::new(p, 9, BLACK.stroke_width(2))),
            )?;
        }
        draw_legend(&mut chart, 15)?;
        Ok(())
    }
}
