//! The shipped font, registered once with plotters' ab_glyph engine.

use std::sync::OnceLock;

use plotters::style::FontStyle;

/// DejaVu Sans (see `assets/fonts/LICENSE-DejaVu`), embedded in the binary.
static DEJAVU_SANS: &[u8] = include_bytes!("../../../../assets/fonts/DejaVuSans.ttf");

/// DejaVu Sans as TrueType bytes: the font of the plots, for pages that draw their
/// own (the live view serves it).
pub fn dejavu_sans() -> &'static [u8] {
    DEJAVU_SANS
}

/// The family every text of the plots uses. Registered under the generic name, so
/// that an SVG viewer without DejaVu Sans still picks a sans-serif face.
pub(crate) const FAMILY: &str = "sans-serif";

/// Registers the font (once per process); false when ab_glyph refuses it.
pub(crate) fn ensure() -> bool {
    static DONE: OnceLock<bool> = OnceLock::new();
    *DONE.get_or_init(|| {
        let normal = plotters::style::register_font(FAMILY, FontStyle::Normal, DEJAVU_SANS).is_ok();
        // Other styles fall back to Normal in the engine; registering them explicitly
        // keeps that independent of the fallback.
        let bold = plotters::style::register_font(FAMILY, FontStyle::Bold, DEJAVU_SANS).is_ok();
        normal && bold
    })
}
