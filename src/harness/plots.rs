//! What every harness's plots share (plotters, drawn into memory and written as PNG
//! atomically): the bundled font (assets/fonts, DejaVu Sans, Bitstream Vera licence, so plots
//! look the same on every machine), one colour per method, panels and legends.

use std::path::{Path, PathBuf};
use std::sync::Once;

use plotters::prelude::*;

use crate::encoding::Method;
use crate::error::{Error, Result};

const FONT: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");
const SIZE_PER_PANEL: (u32, u32) = (560, 440);

/// A plot written by [`all`].
#[derive(Clone, Debug)]
pub struct Plot {
    pub title: String,
    pub path: PathBuf,
}

fn register_font() {
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

pub(crate) const SCENE_COLOURS: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
];

pub fn plot_err(what: &str, e: impl std::fmt::Display) -> Error {
    Error::Usage(format!("drawing the {what} plot: {e}"))
}

/// Draws `panels` side by side with `draw(area, panel index)` and writes the PNG atomically.
pub fn render_png(
    path: &Path,
    panels: usize,
    what: &str,
    mut draw: impl FnMut(&DrawingArea<BitMapBackend, plotters::coord::Shift>, usize) -> Result<()>,
) -> Result<()> {
    register_font();
    let (w, h) = (SIZE_PER_PANEL.0 * panels.max(1) as u32, SIZE_PER_PANEL.1);
    let mut buf = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| plot_err(what, e))?;
        for (i, area) in root.split_evenly((1, panels.max(1))).iter().enumerate() {
            draw(area, i)?;
        }
        root.present().map_err(|e| plot_err(what, e))?;
    }
    let img = image::RgbImage::from_raw(w, h, buf).expect("buffer sized for the image");
    let mut png = std::io::Cursor::new(vec![]);
    img.write_to(&mut png, image::ImageFormat::Png).map_err(|e| plot_err(what, e))?;
    crate::io::write_atomic(path, png.get_ref())
}

/// The legend every plot draws, at `pos`.
pub fn legend<'a, DB: DrawingBackend + 'a, CT: plotters::coord::CoordTranslate>(
    chart: &mut ChartContext<'a, DB, CT>,
    pos: SeriesLabelPosition,
    what: &str,
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    chart
        .configure_series_labels()
        .position(pos)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .label_font(("sans-serif", 14))
        .draw()
        .map_err(|e| plot_err(what, e))
}
