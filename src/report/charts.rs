//! SVG charts drawn with plotters: line charts with a legend (the in-plane BRDF plot, curves of
//! error against a knob) and scatter charts with the Pareto front marked (speed against accuracy).
//!
//! Each function takes data and a [`ChartSpec`] and returns the SVG document as a string: pure,
//! no files (the report writer or the CLI decides where it goes). Text is SVG `<text>` (no font
//! files are read). Points that cannot be drawn (not finite, or not positive on a log axis) are
//! left out, and a line series is broken there rather than drawn across the gap.

use plotters::coord::Shift;
use plotters::coord::ranged1d::{AsRangedCoord, ValueFormatter};
use plotters::prelude::*;

/// A colour, 8-bit sRGB.
pub type Rgb = [u8; 3];

/// Tableau 10: distinct colours for up to ten series, then repeated.
pub const PALETTE: [Rgb; 10] = [
    [31, 119, 180],
    [255, 127, 14],
    [44, 160, 44],
    [214, 39, 40],
    [148, 103, 189],
    [140, 86, 75],
    [227, 119, 194],
    [127, 127, 127],
    [188, 189, 34],
    [23, 190, 207],
];

/// What plotters reports when drawing into the SVG string fails.
pub type DrawError = plotters::drawing::DrawingAreaErrorKind<std::io::Error>;

#[derive(Debug, thiserror::Error)]
pub enum ChartError {
    #[error("drawing the chart {title:?}: {source}")]
    Draw {
        title: String,
        #[source]
        source: DrawError,
    },
}

/// One line of a line chart.
#[derive(Clone, Debug, PartialEq)]
pub struct Series {
    pub label: String,
    pub points: Vec<(f64, f64)>,
    /// `None`: the palette colour of the series' position.
    pub color: Option<Rgb>,
    pub dashed: bool,
}

impl Series {
    pub fn new(label: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        Self {
            label: label.into(),
            points,
            color: None,
            dashed: false,
        }
    }

    pub fn with_color(mut self, color: Rgb) -> Self {
        self.color = Some(color);
        self
    }

    pub fn dashed(mut self) -> Self {
        self.dashed = true;
        self
    }
}

/// Title, axis labels, scales and size of a chart.
#[derive(Clone, Debug, PartialEq)]
pub struct ChartSpec {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub log_x: bool,
    pub log_y: bool,
    /// Pixels (the SVG's width and height attributes).
    pub width: u32,
    pub height: u32,
}

impl ChartSpec {
    /// Linear axes, 640 x 420.
    pub fn new(
        title: impl Into<String>,
        x_label: impl Into<String>,
        y_label: impl Into<String>,
    ) -> Self {
        Self {
            title: title.into(),
            x_label: x_label.into(),
            y_label: y_label.into(),
            log_x: false,
            log_y: false,
            width: 640,
            height: 420,
        }
    }

    pub fn log_x(mut self, on: bool) -> Self {
        self.log_x = on;
        self
    }

    pub fn log_y(mut self, on: bool) -> Self {
        self.log_y = on;
        self
    }

    pub fn size(mut self, width: u32, height: u32) -> Self {
        self.width = width.max(120);
        self.height = height.max(100);
        self
    }
}

/// Whether smaller or larger is better along an axis (for the Pareto front).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Goal {
    Minimise,
    Maximise,
}

/// One labelled point of a scatter chart (e.g. one setting: seconds, error).
#[derive(Clone, Debug, PartialEq)]
pub struct ScatterPoint {
    pub label: String,
    pub x: f64,
    pub y: f64,
}

impl ScatterPoint {
    pub fn new(label: impl Into<String>, x: f64, y: f64) -> Self {
        Self {
            label: label.into(),
            x,
            y,
        }
    }
}

