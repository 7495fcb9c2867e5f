//! What every harness's plots share (plotters, drawn into memory and written as PNG
//! atomically): the bundled font (assets/fonts, DejaVu Sans, Bitstream Vera licence, so plots
//! look the same on every machine), one colour per method, panels, and a legend in a strip
//! beside the panels (never over data), axis label areas wide enough for their text.

use std::path::{Path, PathBuf};
use std::sync::Once;

use plotters::prelude::*;

use crate::encoding::Method;
use crate::error::{Error, Result};

const FONT: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");
const SIZE_PER_PANEL: (u32, u32) = (640, 480);

/// A plot written by [`all`].
#[derive(Clone, Debug)]
pub struct Plot {
    pub title: String,
    pub path: PathBuf,
}

pub(crate) fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // The bundled font is a valid TrueType file; failure would only make text invisible.
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, FONT);
    });
}

/// Method colours in registry order: matplotlib's tab10, with its grey seventh so that the f64
/// reference reads as neutral.
const METHOD_COLOURS: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(127, 127, 127),
    RGBColor(227, 119, 194),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

/// A method's colour in every plot: by its place in the registry.
pub fn colour(m: Method) -> RGBColor {
    let i = Method::ALL.iter().position(|&x| x == m).expect("every method is in the registry");
    METHOD_COLOURS[i % METHOD_COLOURS.len()]
}

/// The colour of the `i`-th scene or device of a plot: tab10's first six, in turn.
pub fn series_colour(i: usize) -> RGBColor {
    METHOD_COLOURS[i % 6]
}

pub fn plot_err(what: &str, e: impl std::fmt::Display) -> Error {
    Error::Usage(format!("drawing the {what} plot: {e}"))
}

/// Room for the x axis's tick labels and description below a chart, pixels.
pub const X_LABEL_AREA: u32 = 60;
/// Room for the y axis's tick labels and description left of a chart, pixels.
pub const Y_LABEL_AREA: u32 = 85;
/// Width of the legend strip right of the panels, pixels.
const LEGEND_WIDTH: u32 = 190;

/// How a legend entry shows its series.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Marker {
    Line,
    Dot,
    Bar,
}

/// One legend entry: a series' label, colour and marker.
#[derive(Clone, Debug)]
pub struct LegendEntry {
    pub label: String,
    pub colour: RGBColor,
    pub marker: Marker,
}

impl LegendEntry {
    pub fn new(label: impl Into<String>, colour: RGBColor, marker: Marker) -> LegendEntry {
        LegendEntry { label: label.into(), colour, marker }
    }
}

/// A panel's chart builder: the caption in `caption_size` points, the margin and the axis
/// label areas every plot has.
pub fn chart_on<'a, 'b>(
    area: &'a DrawingArea<BitMapBackend<'b>, plotters::coord::Shift>,
    caption: &str,
    caption_size: u32,
) -> ChartBuilder<'a, 'b, BitMapBackend<'b>> {
    let mut b = ChartBuilder::on(area);
    b.caption(caption, ("sans-serif", caption_size))
        .margin(12)
        .x_label_area_size(X_LABEL_AREA)
        .y_label_area_size(Y_LABEL_AREA);
    b
}

/// A panel whose x axis is the leaf sizes `leaves` (one segment each, labelled with the size)
/// and whose y axis is `y`, its mesh drawn: the chart of every time-against-leaf-size plot
/// (the study's, the merge's).
pub fn leaf_size_chart<'a, 'b>(
    area: &'a DrawingArea<BitMapBackend<'b>, plotters::coord::Shift>,
    caption: &str,
    leaves: &[u32],
    y: std::ops::Range<f64>,
    y_desc: &str,
    what: &str,
) -> Result<LeafSizeChart<'a, 'b>> {
    let mut chart = chart_on(area, caption, 20)
        // Integer ranges include their end in plotters: n points are 0..n-1.
        .build_cartesian_2d((0u32..leaves.len().saturating_sub(1) as u32).into_segmented(), y)
        .map_err(|e| plot_err(what, e))?;
    chart
        .configure_mesh()
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 15))
        .x_desc("triangles per leaf")
        .y_desc(y_desc)
        .x_label_formatter(&|v| match v {
            SegmentValue::CenterOf(i) => leaves.get(*i as usize).map(|l| l.to_string()).unwrap_or_default(),
            _ => String::new(),
        })
        .draw()
        .map_err(|e| plot_err(what, e))?;
    Ok(chart)
}

