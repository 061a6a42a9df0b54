//! The run's figures, as PNG and SVG (plotters): per case the time series
//! of θ_d, θ_a and every estimate (the paper's Fig. 7) and the hysteresis
//! loops (θ_a against θ_d, one curve per estimator), and per table a
//! summary of our RMSE beside the paper's.
//!
//! Text needs a TrueType font: `KFLEX_FONT` names one, else the first of a
//! few common sans-serif fonts found on the system (Debian's
//! `fonts-dejavu-core` first). Without one the figures are skipped with a
//! warning saying what to install; the run's results do not depend on them.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use anyhow::{Context, Result, anyhow, bail};
use plotters::coord::Shift;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

use crate::output::{encode_png, write_atomic_bytes};

/// Fonts tried when `KFLEX_FONT` is not set, in order.
const SYSTEM_FONTS: [&str; 6] = [
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu-sans-fonts/DejaVuSans.ttf",
    "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
    "/usr/share/fonts/truetype/freefont/FreeSans.ttf",
    "/usr/share/fonts/truetype/noto/NotoSans-Regular.ttf",
];

/// Size of every figure, px (the SVG's too).
const SIZE: (u32, u32) = (960, 600);

/// Colours (Okabe–Ito, colour-blind safe).
pub const BLACK_LINE: RGBColor = RGBColor(0, 0, 0);
pub const ORANGE: RGBColor = RGBColor(230, 159, 0);
pub const GREY: RGBColor = RGBColor(120, 120, 120);
pub const BLUE: RGBColor = RGBColor(0, 114, 178);
pub const VERMILLION: RGBColor = RGBColor(213, 94, 0);
pub const GREEN: RGBColor = RGBColor(0, 158, 115);
pub const PINK: RGBColor = RGBColor(204, 121, 167);

/// Registers the font for the figures' text, once per process: `Ok(path)`
/// of the font used, or why there is none (with what to do).
pub fn init_font() -> Result<&'static Path, String> {
    static FONT: OnceLock<Result<PathBuf, String>> = OnceLock::new();
    FONT.get_or_init(|| {
        let path = match std::env::var_os("KFLEX_FONT") {
            Some(p) => PathBuf::from(p),
            None => SYSTEM_FONTS
                .iter()
                .map(PathBuf::from)
                .find(|p| p.is_file())
                .ok_or_else(|| {
                    "no TrueType font found for the figures' text: install one \
                     (Debian/Ubuntu: apt-get install fonts-dejavu-core) or set \
                     KFLEX_FONT=/path/to/font.ttf"
                        .to_owned()
                })?,
        };
        let bytes = std::fs::read(&path)
            .map_err(|e| format!("reading the font {} (KFLEX_FONT): {e}", path.display()))?;
        // plotters keeps fonts for the whole process
        let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
        plotters::style::register_font("sans-serif", FontStyle::Normal, bytes).map_err(|_| {
            format!(
                "{} is not a TrueType or OpenType font (KFLEX_FONT)",
                path.display()
            )
        })?;
        Ok(path)
    })
    .as_deref()
    .map_err(Clone::clone)
}

/// A named series of y values (`None`: no value there, e.g. an estimator
/// before its first estimate).
pub struct Series<'a> {
    pub name: String,
    pub colour: RGBColor,
    pub values: &'a [Option<f64>],
}

/// A named curve through (x, y) points.
pub struct Curve<'a> {
    pub name: String,
    pub colour: RGBColor,
    pub x: &'a [f64],
    pub y: &'a [Option<f64>],
}

/// A figure's mean and standard deviation.
pub type MeanStd = (f64, f64);

/// One member's bars in a group: ours and the paper's, where there are.
pub type BarPair = (Option<MeanStd>, Option<MeanStd>);

/// One group of bars: a case, with our figure and the paper's per member.
pub struct BarGroup {
    pub label: String,
    /// Per member (estimator), in the figure's member order.
    pub bars: Vec<BarPair>,
}

