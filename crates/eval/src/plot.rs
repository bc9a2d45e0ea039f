//! Figures as PNG: line charts with log or linear axes, bar charts, stacked bar charts, error
//! maps with a colour bar, crops and outlined images.
//!
//! Charts are drawn by `plotters` on an RGB buffer with an embedded font (Ubuntu Light, from
//! `epaint_default_fonts`), so they look the same on every machine and need no system fonts.
//! Log axes are drawn as linear axes over log10 of the values with ticks placed here, at
//! powers of ten (and 2 and 5 times them over short ranges), so that labels are round numbers.

use std::sync::Once;

use plotters::chart::MeshStyle;
use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint, Ranged};
use plotters::prelude::*;
use plotters::style::colors::colormaps::ViridisRGB;

use crate::image::Image;
use pathlight_core::color::{linear_to_srgb, linear_to_srgb8, luminance};
use pathlight_render::output::encode_rgb8_png;

/// Largest chart or image side drawn (a guard against absurd sizes).
const MAX_SIDE: u32 = 8192;
/// Colours of the series, bars and crop outlines, in order (Tableau 10).
pub const PALETTE: [(u8, u8, u8); 10] = [
    (31, 119, 180),
    (255, 127, 14),
    (44, 160, 44),
    (214, 39, 40),
    (148, 103, 189),
    (140, 86, 75),
    (227, 119, 194),
    (127, 127, 127),
    (188, 189, 34),
    (23, 190, 207),
];
const FONT: &str = "sans-serif";

/// The charts' common axis style: label fonts, light grey grid lines, no minor lines.
fn house_style<'m, 'a, 'b, X, Y, DB>(
    mesh: &'m mut MeshStyle<'a, 'b, X, Y, DB>,
) -> &'m mut MeshStyle<'a, 'b, X, Y, DB>
where
    X: Ranged,
    Y: Ranged,
    DB: DrawingBackend,
{
    mesh.label_style((FONT, 15))
        .axis_desc_style((FONT, 16))
        .bold_line_style(RGBColor(215, 215, 215))
        .light_line_style(TRANSPARENT)
}

/// One line of a line chart.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    pub name: String,
    pub points: Vec<(f64, f64)>,
    /// A guide (e.g. the slope a theory predicts): drawn dashed and grey, without markers.
    pub guide: bool,
}

/// An axis: its label and whether it is logarithmic.
#[derive(Debug, Clone, PartialEq)]
pub struct Axis {
    pub label: String,
    pub log: bool,
}

/// One bar of a stacked bar chart: its label and its parts (name, value), bottom first.
#[derive(Debug, Clone, PartialEq)]
pub struct Stack {
    pub label: String,
    pub parts: Vec<(String, f64)>,
}

/// A rectangle of pixels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct Rect {
    pub x: u32,
    pub y: u32,
    pub width: u32,
    pub height: u32,
}

/// A figure that could not be drawn.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    #[error("plot {title:?}: {problem}")]
    Draw { title: String, problem: String },
    #[error("plot {title:?}: size {width}x{height} is outside 1..={MAX_SIDE}")]
    Size {
        title: String,
        width: u32,
        height: u32,
    },
}

fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // The font is compiled in and valid; should it ever fail to parse, text is simply
        // missing from the charts (plotters reports the missing font per call).
        let _ = plotters::style::register_font(
            FONT,
            FontStyle::Normal,
            epaint_default_fonts::UBUNTU_LIGHT,
        );
    });
}

fn colour(i: usize) -> RGBColor {
    let (r, g, b) = PALETTE[i % PALETTE.len()];
    RGBColor(r, g, b)
}

/// A white RGB canvas of `width` x `height`, checked.
fn canvas(title: &str, width: u32, height: u32) -> Result<Vec<u8>, PlotError> {
    if width == 0 || height == 0 || width > MAX_SIDE || height > MAX_SIDE {
        return Err(PlotError::Size {
            title: title.to_owned(),
            width,
            height,
        });
    }
    register_font();
    Ok(vec![255u8; width as usize * height as usize * 3])
}

