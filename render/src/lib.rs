//! Drawing for spindlelab: the figures the engine describes ([`engine::plot::Figure`]) drawn
//! by plotters as SVG or PNG with a bundled font, and the self-contained HTML run report.
//! The engine decides what a plot shows; this crate decides how it looks.

#![forbid(unsafe_code)]

pub mod draw;
pub mod report;

use engine::exec::Manifest;
use engine::plot::{Figure, Layer, PlotError, PlotFormat};
use engine::render::Renderer;
use spindlelab_engine as engine;
use std::sync::Arc;

/// The renderer of the command and the tests: plotters with the bundled font, and the HTML
/// report of [`report::html`].
#[derive(Debug, Clone, Copy, Default)]
pub struct Plotters;

impl Renderer for Plotters {
    fn draw(&self, fig: &Figure, format: PlotFormat) -> Result<Vec<u8>, PlotError> {
        match format {
            PlotFormat::Svg => draw::svg(fig).map(String::into_bytes),
            PlotFormat::Png => draw::png(fig),
        }
    }

    fn report(&self, manifest: &Manifest, recipe_text: Option<&str>, files: &[(String, Vec<u8>)]) -> String {
        report::html(manifest, recipe_text, files)
    }
}

/// The renderer as the run options take it.
pub fn renderer() -> Arc<dyn Renderer> {
    Arc::new(Plotters)
}

/// The figure of `main` with `with` drawn over it, as the bytes of an SVG or PNG file.
pub fn render(
    format: PlotFormat,
    title: &str,
    variant: Option<&str>,
    main: &[Layer],
    with: &[Layer],
) -> Result<Vec<u8>, PlotError> {
    Plotters.draw(&engine::plot::figure(title, variant, main, with)?, format)
}

#[cfg(test)]
mod tests {
    use super::*;
    use engine::value::{Lobes, Value};

    /// The same figure gives the same bytes (SVG and PNG), and the PNG decodes to the size drawn.
    #[test]
    fn plots_are_the_same_bytes_every_time_and_the_png_decodes() {
        let l = Value::Lobes(Lobes::from_rpm(
            &[1000.0, 2000.0, 3000.0],
            vec![1e-3, f64::INFINITY, 2e-3],
            vec![900.0, f64::NAN, 950.0],
        ));
        let fig = engine::plot::figure("lobes", None, &[Layer::new("t", &l)], &[]).unwrap();
        assert_eq!(draw::svg(&fig).unwrap(), draw::svg(&fig).unwrap());
        let png = draw::png(&fig).unwrap();
        assert_eq!(png, draw::png(&fig).unwrap());
        let decoder = png::Decoder::new(std::io::Cursor::new(&png));
        let reader = decoder.read_info().unwrap();
        let info = reader.info();
        assert_eq!((info.width, info.height), (draw::WIDTH, draw::height(&fig)));
    }
}