/// The chart [`leaf_size_chart`] returns: x a leaf size's index (segmented), y a value.
pub type LeafSizeChart<'a, 'b> = ChartContext<
    'a,
    BitMapBackend<'b>,
    Cartesian2d<
        plotters::coord::ranged1d::SegmentedCoord<plotters::coord::types::RangedCoordu32>,
        plotters::coord::types::RangedCoordf64,
    >,
>;

/// One series on a leaf-size chart: `points` (leaf size index, median, min, max) as a line
/// through the medians with a min-max bar at each.
pub fn line_with_error_bars(
    chart: &mut LeafSizeChart,
    points: &[(u32, f64, f64, f64)],
    c: RGBColor,
    what: &str,
) -> Result<()> {
    chart
        .draw_series(LineSeries::new(points.iter().map(|p| (SegmentValue::CenterOf(p.0), p.1)), c.stroke_width(2)))
        .map_err(|e| plot_err(what, e))?;
    chart
        .draw_series(
            points.iter().map(|p| ErrorBar::new_vertical(SegmentValue::CenterOf(p.0), p.2, p.1, p.3, c.filled(), 6)),
        )
        .map_err(|e| plot_err(what, e))?;
    Ok(())
}

/// A panel whose x axis is the categories `labels` (at 0, 1, ...; a group of bars each) and
/// whose y axis runs from 0 to `ymax`, its mesh drawn: the chart of every grouped bar plot.
pub fn category_chart<'a, 'b>(
    area: &'a DrawingArea<BitMapBackend<'b>, plotters::coord::Shift>,
    caption: &str,
    labels: &[&str],
    ymax: f64,
    y_desc: &str,
    what: &str,
) -> Result<CategoryChart<'a, 'b>> {
    let mut chart = chart_on(area, caption, 20)
        .build_cartesian_2d(-0.5f64..(labels.len() as f64 - 0.5), 0f64..ymax.max(1e-9))
        .map_err(|e| plot_err(what, e))?;
    chart
        .configure_mesh()
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 15))
        .disable_x_mesh()
        .x_labels(labels.len().max(1))
        .x_label_formatter(&|x| {
            let k = x.round();
            if (x - k).abs() < 1e-6 && k >= 0.0 {
                labels.get(k as usize).map(|s| s.to_string()).unwrap_or_default()
            } else {
                String::new()
            }
        })
        .y_desc(y_desc)
        .draw()
        .map_err(|e| plot_err(what, e))?;
    Ok(chart)
}

/// The chart [`category_chart`] returns: x a category's index, y a value.
pub type CategoryChart<'a, 'b> = ChartContext<
    'a,
    BitMapBackend<'b>,
    Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
>;

/// Series `j` of `n` on a category chart: a bar for each category with a value (`values[k]`),
/// in the `j`-th of `n` slots of the category's group.
pub fn bar_series(
    chart: &mut CategoryChart,
    values: &[Option<f64>],
    (j, n): (usize, usize),
    c: RGBColor,
    what: &str,
) -> Result<()> {
    let width = 0.8 / n as f64;
    let bars: Vec<Rectangle<(f64, f64)>> = values
        .iter()
        .enumerate()
        .filter_map(|(k, v)| {
            let x0 = k as f64 - 0.4 + j as f64 * width;
            Some(Rectangle::new([(x0, 0.0), (x0 + width * 0.9, (*v)?)], c.filled()))
        })
        .collect();
    chart.draw_series(bars).map_err(|e| plot_err(what, e))?;
    Ok(())
}