/// Draws with plotters into `buf` and encodes the result.
fn draw_png(
    title: &str,
    width: u32,
    height: u32,
    draw: impl FnOnce(
        &DrawingArea<BitMapBackend, plotters::coord::Shift>,
    ) -> Result<(), Box<dyn std::error::Error>>,
) -> Result<Vec<u8>, PlotError> {
    let mut buf = canvas(title, width, height)?;
    {
        let root = BitMapBackend::with_buffer(&mut buf, (width, height)).into_drawing_area();
        draw(&root)
            .and_then(|()| root.present().map_err(Into::into))
            .map_err(|e| PlotError::Draw {
                title: title.to_owned(),
                problem: e.to_string(),
            })?;
    }
    Ok(encode_rgb8_png(width, height, &buf))
}

/// An axis' range in drawing space (log10 of the values for a log axis) and its ticks.
struct AxisScale {
    log: bool,
    range: (f64, f64),
    ticks: Vec<f64>,
}

impl AxisScale {
    /// The scale covering `values` (the finite ones, and for a log axis the positive ones),
    /// with a margin; `zero`: a linear axis that includes 0 (bar charts).
    fn new(values: impl Iterator<Item = f64>, log: bool, zero: bool) -> Self {
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for v in values.filter(|v| v.is_finite() && (!log || *v > 0.0)) {
            let t = if log { v.log10() } else { v };
            lo = lo.min(t);
            hi = hi.max(t);
        }
        if lo > hi {
            // No data: an empty unit range (one decade on a log axis).
            (lo, hi) = (0.0, 1.0);
        }
        if zero && !log {
            lo = lo.min(0.0);
            hi = hi.max(0.0);
        }
        if hi - lo < 1e-12 {
            let pad = if log { 0.5 } else { lo.abs().max(1.0) * 0.1 };
            lo -= pad;
            hi += pad;
        }
        let margin = (hi - lo) * 0.06;
        let lo = if zero && !log && lo == 0.0 {
            0.0
        } else {
            lo - margin
        };
        let hi = hi + margin;
        let ticks = if log {
            log_ticks(lo, hi)
        } else {
            linear_ticks(lo, hi)
        };
        Self {
            log,
            range: (lo, hi),
            ticks,
        }
    }

    /// A value in drawing space (`None` for a non-positive value on a log axis).
    fn to_draw(&self, v: f64) -> Option<f64> {
        if !v.is_finite() || (self.log && v <= 0.0) {
            None
        } else if self.log {
            Some(v.log10())
        } else {
            Some(v)
        }
    }

    fn coord(&self) -> Ticked {
        Ticked {
            lo: self.range.0,
            hi: self.range.1,
            ticks: self.ticks.clone(),
        }
    }

    fn label(&self, t: f64) -> String {
        format_number(if self.log { 10f64.powf(t) } else { t })
    }
}

/// A linear coordinate over [lo, hi] whose labelled grid lines are exactly `ticks`.
#[derive(Clone)]
struct Ticked {
    lo: f64,
    hi: f64,
    ticks: Vec<f64>,
}

impl Ranged for Ticked {
    type FormatOption = DefaultFormatting;
    type ValueType = f64;

    fn map(&self, v: &f64, limit: (i32, i32)) -> i32 {
        let t = (v - self.lo) / (self.hi - self.lo);
        limit.0 + (t * f64::from(limit.1 - limit.0)).round() as i32
    }

    fn key_points<H: KeyPointHint>(&self, hint: H) -> Vec<f64> {
        // Only bold (labelled) lines; light lines are not drawn.
        if hint.weight().allow_light_points() {
            Vec::new()
        } else {
            self.ticks.clone()
        }
    }

    fn range(&self) -> std::ops::Range<f64> {
        self.lo..self.hi
    }
}

/// Ticks of a log axis over [lo, hi] (log10 units): powers of ten, plus 2 and 5 times them
/// when the range spans fewer than three decades, every integer multiple under one decade,
/// and round linear steps under half a decade.
fn log_ticks(lo: f64, hi: f64) -> Vec<f64> {
    let span = hi - lo;
    if span < 0.5 {
        return linear_ticks(10f64.powf(lo), 10f64.powf(hi))
            .into_iter()
            .filter(|v| *v > 0.0)
            .map(f64::log10)
            .collect();
    }
    let mults: &[f64] = if span < 1.0 {
        &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0]
    } else if span < 3.0 {
        &[1.0, 2.0, 5.0]
    } else {
        &[1.0]
    };
    let step = if span > 12.0 {
        (span / 8.0).ceil() as i32
    } else {
        1
    };
    let mut ticks = Vec::new();
    let mut e = lo.floor() as i32;
    while (e as f64) <= hi.ceil() {
        for m in mults {
            let t = e as f64 + m.log10();
            if t >= lo - 1e-9 && t <= hi + 1e-9 && (step == 1 || e % step == 0) {
                ticks.push(t);
            }
        }
        e += 1;
    }
    ticks
}