/// Indices of the points on the Pareto front (no other point is at least as good on both axes
/// and better on one), ordered by increasing x. Points with a non-finite coordinate are never
/// on it; of exact duplicates only the first is kept.
pub fn pareto_front(points: &[(f64, f64)], x_goal: Goal, y_goal: Goal) -> Vec<usize> {
    let better = |goal: Goal, a: f64, b: f64| match goal {
        Goal::Minimise => a < b,
        Goal::Maximise => a > b,
    };
    let no_worse = |goal: Goal, a: f64, b: f64| a == b || better(goal, a, b);
    let finite: Vec<usize> = (0..points.len())
        .filter(|&i| points[i].0.is_finite() && points[i].1.is_finite())
        .collect();
    let mut front: Vec<usize> = finite
        .iter()
        .copied()
        .filter(|&i| {
            let (xi, yi) = points[i];
            !finite.iter().any(|&j| {
                let (xj, yj) = points[j];
                let dominates = no_worse(x_goal, xj, xi)
                    && no_worse(y_goal, yj, yi)
                    && (better(x_goal, xj, xi) || better(y_goal, yj, yi));
                let earlier_duplicate = j < i && xj == xi && yj == yi;
                dominates || earlier_duplicate
            })
        })
        .collect();
    front.sort_by(|&a, &b| points[a].0.total_cmp(&points[b].0));
    front
}

/// A line chart with a legend; `spec.log_y` (and `log_x`) switch to logarithmic axes.
pub fn line_chart(series: &[Series], spec: &ChartSpec) -> Result<String, ChartError> {
    let drawable = |(x, y): &(f64, f64)| drawable(spec, *x, *y);
    // Each series as runs of drawable points, so a gap (e.g. a zero on a log axis) breaks it.
    let runs: Vec<Vec<Vec<(f64, f64)>>> = series
        .iter()
        .map(|s| {
            let mut out: Vec<Vec<(f64, f64)>> = vec![Vec::new()];
            for p in &s.points {
                if drawable(p) {
                    if let Some(last) = out.last_mut() {
                        last.push(*p);
                    }
                } else if out.last().is_some_and(|r| !r.is_empty()) {
                    out.push(Vec::new());
                }
            }
            out.retain(|r| !r.is_empty());
            out
        })
        .collect();
    let all: Vec<(f64, f64)> = runs.iter().flatten().flatten().copied().collect();
    let (xr, mut yr) = ranges(spec, &all);
    let legend_rows = series.iter().filter(|s| !s.label.is_empty()).count();
    if legend_rows > 0 && !all.is_empty() {
        yr = with_legend_headroom(spec, yr, legend_rows);
    }
    let plot = |root: &DrawingArea<SVGBackend, Shift>| -> Result<(), DrawError> {
        with_axes(root, spec, xr, yr, |chart| {
            for (k, (s, runs)) in series.iter().zip(&runs).enumerate() {
                let color = to_color(s.color.unwrap_or(PALETTE[k % PALETTE.len()]));
                let style = color.stroke_width(2);
                for (r, run) in runs.iter().enumerate() {
                    // The legend entry comes with the first run only.
                    let label = (r == 0 && !s.label.is_empty()).then_some(s.label.as_str());
                    chart.line(run, style, s.dashed, label)?;
                }
            }
            if series.iter().any(|s| !s.label.is_empty()) && !all.is_empty() {
                chart.legend()?;
            }
            Ok(())
        })
    };
    render(spec, plot)
}