/// The drawing of one figure, on any backend.
pub trait Figure {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<()>;

    /// Writes `stem.png` and `stem.svg` in `dir`, each whole or not at all.
    fn write(&self, dir: &Path, stem: &str) -> Result<Vec<PathBuf>> {
        let (w, h) = SIZE;
        let mut rgb = vec![0u8; 3 * w as usize * h as usize];
        {
            let root = BitMapBackend::with_buffer(&mut rgb, SIZE).into_drawing_area();
            self.draw(&root)?;
            root.present()
                .map_err(|e| anyhow!("drawing {stem}.png: {e}"))?;
        }
        let png = encode_png(
            &format!("{stem}.png"),
            &rgb,
            w,
            h,
            image::ExtendedColorType::Rgb8,
        )?;
        let mut svg = String::new();
        {
            let root = SVGBackend::with_string(&mut svg, SIZE).into_drawing_area();
            self.draw(&root)?;
            root.present()
                .map_err(|e| anyhow!("drawing {stem}.svg: {e}"))?;
        }
        Ok(vec![
            write_atomic_bytes(dir, &format!("{stem}.png"), &png)?,
            write_atomic_bytes(dir, &format!("{stem}.svg"), svg.as_bytes())?,
        ])
    }
}

/// A plotters error as ours.
fn err<E: std::fmt::Debug>(e: E) -> anyhow::Error {
    anyhow!("drawing a figure: {e:?}")
}

/// The range of finite values in `values`, padded by 5 % (a flat range by ±1).
fn range(values: impl Iterator<Item = f64>) -> Option<std::ops::Range<f64>> {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    if lo > hi {
        return None;
    }
    let pad = if hi > lo { 0.05 * (hi - lo) } else { 1.0 };
    Some(lo - pad..hi + pad)
}

/// Unbroken runs of a series' defined points (both coordinates finite).
fn runs<'a>(x: &'a [f64], y: &'a [Option<f64>]) -> impl Iterator<Item = Vec<(f64, f64)>> + 'a {
    let point = |(x, y): (&f64, &Option<f64>)| {
        y.filter(|y| y.is_finite() && x.is_finite())
            .map(|y| (*x, y))
    };
    let mut points = x.iter().zip(y).map(point).peekable();
    std::iter::from_fn(move || {
        while points.next_if(Option::is_none).is_some() {}
        let run: Vec<(f64, f64)> =
            std::iter::from_fn(|| points.next_if(Option::is_some).flatten()).collect();
        (!run.is_empty()).then_some(run)
    })
}

/// A chart on f64 axes.
type Chart<'a, DB> = ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// A white page with `title` and f64 axes over `x` and `y`.
fn chart<'a, DB: DrawingBackend + 'a>(
    root: &'a DrawingArea<DB, Shift>,
    title: &str,
    x: std::ops::Range<f64>,
    y: std::ops::Range<f64>,
) -> Result<Chart<'a, DB>> {
    root.fill(&WHITE).map_err(err)?;
    ChartBuilder::on(root)
        .caption(title, ("sans-serif", 22))
        .margin(16)
        .x_label_area_size(44)
        .y_label_area_size(56)
        .build_cartesian_2d(x, y)
        .map_err(err)
}

/// The series' legend, in the chart's upper left corner.
fn legend<'a, DB: DrawingBackend + 'a>(chart: &mut Chart<'a, DB>) -> Result<()> {
    chart
        .configure_series_labels()
        .label_font(("sans-serif", 15))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK.mix(0.5))
        .position(SeriesLabelPosition::UpperLeft)
        .draw()
        .map_err(err)?;
    Ok(())
}