/// About six round ticks (1, 2 or 5 times a power of ten apart) over [lo, hi].
fn linear_ticks(lo: f64, hi: f64) -> Vec<f64> {
    let raw = (hi - lo) / 6.0;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * mag)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * mag);
    let first = (lo / step).ceil() as i64;
    let last = (hi / step).floor() as i64;
    (first..=last).map(|i| i as f64 * step).collect()
}

/// A short label with at most four significant digits: plain decimals between 0.01 and
/// 100000, else scientific (`2.79e-3`).
pub fn format_number(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let a = v.abs();
    let trim = |s: String| {
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_owned()
        } else {
            s
        }
    };
    if (1e-2..1e5).contains(&a) {
        let digits = (3 - a.log10().floor() as i32).clamp(0, 6) as usize;
        return trim(format!("{v:.digits$}"));
    }
    let s = format!("{v:.2e}");
    let (mantissa, exponent) = s.split_once('e').expect("scientific notation");
    format!("{}e{exponent}", trim(mantissa.to_owned()))
}

/// The legend's corner: the one of the four whose quarter-sized box (in drawing space) holds
/// the fewest points along the lines, so that the legend hides as little data as possible.
fn legend_corner(lines: &[Vec<(f64, f64)>], xs: &AxisScale, ys: &AxisScale) -> SeriesLabelPosition {
    let fx = |x: f64| (x - xs.range.0) / (xs.range.1 - xs.range.0);
    let fy = |y: f64| (y - ys.range.0) / (ys.range.1 - ys.range.0);
    // Points along each segment, 32 per segment, in unit coordinates.
    let mut samples = Vec::new();
    for l in lines {
        for w in l.windows(2) {
            for k in 0..=32 {
                let t = k as f64 / 32.0;
                let x = w[0].0 + (w[1].0 - w[0].0) * t;
                let y = w[0].1 + (w[1].1 - w[0].1) * t;
                samples.push((fx(x), fy(y)));
            }
        }
        samples.extend(l.iter().map(|p| (fx(p.0), fy(p.1))));
    }
    let corners = [
        (SeriesLabelPosition::UpperRight, true, true),
        (SeriesLabelPosition::UpperLeft, false, true),
        (SeriesLabelPosition::LowerRight, true, false),
        (SeriesLabelPosition::LowerLeft, false, false),
    ];
    let count = |right: bool, upper: bool| {
        samples
            .iter()
            .filter(|(x, y)| {
                (if right { *x > 0.6 } else { *x < 0.4 })
                    && (if upper { *y > 0.7 } else { *y < 0.3 })
            })
            .count()
    };
    let mut best = (usize::MAX, SeriesLabelPosition::UpperRight);
    for (pos, right, upper) in corners {
        let n = count(right, upper);
        if n < best.0 {
            best = (n, pos);
        }
    }
    best.1
}