/// A scatter chart of labelled points with the Pareto front marked (front points filled and
/// joined by a line, each point labelled). For speed against error both goals are `Minimise`.
pub fn scatter_pareto(
    points: &[ScatterPoint],
    spec: &ChartSpec,
    x_goal: Goal,
    y_goal: Goal,
) -> Result<String, ChartError> {
    let shown: Vec<usize> = (0..points.len())
        .filter(|&i| drawable(spec, points[i].x, points[i].y))
        .collect();
    let xy: Vec<(f64, f64)> = shown.iter().map(|&i| (points[i].x, points[i].y)).collect();
    let front_local = pareto_front(&xy, x_goal, y_goal);
    let front: Vec<(f64, f64)> = front_local.iter().map(|&k| xy[k]).collect();
    let (xr, yr) = ranges(spec, &xy);
    let others = to_color(PALETTE[0]).stroke_width(1);
    let marked = to_color(PALETTE[3]).filled();
    let labels: Vec<((f64, f64), String)> = shown
        .iter()
        .map(|&i| ((points[i].x, points[i].y), points[i].label.clone()))
        .collect();
    let plot = |root: &DrawingArea<SVGBackend, Shift>| -> Result<(), DrawError> {
        with_axes(root, spec, xr, yr, |chart| {
            chart.circles(&xy, 4, others, Some("settings"))?;
            if !front.is_empty() {
                chart.line(&front, to_color(PALETTE[3]).stroke_width(2), false, None)?;
                chart.circles(&front, 5, marked, Some("Pareto front"))?;
            }
            chart.texts(&labels)?;
            if !xy.is_empty() {
                chart.legend()?;
            }
            Ok(())
        })
    };
    render(spec, plot)
}

fn drawable(spec: &ChartSpec, x: f64, y: f64) -> bool {
    x.is_finite() && y.is_finite() && (!spec.log_x || x > 0.0) && (!spec.log_y || y > 0.0)
}

fn to_color(c: Rgb) -> RGBColor {
    RGBColor(c[0], c[1], c[2])
}

/// Axis ranges covering the data with a margin; defaults when there is none.
fn ranges(spec: &ChartSpec, pts: &[(f64, f64)]) -> ((f64, f64), (f64, f64)) {
    let axis = |vals: Vec<f64>, log: bool| -> (f64, f64) {
        let lo = vals.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = vals.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        if !lo.is_finite() || !hi.is_finite() {
            return if log { (0.1, 10.0) } else { (0.0, 1.0) };
        }
        if log {
            if hi / lo < 1.0 + 1e-9 {
                (lo / 2.0, hi * 2.0)
            } else {
                let f = (hi / lo).powf(0.05);
                (lo / f, hi * f)
            }
        } else if hi - lo <= 1e-12 * hi.abs().max(lo.abs()).max(1e-300) {
            let pad = if lo == 0.0 { 1.0 } else { 0.1 * lo.abs() };
            (lo - pad, hi + pad)
        } else {
            let pad = 0.05 * (hi - lo);
            (lo - pad, hi + pad)
        }
    };
    (
        axis(pts.iter().map(|p| p.0).collect(), spec.log_x),
        axis(pts.iter().map(|p| p.1).collect(), spec.log_y),
    )
}

/// Raises the top of the y range so the legend box (upper right, about 17 px a row) sits above
/// the data rather than over it.
fn with_legend_headroom(spec: &ChartSpec, yr: (f64, f64), rows: usize) -> (f64, f64) {
    // Plot height: the SVG less the caption, margins and the x label area (see `axes_and`).
    let plot_px = (spec.height as f64 - 90.0).max(40.0);
    let legend_px = 17.0 * rows as f64 + 14.0;
    let f = (legend_px / plot_px).min(0.6);
    if spec.log_y {
        let (lo, hi) = (yr.0.ln(), yr.1.ln());
        (yr.0, (hi + (hi - lo) * f / (1.0 - f)).exp())
    } else {
        (yr.0, yr.1 + (yr.1 - yr.0) * f / (1.0 - f))
    }
}

