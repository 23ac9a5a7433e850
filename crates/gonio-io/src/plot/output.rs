//! Backends: PNG and SVG files, SVG strings, PNG bytes and RGB buffers in memory.

use std::fs;
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};

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
        Some(Format::Png) => draw_on(BitMapBackend::new(path, size).into_drawing_area(), fig, 1),
        Some(Format::Svg) => draw_on(
            SVGBackend::new(path, size).into_drawing_area(),
            fig,
            SVG_CELL,
        ),
        None => Err(PlotErrorKind::Extension),
    }
}

/// PNG bytes through the bitmap backend's encoder, which only writes files: the
/// image goes to a fresh private directory under the system's temporary directory,
/// is read back, and the directory is removed.
fn to_png_bytes<F: Figure>(
    size: (u32, u32),
    fig: &F,
) -> Result<(Vec<u8>, Vec<PanelRect>), PlotErrorKind> {
    static SEQ: AtomicU64 = AtomicU64::new(0);
    let base = std::env::temp_dir();
    let mut dir = None;
    for _ in 0..64 {
        let d = base.join(format!(
            "gonio-plot-{}-{}",
            std::process::id(),
            SEQ.fetch_add(1, Ordering::Relaxed)
        ));
        match fs::create_dir(&d) {
            Ok(()) => {
                dir = Some(d);
                break;
            }
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(PlotErrorKind::Io(e)),
        }
    }
    let dir = dir.ok_or_else(|| {
        PlotErrorKind::Io(std::io::Error::new(
            std::io::ErrorKind::AlreadyExists,
            "no free temporary directory name for the PNG encoder",
        ))
    })?;
    let file = dir.join("plot.png");
    let result = to_file(&file, size, fig)
        .and_then(|p| fs::read(&file).map(|b| (b, p)).map_err(PlotErrorKind::Io));
    // Best effort: a leftover empty directory in the temporary directory is harmless.
    let _ = fs::remove_dir_all(&dir);
    result
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
        Output::Rgb(buf) => {
            buf.clear();
            buf.resize(size.0 as usize * size.1 as usize * 3, 0);
            draw_on(
                BitMapBackend::with_buffer(buf, size).into_drawing_area(),
                fig,
                1,
            )
        }
    }
    .map_err(fail)?;
    Ok(Drawn { size, panels })
}