/// A line chart: one line with markers per series (guides dashed), a legend, log or linear
/// axes. Points that a log axis cannot show (non-positive) and non-finite points are left out.
pub fn line_chart(
    title: &str,
    x: &Axis,
    y: &Axis,
    series: &[Series],
    width: u32,
    height: u32,
) -> Result<Vec<u8>, PlotError> {
    let all = || series.iter().flat_map(|s| s.points.iter());
    let xs = AxisScale::new(all().map(|p| p.0), x.log, false);
    let ys = AxisScale::new(all().map(|p| p.1), y.log, false);
    draw_png(title, width, height, |root| {
        root.fill(&WHITE)?;
        let mut chart = ChartBuilder::on(root)
            .caption(title, (FONT, 22))
            .margin(14)
            .x_label_area_size(46)
            .y_label_area_size(78)
            .build_cartesian_2d(xs.coord(), ys.coord())?;
        let xl = |t: &f64| xs.label(*t);
        let yl = |t: &f64| ys.label(*t);
        house_style(&mut chart.configure_mesh())
            .x_desc(x.label.as_str())
            .y_desc(y.label.as_str())
            .x_label_formatter(&xl)
            .y_label_formatter(&yl)
            .draw()?;
        let drawn: Vec<Vec<(f64, f64)>> = series
            .iter()
            .map(|s| {
                s.points
                    .iter()
                    .filter_map(|&(px, py)| Some((xs.to_draw(px)?, ys.to_draw(py)?)))
                    .collect()
            })
            .collect();
        let mut line_index = 0;
        for (s, pts) in series.iter().zip(drawn.iter().cloned()) {
            if s.guide {
                let style = RGBColor(110, 110, 110).stroke_width(2);
                chart
                    .draw_series(DashedLineSeries::new(pts, 8, 6, style))?
                    .label(s.name.as_str())
                    .legend(move |(lx, ly)| PathElement::new(vec![(lx, ly), (lx + 22, ly)], style));
                continue;
            }
            let c = colour(line_index);
            line_index += 1;
            chart
                .draw_series(LineSeries::new(pts.clone(), c.stroke_width(3)))?
                .label(s.name.as_str())
                .legend(move |(lx, ly)| {
                    PathElement::new(vec![(lx, ly), (lx + 22, ly)], c.stroke_width(3))
                });
            chart.draw_series(pts.iter().map(|&p| Circle::new(p, 4, c.filled())))?;
        }
        chart
            .configure_series_labels()
            .label_font((FONT, 16))
            .background_style(WHITE.mix(0.85))
            .border_style(RGBColor(180, 180, 180))
            .position(legend_corner(&drawn, &xs, &ys))
            .draw()?;
        Ok(())
    })
}

/// A bar chart, one labelled bar per entry with its value written above it. With a log axis
/// the bars rise from the bottom of the axis.
pub fn bar_chart(
    title: &str,
    y: &Axis,
    bars: &[(String, f64)],
    width: u32,
    height: u32,
) -> Result<Vec<u8>, PlotError> {
    let stacks: Vec<Stack> = bars
        .iter()
        .map(|(label, v)| Stack {
            label: label.clone(),
            parts: vec![(label.clone(), *v)],
        })
        .collect();
    bars_png(title, y, &stacks, false, width, height)
}

/// A stacked bar chart: one bar per stack, one colour per part name (with a legend), the
/// total written above each bar. The axis is linear.
pub fn stacked_bar_chart(
    title: &str,
    y: &Axis,
    stacks: &[Stack],
    width: u32,
    height: u32,
) -> Result<Vec<u8>, PlotError> {
    let y = Axis {
        log: false,
        ..y.clone()
    };
    bars_png(title, &y, stacks, true, width, height)
}