/// Number text for tick labels: short, and scientific where plain would be long.
pub fn format_tick(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    let a = v.abs();
    if !(1e-3..1e5).contains(&a) {
        return format!("{v:.1e}");
    }
    let s = format!("{v:.4}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    s.to_string()
}

type Chart<'a, 'b, X, Y> = ChartContext<'a, SVGBackend<'b>, Cartesian2d<X, Y>>;

/// Builds the chart with the right combination of linear and log axes, draws the mesh, then
/// calls `draw` through [`SeriesTarget`], so the drawing code is written once for all four.
fn with_axes(
    root: &DrawingArea<SVGBackend, Shift>,
    spec: &ChartSpec,
    xr: (f64, f64),
    yr: (f64, f64),
    draw: impl Fn(&mut dyn SeriesTarget) -> Result<(), DrawError>,
) -> Result<(), DrawError> {
    match (spec.log_x, spec.log_y) {
        (false, false) => axes_and(root, spec, xr.0..xr.1, yr.0..yr.1, &draw),
        (false, true) => axes_and(root, spec, xr.0..xr.1, (yr.0..yr.1).log_scale(), &draw),
        (true, false) => axes_and(root, spec, (xr.0..xr.1).log_scale(), yr.0..yr.1, &draw),
        (true, true) => axes_and(
            root,
            spec,
            (xr.0..xr.1).log_scale(),
            (yr.0..yr.1).log_scale(),
            &draw,
        ),
    }
}

fn axes_and<XS, YS>(
    root: &DrawingArea<SVGBackend, Shift>,
    spec: &ChartSpec,
    xs: XS,
    ys: YS,
    draw: &dyn Fn(&mut dyn SeriesTarget) -> Result<(), DrawError>,
) -> Result<(), DrawError>
where
    XS: AsRangedCoord<Value = f64>,
    YS: AsRangedCoord<Value = f64>,
    XS::CoordDescType: ValueFormatter<f64> + 'static,
    YS::CoordDescType: ValueFormatter<f64> + 'static,
{
    let mut chart = ChartBuilder::on(root)
        .caption(&spec.title, ("sans-serif", 17))
        .margin(12)
        .x_label_area_size(42)
        .y_label_area_size(64)
        .build_cartesian_2d(xs, ys)?;
    chart
        .configure_mesh()
        .x_desc(&spec.x_label)
        .y_desc(&spec.y_label)
        .x_label_formatter(&|v| format_tick(*v))
        .y_label_formatter(&|v| format_tick(*v))
        .label_style(("sans-serif", 12))
        .axis_desc_style(("sans-serif", 14))
        .light_line_style(BLACK.mix(0.05))
        .bold_line_style(BLACK.mix(0.15))
        .draw()?;
    draw(&mut chart)
}

/// The drawing operations the chart functions need, without naming the coordinate types (which
/// differ between linear and log axes).
trait SeriesTarget {
    fn line(
        &mut self,
        pts: &[(f64, f64)],
        style: ShapeStyle,
        dashed: bool,
        label: Option<&str>,
    ) -> Result<(), DrawError>;
    fn circles(
        &mut self,
        pts: &[(f64, f64)],
        size: u32,
        style: ShapeStyle,
        label: Option<&str>,
    ) -> Result<(), DrawError>;
    fn texts(&mut self, items: &[((f64, f64), String)]) -> Result<(), DrawError>;
    fn legend(&mut self) -> Result<(), DrawError>;
}

impl<'a, 'b: 'a, X, Y> SeriesTarget for Chart<'a, 'b, X, Y>
where
    X: plotters::coord::ranged1d::Ranged<ValueType = f64>,
    Y: plotters::coord::ranged1d::Ranged<ValueType = f64>,
{
    fn line(
        &mut self,
        pts: &[(f64, f64)],
        style: ShapeStyle,
        dashed: bool,
        label: Option<&str>,
    ) -> Result<(), DrawError> {
        // A lone point (a run between gaps, or a one-point series) would draw nothing as a line.
        let anno = if pts.len() == 1 {
            self.draw_series(pts.iter().map(|&p| Circle::new(p, 3, style.filled())))?
        } else if dashed {
            self.draw_series(DashedLineSeries::new(pts.iter().copied(), 6, 4, style))?
        } else {
            self.draw_series(LineSeries::new(pts.iter().copied(), style))?
        };
        if let Some(l) = label {
            anno.label(l)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], style));
        }
        Ok(())
    }

    fn circles(
        &mut self,
        pts: &[(f64, f64)],
        size: u32,
        style: ShapeStyle,
        label: Option<&str>,
    ) -> Result<(), DrawError> {
        let anno = self.draw_series(pts.iter().map(|&p| Circle::new(p, size, style)))?;
        if let Some(l) = label {
            anno.label(l)
                .legend(move |(x, y)| Circle::new((x + 10, y), size, style));
        }
        Ok(())
    }

    fn texts(&mut self, items: &[((f64, f64), String)]) -> Result<(), DrawError> {
        let font = ("sans-serif", 11).into_font().color(&BLACK.mix(0.8));
        self.draw_series(
            items
                .iter()
                .map(|(p, t)| EmptyElement::at(*p) + Text::new(t.clone(), (7, -7), font.clone())),
        )?;
        Ok(())
    }

    fn legend(&mut self) -> Result<(), DrawError> {
        self.configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK.mix(0.4))
            .label_font(("sans-serif", 13))
            .draw()
    }
}