/// Lines of (x, y) curves on shared axes, with a legend.
pub struct Lines<'a> {
    pub title: String,
    pub x_desc: &'static str,
    pub y_desc: &'static str,
    pub curves: Vec<Curve<'a>>,
    /// Draw the diagonal y = x (a loop's ideal).
    pub diagonal: bool,
}

impl Lines<'_> {
    /// Time series: `series` against `time_s`.
    pub fn time_series<'a>(title: String, time_s: &'a [f64], series: Vec<Series<'a>>) -> Lines<'a> {
        Lines {
            title,
            x_desc: "time (s)",
            y_desc: "angle (deg)",
            curves: series
                .into_iter()
                .map(|s| Curve {
                    name: s.name,
                    colour: s.colour,
                    x: time_s,
                    y: s.values,
                })
                .collect(),
            diagonal: false,
        }
    }
}

impl Figure for Lines<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<()> {
        let x = range(self.curves.iter().flat_map(|c| c.x.iter().copied()))
            .context("a figure with no data")?;
        let y = range(
            self.curves
                .iter()
                .flat_map(|c| c.y.iter().filter_map(|v| *v)),
        )
        .context("a figure with no data")?;
        // room above the data for the legend
        let y = y.start..y.end + 0.06 * (self.curves.len() + 1) as f64 * (y.end - y.start);
        let mut chart = chart(root, &self.title, x.clone(), y.clone())?;
        chart
            .configure_mesh()
            .x_desc(self.x_desc)
            .y_desc(self.y_desc)
            .label_style(("sans-serif", 15))
            .axis_desc_style(("sans-serif", 16))
            .light_line_style(RGBColor(244, 244, 244))
            .draw()
            .map_err(err)?;
        if self.diagonal {
            let (lo, hi) = (x.start.max(y.start), x.end.min(y.end));
            if lo < hi {
                chart
                    .draw_series(std::iter::once(PathElement::new(
                        vec![(lo, lo), (hi, hi)],
                        BLACK.mix(0.4).stroke_width(1),
                    )))
                    .map_err(err)?
                    .label("ideal")
                    .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK.mix(0.4)));
            }
        }
        for curve in &self.curves {
            let colour = curve.colour;
            let mut labelled = false;
            for run in runs(curve.x, curve.y) {
                let drawn = chart
                    .draw_series(LineSeries::new(run, colour.stroke_width(2)))
                    .map_err(err)?;
                if !labelled {
                    drawn.label(curve.name.clone()).legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2))
                    });
                    labelled = true;
                }
            }
        }
        legend(&mut chart)
    }
}

/// A table's summary: per case, per member our bar (solid) beside the
/// paper's (pale), each with its ± std as a whisker.
pub struct Bars {
    pub title: String,
    pub y_desc: &'static str,
    /// The members' names (estimators) and colours, in bar order.
    pub members: Vec<(String, RGBColor)>,
    pub groups: Vec<BarGroup>,
}

