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
    /// Text written beside points: each point's target (`budget 25000`), so that a line's
    /// points can be told apart.
    pub labels: Vec<((f64, f64), String)>,
}

/// The corner of the plot whose quarter holds the fewest of `points`, each given as
/// fractions `(0..1, 0..1)` of the axes (x left to right, y bottom to top): where the
/// legend covers no data, or the least. Ties go to upper right, upper left, lower left,
/// lower right, in that order.
pub(super) fn emptiest_corner(points: &[(f64, f64)]) -> SeriesLabelPosition {
    let corners = [
        (SeriesLabelPosition::UpperRight, true, true),
        (SeriesLabelPosition::UpperLeft, false, true),
        (SeriesLabelPosition::LowerLeft, false, false),
        (SeriesLabelPosition::LowerRight, true, false),
    ];
    let count = |right: bool, upper: bool| {
        points
            .iter()
            .filter(|(x, y)| (*x >= 0.5) == right && (*y >= 0.5) == upper)
            .count()
    };
    let mut best = (usize::MAX, SeriesLabelPosition::UpperRight);
    for (at, right, upper) in corners {
        let n = count(right, upper);
        if n < best.0 {
            best = (n, at);
        }
    }
    best.1
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
        // Each point as fractions of the axes, for the legend's corner.
        let fractions = |fx: &dyn Fn(f64) -> f64| -> Vec<(f64, f64)> {
            all().map(|(x, f)| (fx(x), f / y.end)).collect()
        };
        match PointsAxis::of(all().map(|p| p.0)) {
            PointsAxis::Log(x) => {
                let (lo, hi) = (x.start.ln(), x.end.ln());
                let at = emptiest_corner(&fractions(&|v| (v.ln() - lo) / (hi - lo)));
                self.panel(&root, x.log_scale(), y, &format!("{caption} (log x)"), at)
            }
            PointsAxis::Linear(x) => {
                let (lo, hi) = (x.start, x.end);
                let at = emptiest_corner(&fractions(&|v| (v - lo) / (hi - lo)));
                self.panel(&root, x, y, caption, at)
            }
            PointsAxis::Empty => self.panel(
                &root,
                0.0..1.0,
                0.0..1.0,
                caption,
                SeriesLabelPosition::UpperRight,
            ),
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
        legend: SeriesLabelPosition,
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
        let small = (FONT, 12).into_font().color(&BLACK.mix(0.6));
        chart.draw_series(
            self.labels
                .iter()
                .map(|(p, text)| Text::new(text.clone(), *p, small.clone()).into_dyn()),
        )?;
        draw_legend_at(&mut chart, 15, legend)?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The legend goes to the corner with the fewest points: a tune's curves fall from the
    /// upper left to the lower right, leaving the upper right empty; points there send it to
    /// the next empty corner.
    #[test]
    fn the_legend_takes_the_emptiest_corner() {
        let falling = [(0.0, 1.0), (0.3, 0.6), (0.6, 0.3), (1.0, 0.1)];
        assert_eq!(emptiest_corner(&falling), SeriesLabelPosition::UpperRight);
        let rising = [(0.1, 0.1), (0.4, 0.3), (0.7, 0.7), (0.9, 0.9)];
        assert_eq!(emptiest_corner(&rising), SeriesLabelPosition::UpperLeft);
        let mut busy: Vec<(f64, f64)> = vec![(0.9, 0.9), (0.1, 0.9), (0.1, 0.1), (0.1, 0.2)];
        busy.push((0.8, 0.9));
        assert_eq!(emptiest_corner(&busy), SeriesLabelPosition::LowerRight);
        assert_eq!(emptiest_corner(&[]), SeriesLabelPosition::UpperRight);
    }
}