/// Draws into an SVG string.
fn render(
    spec: &ChartSpec,
    plot: impl FnOnce(&DrawingArea<SVGBackend, Shift>) -> Result<(), DrawError>,
) -> Result<String, ChartError> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (spec.width, spec.height)).into_drawing_area();
        let err = |source| ChartError::Draw {
            title: spec.title.clone(),
            source,
        };
        root.fill(&WHITE).map_err(err)?;
        plot(&root).map_err(err)?;
        root.present().map_err(err)?;
    }
    Ok(svg)
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;

    fn count(svg: &str, needle: &str) -> usize {
        svg.matches(needle).count()
    }

    /// The `<text>` contents of an SVG, in order.
    fn texts(svg: &str) -> Vec<String> {
        svg.split("<text")
            .skip(1)
            .filter_map(|t| {
                let start = t.find('>')? + 1;
                let end = t.find("</text>")?;
                Some(t[start..end].trim().to_string())
            })
            .collect()
    }

    #[test]
    fn line_chart_draws_each_series_with_legend_title_and_axis_labels() {
        let s = vec![
            Series::new(
                "truth <neural fit>",
                vec![(0.0, 1.0), (1.0, 2.0), (2.0, 3.0)],
            ),
            Series::new("recon & co", vec![(0.0, 2.0), (2.0, 1.0)]),
        ];
        let svg = line_chart(&s, &ChartSpec::new("In-plane", "view (deg)", "f_r (1/sr)")).unwrap();
        assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
        // One polyline per series and one per legend swatch, in the palette colours.
        assert_eq!(count(&svg, "stroke=\"#1F77B4\""), 2);
        assert_eq!(count(&svg, "stroke=\"#FF7F0E\""), 2);
        let t = texts(&svg);
        for want in ["In-plane", "view (deg)", "f_r (1/sr)"] {
            assert!(t.iter().any(|x| x == want), "{want} missing from {t:?}");
        }
        // Labels are escaped by the SVG backend.
        assert!(t.iter().any(|x| x == "truth &lt;neural fit&gt;"), "{t:?}");
        assert!(t.iter().any(|x| x == "recon &amp; co"), "{t:?}");
    }

    #[test]
    fn log_axis_breaks_lines_at_zeros_instead_of_bridging_them() {
        let pts = vec![(0.0, 1.0), (1.0, 2.0), (2.0, 0.0), (3.0, 4.0), (4.0, 8.0)];
        let spec = ChartSpec::new("log", "x", "y");
        let lin = line_chart(&[Series::new("s", pts.clone())], &spec).unwrap();
        assert_eq!(count(&lin, "stroke=\"#1F77B4\""), 2); // one line + legend
        let log = line_chart(&[Series::new("s", pts)], &spec.clone().log_y(true)).unwrap();
        assert_eq!(count(&log, "stroke=\"#1F77B4\""), 3); // two runs + legend
        // Log ticks are labelled with data-range numbers.
        assert!(texts(&log).iter().any(|x| x == "1"));
    }

    #[test]
    fn empty_or_undrawable_data_still_gives_a_valid_chart() {
        for spec in [
            ChartSpec::new("empty", "x", "y"),
            ChartSpec::new("empty", "x", "y").log_x(true).log_y(true),
        ] {
            let svg = line_chart(&[], &spec).unwrap();
            assert!(svg.contains("</svg>"));
            let nan = vec![Series::new(
                "nan",
                vec![(f64::NAN, 1.0), (1.0, f64::INFINITY)],
            )];
            assert!(line_chart(&nan, &spec).unwrap().contains("</svg>"));
            assert!(
                scatter_pareto(&[], &spec, Goal::Minimise, Goal::Minimise)
                    .unwrap()
                    .contains("</svg>")
            );
        }
        // A constant series gets a non-degenerate range.
        let flat = vec![Series::new("flat", vec![(0.0, 0.0), (1.0, 0.0)])];
        assert!(line_chart(&flat, &ChartSpec::new("f", "x", "y")).is_ok());
    }

    #[test]
    fn pareto_front_of_known_sets() {
        // (seconds, error): the front is the lower-left staircase.
        let p = [
            (1.0, 0.5),
            (2.0, 0.2),
            (4.0, 0.3),
            (3.0, 0.1),
            (5.0, 0.1),
            (0.5, 0.9),
        ];
        assert_eq!(
            pareto_front(&p, Goal::Minimise, Goal::Minimise),
            vec![5, 0, 1, 3]
        );
        // Maximising y (e.g. similarity) flips which points survive.
        assert_eq!(pareto_front(&p, Goal::Minimise, Goal::Maximise), vec![5]);
        assert_eq!(
            pareto_front(&p, Goal::Maximise, Goal::Maximise),
            vec![5, 0, 2, 4]
        );
        // Duplicates count once; non-finite points never join.
        let d = [
            (1.0, 1.0),
            (1.0, 1.0),
            (f64::NAN, 0.0),
            (0.0, f64::INFINITY),
        ];
        assert_eq!(pareto_front(&d, Goal::Minimise, Goal::Minimise), vec![0]);
        assert!(pareto_front(&[], Goal::Minimise, Goal::Minimise).is_empty());
    }

    #[test]
    fn scatter_marks_exactly_the_front() {
        let pts = vec![
            ScatterPoint::new("k=4", 1.0, 0.5),
            ScatterPoint::new("k=8", 2.0, 0.2),
            ScatterPoint::new("k=16", 4.0, 0.3),
            ScatterPoint::new("k=32", 3.0, 0.1),
        ];
        let spec = ChartSpec::new("speed vs error", "seconds", "relative error").log_x(true);
        let svg = scatter_pareto(&pts, &spec, Goal::Minimise, Goal::Minimise).unwrap();
        // Filled markers: the three front points and the legend swatch.
        assert_eq!(count(&svg, "fill=\"#D62728\""), 4);
        // Every point drawn (plus the legend swatch), every point labelled.
        assert_eq!(count(&svg, "fill=\"none\" stroke=\"#1F77B4\""), 5);
        let t = texts(&svg);
        for l in ["k=4", "k=8", "k=16", "k=32", "Pareto front"] {
            assert!(t.iter().any(|x| x == l), "{l} missing");
        }
    }

    #[test]
    fn tick_labels_are_short() {
        assert_eq!(format_tick(0.0), "0");
        assert_eq!(format_tick(0.5), "0.5");
        assert_eq!(format_tick(45.0), "45");
        assert_eq!(format_tick(0.0001), "1.0e-4");
        assert_eq!(format_tick(-2.25), "-2.25");
    }
}
