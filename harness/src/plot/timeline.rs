//! The timeline of one run: points drawn, frame times and image error against frame number.

use super::*;

/// The timeline figure of one run.
pub(super) struct Timeline<'a> {
    /// "method · scene · path".
    pub(super) title: String,
    /// The run's frames, sorted by frame number.
    pub(super) frames: &'a [FrameRecord],
}

/// A named line of a timeline panel, split into segments at missing values.
pub(super) struct Line {
    /// Legend name (the CSV column).
    pub(super) name: &'static str,
    /// Line colour.
    pub(super) colour: RGBColor,
    /// Runs of consecutive frames that have a value.
    pub(super) segments: Vec<Vec<(f64, f64)>>,
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
pub(super) fn line_panel<DB: DrawingBackend>(
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
        draw_legend(&mut chart, 14)?;
    }
    Ok(())
}