fn bars_png(
    title: &str,
    y: &Axis,
    stacks: &[Stack],
    stacked: bool,
    width: u32,
    height: u32,
) -> Result<Vec<u8>, PlotError> {
    let totals: Vec<f64> = stacks
        .iter()
        .map(|s| s.parts.iter().map(|p| p.1).filter(|v| v.is_finite()).sum())
        .collect();
    let ys = AxisScale::new(totals.iter().copied(), y.log, true);
    // Part names in order of first appearance: one colour each.
    let mut names: Vec<&str> = Vec::new();
    for s in stacks {
        for (name, _) in &s.parts {
            if !names.contains(&name.as_str()) {
                names.push(name);
            }
        }
    }
    let n = stacks.len().max(1) as f64;
    let xs: Vec<f64> = (0..stacks.len()).map(|i| i as f64 + 0.5).collect();
    draw_png(title, width, height, |root| {
        root.fill(&WHITE)?;
        let mut chart = ChartBuilder::on(root)
            .caption(title, (FONT, 22))
            .margin(14)
            .x_label_area_size(46)
            .y_label_area_size(78)
            .build_cartesian_2d(
                Ticked {
                    lo: 0.0,
                    hi: n,
                    ticks: xs.clone(),
                },
                ys.coord(),
            )?;
        let xl = |t: &f64| {
            let i = t.floor() as usize;
            stacks.get(i).map_or(String::new(), |s| s.label.clone())
        };
        let yl = |t: &f64| ys.label(*t);
        house_style(&mut chart.configure_mesh())
            .disable_x_mesh()
            .y_desc(y.label.as_str())
            .x_label_formatter(&xl)
            .y_label_formatter(&yl)
            .draw()?;
        let bottom = ys.range.0;
        for (i, s) in stacks.iter().enumerate() {
            let (x0, x1) = (i as f64 + 0.2, i as f64 + 0.8);
            let mut acc = 0.0;
            for (part, v) in s.parts.iter().filter(|p| p.1.is_finite()) {
                let from = if acc == 0.0 {
                    bottom
                } else {
                    ys.to_draw(acc).unwrap_or(bottom)
                };
                acc += v;
                let Some(to) = ys.to_draw(acc) else { continue };
                let k = if stacked {
                    names.iter().position(|n| n == part).unwrap_or(0)
                } else {
                    i
                };
                chart.draw_series(std::iter::once(Rectangle::new(
                    [(x0, from), (x1, to)],
                    colour(k).filled(),
                )))?;
            }
            if let Some(top) = ys.to_draw(totals[i]) {
                let label = format_number(totals[i]);
                let pos = chart.backend_coord(&(i as f64 + 0.5, top));
                let style = TextStyle::from((FONT, 15).into_font())
                    .pos(plotters::style::text_anchor::Pos::new(
                        plotters::style::text_anchor::HPos::Center,
                        plotters::style::text_anchor::VPos::Bottom,
                    ))
                    .color(&BLACK);
                root.draw_text(&label, &style, (pos.0, pos.1 - 4))?;
            }
        }
        if stacked && !names.is_empty() {
            for (k, name) in names.iter().enumerate() {
                let c = colour(k);
                chart
                    .draw_series(std::iter::empty::<Rectangle<(f64, f64)>>())?
                    .label(*name)
                    .legend(move |(lx, ly)| {
                        Rectangle::new([(lx, ly - 6), (lx + 16, ly + 6)], c.filled())
                    });
            }
            chart
                .configure_series_labels()
                .label_font((FONT, 16))
                .background_style(WHITE.mix(0.85))
                .border_style(RGBColor(180, 180, 180))
                .position(SeriesLabelPosition::UpperRight)
                .draw()?;
        }
        Ok(())
    })
}

/// Integer upscaling that makes the shorter side of a `width` x `height` picture at least
/// 256 pixels (at most 16x).
fn display_scale(width: u32, height: u32) -> u32 {
    (256 / width.min(height).max(1)).clamp(1, 16)
}

/// The colour of `v` on the error scale [0, max] (viridis; above max saturates).
fn error_colour(v: f32, max: f32) -> [u8; 3] {
    let v = if v.is_finite() { v.max(0.0) } else { max };
    let c = ViridisRGB::get_color_normalized(v.min(max), 0.0, max);
    [c.0, c.1, c.2]
}

