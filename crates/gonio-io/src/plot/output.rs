//! Backends: PNG and SVG files, SVG strings, PNG bytes and RGB buffers in memory.

use std::fs;
use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;

use super::{Drawn, Output, PanelRect, PlotError, PlotErrorKind, SVG_CELL, font};

/// A figure that can draw itself on any backend. `cell` is the side in pixels of the
/// cells rasters are drawn with (1 for bitmaps).
pub(crate) trait Figure {
    /// Draws the whole figure on `root` (already the image's size, not yet filled) and
    /// returns its data regions.
    fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        cell: u32,
    ) -> Result<Vec<PanelRect>, String>;
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Format {
    Png,
    Svg,
}

fn format_of(path: &Path) -> Option<Format> {
    let ext = path.extension()?.to_str()?.to_ascii_lowercase();
    match ext.as_str() {
        "png" => Some(Format::Png),
        "svg" => Some(Format::Svg),
        _ => None,
    }
}

fn draw_on<DB: DrawingBackend, F: Figure>(
    root: DrawingArea<DB, Shift>,
    fig: &F,
    cell: u32,
) -> Result<Vec<PanelRect>, PlotErrorKind> {
    let panels = fig.draw(&root, cell).map_err(PlotErrorKind::Draw)?;
    root.present()
        .map_err(|e| PlotErrorKind::Draw(e.to_string()))?;
    Ok(panels)
}

fn to_file<F: Figure>(
    path: &Path,
    size: (u32, u32),
    fig: &F,
) -> Result<Vec<PanelRect>, PlotErrorKind> {
    match format_of(path) {
        Some(Format::Png) => {
            let (bytes, panels) = to_png_bytes(size, fig)?;
            fs::write(path, bytes).map_err(PlotErrorKind::Io)?;
            Ok(panels)
        }
        Some(Format::Svg) => draw_on(
            SVGBackend::new(path, size).into_drawing_area(),
            fig,
            SVG_CELL,
        ),
        None => Err(PlotErrorKind::Extension),
    }
}

/// Draws `fig` into an RGB buffer of `size`, returning its panels.
fn to_rgb<F: Figure>(
    buf: &mut Vec<u8>,
    size: (u32, u32),
    fig: &F,
) -> Result<Vec<PanelRect>, PlotErrorKind> {
    buf.clear();
    buf.resize(size.0 as usize * size.1 as usize * 3, 0);
    draw_on(
        BitMapBackend::with_buffer(buf, size).into_drawing_area(),
        fig,
        1,
    )
}

/// PNG bytes: the figure drawn into an RGB buffer and encoded by the `png` crate
/// (8-bit RGB, no other chunks), in memory.
fn to_png_bytes<F: Figure>(
    size: (u32, u32),
    fig: &F,
) -> Result<(Vec<u8>, Vec<PanelRect>), PlotErrorKind> {
    let mut rgb = Vec::new();
    let panels = to_rgb(&mut rgb, size, fig)?;
    let mut out = Vec::new();
    let encoding = |e: png::EncodingError| PlotErrorKind::Draw(format!("PNG encoder: {e}"));
    let mut enc = png::Encoder::new(&mut out, size.0, size.1);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    let mut w = enc.write_header().map_err(encoding)?;
    w.write_image_data(&rgb).map_err(encoding)?;
    w.finish().map_err(encoding)?;
    Ok((out, panels))
}

/// Draws `fig` at `size` into `out`.
pub(crate) fn emit<F: Figure>(
    out: Output<'_>,
    size: (u32, u32),
    fig: &F,
) -> Result<Drawn, PlotError> {
    let target = out.target();
    let fail = |kind| PlotError {
        target: target.clone(),
        kind,
    };
    if !font::ensure() {
        return Err(fail(PlotErrorKind::Font));
    }
    let panels = match out {
        Output::File(path) => to_file(path, size, fig),
        Output::Svg(s) => {
            s.clear();
            draw_on(
                SVGBackend::with_string(s, size).into_drawing_area(),
                fig,
                SVG_CELL,
            )
        }
        Output::Png(bytes) => to_png_bytes(size, fig).map(|(b, p)| {
            *bytes = b;
            p
        }),
        Output::Rgb(buf) => to_rgb(buf, size, fig),
    }
    .map_err(fail)?;
    Ok(Drawn { size, panels })
}