/// Draws `panels` side by side with `draw(area, panel index)` and writes the PNG atomically.
/// The legend (shared by every panel) goes in a strip right of the panels, never over data.
pub fn render_png(
    path: &Path,
    panels: usize,
    what: &str,
    legend: &[LegendEntry],
    mut draw: impl FnMut(&DrawingArea<BitMapBackend, plotters::coord::Shift>, usize) -> Result<()>,
) -> Result<()> {
    register_font();
    let strip = if legend.is_empty() { 0 } else { LEGEND_WIDTH };
    let (pw, h) = (SIZE_PER_PANEL.0 * panels.max(1) as u32, SIZE_PER_PANEL.1);
    let w = pw + strip;
    let mut buf = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| plot_err(what, e))?;
        let (charts, side) = root.split_horizontally(pw);
        for (i, area) in charts.split_evenly((1, panels.max(1))).iter().enumerate() {
            draw(area, i)?;
        }
        if !legend.is_empty() {
            draw_legend(&side, legend, what)?;
        }
        root.present().map_err(|e| plot_err(what, e))?;
    }
    write_png(path, w, h, buf, what)
}

/// Writes an RGB buffer as a PNG, atomically.
pub(crate) fn write_png(path: &Path, w: u32, h: u32, buf: Vec<u8>, what: &str) -> Result<()> {
    crate::io::write_atomic(path, &encode_png(w, h, buf, what)?)
}

/// An RGB buffer as PNG bytes, at the best compression with adaptive filters: a plot's flat
/// colours compress some 6x better than at the encoder's fast default, and plots are committed
/// to a tree that travels to lent GPUs under a size limit.
pub(crate) fn encode_png(w: u32, h: u32, buf: Vec<u8>, what: &str) -> Result<Vec<u8>> {
    use image::codecs::png::{CompressionType, FilterType, PngEncoder};
    assert_eq!(buf.len(), w as usize * h as usize * 3, "buffer sized for the image");
    let mut png = vec![];
    let encoder = PngEncoder::new_with_quality(&mut png, CompressionType::Best, FilterType::Adaptive);
    image::ImageEncoder::write_image(encoder, &buf, w, h, image::ExtendedColorType::Rgb8)
        .map_err(|e| plot_err(what, e))?;
    Ok(png)
}

/// The legend: one row per entry, from the top of `area` (the strip beside the panels).
fn draw_legend(
    area: &DrawingArea<BitMapBackend, plotters::coord::Shift>,
    entries: &[LegendEntry],
    what: &str,
) -> Result<()> {
    let font = ("sans-serif", 15).into_font().color(&BLACK);
    let err = |e| plot_err(what, e);
    for (i, e) in entries.iter().enumerate() {
        let (x, y) = (8, 56 + 26 * i as i32);
        let c = e.colour;
        match e.marker {
            Marker::Line => area.draw(&PathElement::new(vec![(x, y), (x + 26, y)], c.stroke_width(3))),
            Marker::Dot => area.draw(&Circle::new((x + 13, y), 6, c.filled())),
            Marker::Bar => area.draw(&Rectangle::new([(x + 5, y - 7), (x + 21, y + 7)], c.filled())),
        }
        .map_err(err)?;
        area.draw(&Text::new(e.label.clone(), (x + 34, y - 8), font.clone())).map_err(err)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The legend strip lies right of the panels: drawing every panel full of data leaves the
    /// legend's pixels as the legend drew them.
    #[test]
    fn the_legend_never_covers_a_panel() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("p.png");
        let entries = [LegendEntry::new("mt", RGBColor(255, 0, 0), Marker::Bar)];
        render_png(&path, 2, "test", &entries, |area, _| {
            area.fill(&RGBColor(0, 0, 255)).map_err(|e| plot_err("test", e))
        })
        .unwrap();
        let img = image::open(&path).unwrap().to_rgb8();
        assert_eq!(img.width(), 2 * SIZE_PER_PANEL.0 + LEGEND_WIDTH);
        let panels_x = 2 * SIZE_PER_PANEL.0;
        // The panels are all data (blue); the legend's marker (red) is beside them.
        assert!((0..panels_x).all(|x| img.get_pixel(x, 100).0 == [0, 0, 255]));
        assert_eq!(img.get_pixel(panels_x + 8 + 13, 56).0, [255, 0, 0]);
    }
}