/// An error map as a picture: each value coloured on a viridis scale from 0 to `max` (or to
/// the largest finite value), upscaled (nearest) so that the shorter side is at least 256
/// pixels, above a colour bar with its range and `label`.
pub fn error_map_png(
    values: &[f32],
    width: u32,
    height: u32,
    max: Option<f32>,
    label: &str,
) -> Result<Vec<u8>, PlotError> {
    if values.len() != width as usize * height as usize {
        return Err(PlotError::Draw {
            title: label.to_owned(),
            problem: format!("{} values for a {width}x{height} map", values.len()),
        });
    }
    let max = max
        .filter(|m| m.is_finite() && *m > 0.0)
        .unwrap_or_else(|| {
            values
                .iter()
                .copied()
                .filter(|v| v.is_finite())
                .fold(0.0, f32::max)
        })
        .max(1e-12);
    let s = display_scale(width, height);
    let (mw, mh) = (width * s, height * s);
    let bar = 54;
    let cw = mw.max(220);
    let ch = mh + bar;
    let mut buf = canvas(label, cw, ch)?;
    let x_off = (cw - mw) / 2;
    for y in 0..mh {
        for x in 0..mw {
            let v = values[((y / s) * width + x / s) as usize];
            let i = ((y * cw + x + x_off) * 3) as usize;
            buf[i..i + 3].copy_from_slice(&error_colour(v, max));
        }
    }
    // The colour bar: 12 pixels high, 8 from the sides, under the map.
    let (bx0, bx1, by0) = (8, cw - 8, mh + 6);
    for y in by0..by0 + 12 {
        for x in bx0..bx1 {
            let t = (x - bx0) as f32 / (bx1 - bx0 - 1).max(1) as f32;
            let i = ((y * cw + x) * 3) as usize;
            buf[i..i + 3].copy_from_slice(&error_colour(t * max, max));
        }
    }
    {
        let root = BitMapBackend::with_buffer(&mut buf, (cw, ch)).into_drawing_area();
        let draw = || -> Result<(), Box<dyn std::error::Error>> {
            use plotters::style::text_anchor::{HPos, Pos, VPos};
            let style = |h| {
                TextStyle::from((FONT, 14).into_font())
                    .pos(Pos::new(h, VPos::Top))
                    .color(&BLACK)
            };
            let ty = (by0 + 15) as i32;
            root.draw_text("0", &style(HPos::Left), (bx0 as i32, ty))?;
            root.draw_text(
                &format!("≥ {}", format_number(max as f64)),
                &style(HPos::Right),
                (bx1 as i32, ty),
            )?;
            root.draw_text(label, &style(HPos::Center), ((cw / 2) as i32, ty + 16))?;
            root.present()?;
            Ok(())
        };
        draw().map_err(|e| PlotError::Draw {
            title: label.to_owned(),
            problem: e.to_string(),
        })?;
    }
    Ok(encode_rgb8_png(cw, ch, &buf))
}

/// The pixels of `image` inside `rect` (clipped to the image).
pub fn crop(image: &Image, rect: Rect) -> Image {
    let r = clip(rect, image.width, image.height);
    let pixels = (r.y..r.y + r.height)
        .flat_map(|y| (r.x..r.x + r.width).map(move |x| (x, y)))
        .map(|(x, y)| image.at(x, y))
        .collect();
    Image::new(r.width, r.height, pixels)
}

/// The values of a row-major map `width` wide inside `rect` (clipped to the map).
pub fn crop_values(values: &[f32], width: u32, rect: Rect) -> Vec<f32> {
    let height = (values.len() / width.max(1) as usize) as u32;
    let r = clip(rect, width, height);
    (r.y..r.y + r.height)
        .flat_map(|y| {
            let start = (y * width + r.x) as usize;
            values[start..start + r.width as usize].iter().copied()
        })
        .collect()
}

fn clip(rect: Rect, width: u32, height: u32) -> Rect {
    let x = rect.x.min(width);
    let y = rect.y.min(height);
    Rect {
        x,
        y,
        width: rect.width.min(width - x),
        height: rect.height.min(height - y),
    }
}

/// 8-bit sRGB bytes of linear `rgb` times `exposure` (non-finite values as black).
fn srgb8(rgb: glam::Vec3, exposure: f32) -> [u8; 3] {
    (rgb * exposure)
        .to_array()
        .map(|v| linear_to_srgb8(if v.is_finite() { v } else { 0.0 }))
}

/// A crop of `image`, tone-mapped (sRGB after `exposure`) and upscaled `scale` times
/// (nearest neighbour, so that pixels and noise stay visible).
pub fn crop_png(image: &Image, rect: Rect, scale: u32, exposure: f32) -> Vec<u8> {
    let c = crop(image, rect);
    let s = scale.clamp(1, 64);
    let (w, h) = (c.width * s, c.height * s);
    let mut buf = Vec::with_capacity(w as usize * h as usize * 3);
    for y in 0..h {
        for x in 0..w {
            buf.extend(srgb8(c.at(x / s, y / s), exposure));
        }
    }
    encode_rgb8_png(w, h, &buf)
}