impl Figure for Bars {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<()> {
        let top = self
            .groups
            .iter()
            .flat_map(|g| g.bars.iter())
            .flat_map(|(a, b)| [a, b])
            .filter_map(|v| v.map(|(m, s)| m + s.max(0.0)))
            .filter(|v| v.is_finite())
            .fold(0.0f64, f64::max);
        if top <= 0.0 {
            bail!("a summary with no figures");
        }
        let n = self.groups.len();
        let m = self.members.len().max(1);
        let labels: Vec<String> = self.groups.iter().map(|g| g.label.clone()).collect();
        let label_of = move |x: &f64| {
            let k = x.round();
            if (x - k).abs() < 1e-6 && k >= 0.0 {
                labels.get(k as usize).cloned().unwrap_or_default()
            } else {
                String::new()
            }
        };
        let mut chart = chart(
            root,
            &self.title,
            -0.5..n as f64 - 0.5,
            // room above the bars for the legend
            0.0..top * (1.1 + 0.09 * (self.members.len() + 1) as f64),
        )?;
        chart
            .configure_mesh()
            .disable_x_mesh()
            .x_labels(n.max(1))
            .x_label_formatter(&label_of)
            .y_desc(self.y_desc)
            .label_style(("sans-serif", 15))
            .axis_desc_style(("sans-serif", 16))
            .light_line_style(RGBColor(244, 244, 244))
            .draw()
            .map_err(err)?;
        // each group spans 0.8 of its slot: m members, two bars each
        let slot = 0.8 / m as f64;
        let bar = slot / 2.0;
        for (g, group) in self.groups.iter().enumerate() {
            for (k, ((_, colour), (ours, paper))) in
                self.members.iter().zip(&group.bars).enumerate()
            {
                let colour = *colour;
                let left = g as f64 - 0.4 + k as f64 * slot;
                for (j, value) in [ours, paper].into_iter().enumerate() {
                    let Some((mean, std)) = *value else {
                        continue;
                    };
                    if !mean.is_finite() {
                        continue;
                    }
                    let x0 = left + j as f64 * bar;
                    let x1 = x0 + 0.9 * bar;
                    let style = if j == 0 {
                        colour.filled()
                    } else {
                        colour.mix(0.35).filled()
                    };
                    chart
                        .draw_series(std::iter::once(Rectangle::new(
                            [(x0, 0.0), (x1, mean)],
                            style,
                        )))
                        .map_err(err)?;
                    if std.is_finite() && std > 0.0 {
                        let xc = 0.5 * (x0 + x1);
                        chart
                            .draw_series(std::iter::once(PathElement::new(
                                vec![(xc, (mean - std).max(0.0)), (xc, mean + std)],
                                BLACK.stroke_width(1),
                            )))
                            .map_err(err)?;
                    }
                }
            }
        }
        // the legend: a member's colour, and solid for ours, pale for the paper's
        for (name, colour) in &self.members {
            let colour = *colour;
            chart
                .draw_series(std::iter::empty::<Rectangle<(f64, f64)>>())
                .map_err(err)?
                .label(name.clone())
                .legend(move |(x, y)| {
                    Rectangle::new([(x, y - 6), (x + 16, y + 6)], colour.filled())
                });
        }
        chart
            .draw_series(std::iter::empty::<Rectangle<(f64, f64)>>())
            .map_err(err)?
            .label("pale: the paper's (± its std)")
            .legend(|(x, y)| {
                Rectangle::new([(x, y - 6), (x + 16, y + 6)], GREY.mix(0.35).filled())
            });
        legend(&mut chart)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_series_breaks_where_it_has_no_value() {
        let x = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0];
        let y = [None, Some(1.0), Some(f64::NAN), Some(3.0), Some(4.0), None];
        let pieces: Vec<Vec<(f64, f64)>> = runs(&x, &y).collect();
        assert_eq!(pieces, vec![vec![(1.0, 1.0)], vec![(3.0, 3.0), (4.0, 4.0)]]);
        assert_eq!(runs(&x, &[None; 6]).count(), 0);
        // a point without a finite x breaks the run too; a shorter x ends it
        let x = [0.0, f64::NAN, 2.0];
        let y = [Some(1.0), Some(2.0), Some(3.0), Some(4.0)];
        let pieces: Vec<Vec<(f64, f64)>> = runs(&x, &y).collect();
        assert_eq!(pieces, vec![vec![(0.0, 1.0)], vec![(2.0, 3.0)]]);
    }

    #[test]
    fn an_axis_range_pads_the_finite_values() {
        let r = range([2.0, f64::NAN, 12.0, f64::INFINITY].into_iter()).unwrap();
        assert!((r.start - 1.5).abs() < 1e-12 && (r.end - 12.5).abs() < 1e-12);
        let flat = range([3.0, 3.0].into_iter()).unwrap();
        assert_eq!(flat, 2.0..4.0);
        assert!(range([f64::NAN].into_iter()).is_none());
    }
}