/// `image` tone-mapped, with each rectangle outlined in its palette colour (crop `i` in
/// [`PALETTE`]`[i]`), two pixels wide.
pub fn image_with_rects_png(image: &Image, rects: &[Rect], exposure: f32) -> Vec<u8> {
    let (w, h) = (image.width, image.height);
    let mut buf: Vec<u8> = image
        .pixels
        .iter()
        .flat_map(|&p| srgb8(p, exposure))
        .collect();
    for (i, r) in rects.iter().enumerate() {
        let r = clip(*r, w, h);
        let (cr, cg, cb) = PALETTE[i % PALETTE.len()];
        for y in r.y..r.y + r.height {
            for x in r.x..r.x + r.width {
                let edge =
                    x < r.x + 2 || y < r.y + 2 || x + 2 >= r.x + r.width || y + 2 >= r.y + r.height;
                if edge {
                    let k = ((y * w + x) * 3) as usize;
                    buf[k..k + 3].copy_from_slice(&[cr, cg, cb]);
                }
            }
        }
    }
    encode_rgb8_png(w, h, &buf)
}

/// Up to `n` non-overlapping `size` x `size` squares of `reference` with the most detail
/// (the sum of absolute differences between neighbouring pixels of sRGB-encoded luminance):
/// where noise and blur are easiest to judge. Candidates lie on a grid of a quarter of the
/// size; ties go to the earlier candidate (top-left first), so the choice is deterministic.
pub fn pick_crops(reference: &Image, n: usize, size: u32) -> Vec<Rect> {
    let (w, h) = (reference.width, reference.height);
    let size = size.min(w).min(h);
    if size == 0 || n == 0 {
        return Vec::new();
    }
    let lum: Vec<f32> = reference
        .pixels
        .iter()
        .map(|&p| {
            let l = luminance(p);
            if l.is_finite() {
                linear_to_srgb(l.clamp(0.0, 1.0))
            } else {
                0.0
            }
        })
        .collect();
    // Detail per pixel, then a summed-area table for the window sums.
    let at = |x: u32, y: u32| lum[(y * w + x) as usize];
    let mut sat = vec![0f64; (w as usize + 1) * (h as usize + 1)];
    let stride = w as usize + 1;
    for y in 0..h {
        let mut row = 0f64;
        for x in 0..w {
            let mut d = 0.0;
            if x + 1 < w {
                d += (at(x + 1, y) - at(x, y)).abs();
            }
            if y + 1 < h {
                d += (at(x, y + 1) - at(x, y)).abs();
            }
            row += d as f64;
            let i = (y as usize + 1) * stride + x as usize + 1;
            sat[i] = sat[i - stride] + row;
        }
    }
    let window = |x: u32, y: u32| {
        let (x0, y0, x1, y1) = (
            x as usize,
            y as usize,
            (x + size) as usize,
            (y + size) as usize,
        );
        sat[y1 * stride + x1] - sat[y0 * stride + x1] - sat[y1 * stride + x0]
            + sat[y0 * stride + x0]
    };
    let step = (size / 4).max(1);
    let mut candidates = Vec::new();
    let positions = |extent: u32| {
        let mut v: Vec<u32> = (0..=extent - size).step_by(step as usize).collect();
        if *v.last().expect("at least 0") != extent - size {
            v.push(extent - size);
        }
        v
    };
    for y in positions(h) {
        for x in positions(w) {
            candidates.push((window(x, y), x, y));
        }
    }
    // Highest detail first; stable, so ties keep the scan order.
    candidates.sort_by(|a, b| b.0.total_cmp(&a.0));
    let mut picked: Vec<Rect> = Vec::new();
    for (_, x, y) in candidates {
        let r = Rect {
            x,
            y,
            width: size,
            height: size,
        };
        let overlaps = picked.iter().any(|p| {
            r.x < p.x + p.width
                && p.x < r.x + r.width
                && r.y < p.y + p.height
                && p.y < r.y + r.height
        });
        if !overlaps {
            picked.push(r);
            if picked.len() == n {
                break;
            }
        }
    }
    picked
}

#[cfg(test)]
mod tests {
    use super::*;
    fn decode(png: &[u8]) -> (u32, u32, Vec<u8>) {
        let img = image::load_from_memory(png).unwrap().to_rgb8();
        (img.width(), img.height(), img.into_raw())
    }

    #[test]
    fn ticks_are_round_numbers() {
        // 1..256 spp: 2.4 decades, so 1, 2, 5 times powers of ten.
        let t: Vec<String> = log_ticks(0.0, 256f64.log10())
            .iter()
            .map(|t| format_number(10f64.powf(*t)))
            .collect();
        assert_eq!(t, ["1", "2", "5", "10", "20", "50", "100", "200"]);
        // Six decades: powers of ten only.
        let t = log_ticks(-6.2, -0.1);
        assert_eq!(t.len(), 6);
        assert!(t.iter().all(|v| (v - v.round()).abs() < 1e-12));
        // A fifth of a decade (0.16 to 0.26): round linear steps.
        let t: Vec<String> = log_ticks(0.16f64.log10(), 0.26f64.log10())
            .iter()
            .map(|t| format_number(10f64.powf(*t)))
            .collect();
        assert_eq!(t, ["0.16", "0.18", "0.2", "0.22", "0.24", "0.26"]);
        assert_eq!(
            linear_ticks(0.0, 1.0),
            vec![0.0, 0.2, 0.4, 0.6000000000000001, 0.8, 1.0]
        );
        assert_eq!(format_number(0.0001234), "1.23e-4");
        assert_eq!(format_number(0.002793), "2.79e-3");
        assert_eq!(format_number(0.001), "1e-3");
        assert_eq!(format_number(0.25), "0.25");
        assert_eq!(format_number(9.2654), "9.265");
        assert_eq!(format_number(256.0), "256");
        assert_eq!(format_number(1.0e6), "1e6");
        assert_eq!(format_number(-0.5), "-0.5");
    }

    #[test]
    fn charts_are_pngs_of_the_asked_size_with_ink() {
        let series = vec![
            Series {
                name: "a".into(),
                points: vec![(1.0, 1.0), (4.0, 0.25), (16.0, 0.0625), (0.0, 5.0)],
                guide: false,
            },
            Series {
                name: "slope -1".into(),
                points: vec![(1.0, 1.0), (16.0, 1.0 / 16.0)],
                guide: true,
            },
        ];
        let log = Axis {
            label: "x".into(),
            log: true,
        };
        let png = line_chart("t", &log, &log, &series, 400, 300).unwrap();
        let (w, h, px) = decode(&png);
        assert_eq!((w, h), (400, 300));
        // The first series' colour is drawn.
        let (r, g, b) = PALETTE[0];
        assert!(px.chunks(3).any(|c| c == [r, g, b]));
        let png = bar_chart("b", &log, &[("x".into(), 3.0), ("y".into(), 0.5)], 300, 200).unwrap();
        assert_eq!(decode(&png).0, 300);
        let stacks = vec![Stack {
            label: "s".into(),
            parts: vec![("p".into(), 1.0), ("q".into(), 2.0)],
        }];
        let (_, _, px) = decode(&stacked_bar_chart("s", &log, &stacks, 300, 200).unwrap());
        let (r, g, b) = PALETTE[1];
        assert!(px.chunks(3).any(|c| c == [r, g, b]), "second part drawn");
        assert!(line_chart("t", &log, &log, &series, 0, 10).is_err());
        // Empty data still gives a chart.
        assert!(line_chart("t", &log, &log, &[], 200, 100).is_ok());
    }

    #[test]
    fn error_map_colours_values_and_upscales() {
        let values = vec![0.0, 1.0, 2.0, f32::NAN];
        let png = error_map_png(&values, 2, 2, Some(1.0), "err").unwrap();
        let (w, h, px) = decode(&png);
        // 2x2 upscaled 16x to 32x32, centred in a canvas at least 220 wide, plus the bar.
        assert_eq!((w, h), (220, 32 + 54));
        let at = |x: u32, y: u32| {
            let i = ((y * w + x) * 3) as usize;
            [px[i], px[i + 1], px[i + 2]]
        };
        let x0 = (220 - 32) / 2;
        assert_eq!(at(x0, 0), error_colour(0.0, 1.0));
        assert_eq!(at(x0 + 16, 0), error_colour(1.0, 1.0));
        // Above max saturates; NaN shows as max.
        assert_eq!(at(x0, 16), error_colour(1.0, 1.0));
        assert_eq!(at(x0 + 16, 16), error_colour(1.0, 1.0));
        assert_ne!(error_colour(0.0, 1.0), error_colour(1.0, 1.0));
        assert!(error_map_png(&values, 3, 2, None, "err").is_err());
    }
}
