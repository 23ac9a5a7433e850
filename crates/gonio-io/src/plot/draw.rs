//! Drawing helpers shared by the plots: text, legends, colours, ticks, rasters.

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use rayon::prelude::*;

use super::font::FAMILY;

/// The drawing area every figure draws on, in pixels from the image's top left.
pub(crate) type Area<DB> = DrawingArea<DB, Shift>;

/// Drawing errors as text (the figure's caller adds the output's name).
pub(crate) fn de<E: std::fmt::Display>(e: E) -> String {
    e.to_string()
}

/// Font sizes and lengths, scaled with the image (1 at 900 × 560 and larger heights).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Sizes {
    /// Scale factor.
    pub s: f64,
    /// Title font size, px.
    pub title: f64,
    /// Axis description font size, px.
    pub label: f64,
    /// Tick label font size, px.
    pub tick: f64,
    /// Legend font size, px.
    pub legend: f64,
}

impl Sizes {
    pub(crate) fn for_area<DB: DrawingBackend>(area: &Area<DB>) -> Sizes {
        let (w, h) = area.dim_in_pixel();
        let s = (w as f64 / 900.0).min(h as f64 / 560.0).clamp(0.5, 4.0);
        Sizes {
            s,
            title: 23.0 * s,
            label: 18.0 * s,
            tick: 15.0 * s,
            legend: 16.0 * s,
        }
    }

    /// `v` design pixels at this scale.
    pub(crate) fn px(&self, v: f64) -> i32 {
        (v * self.s).round() as i32
    }
}

/// Near-black for text and axes.
pub(crate) const INK: RGBColor = RGBColor(20, 20, 20);
/// Grid lines.
pub(crate) const GRID: RGBColor = RGBColor(214, 214, 214);
/// Secondary text.
pub(crate) const MUTED: RGBColor = RGBColor(90, 90, 90);
/// "No data" in colour maps.
pub(crate) const NO_DATA: RGBColor = RGBColor(190, 190, 190);

/// The ten categorical colours of matplotlib's "tab10".
pub(crate) const TAB10: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

/// Categorical colour `i`.
pub(crate) fn series_color(i: usize) -> RGBColor {
    TAB10[i % TAB10.len()]
}

/// Viridis (matplotlib), sampled at t = 0, 0.1, …, 1 and interpolated linearly.
pub(crate) fn viridis(t: f64) -> RGBColor {
    const V: [(f64, f64, f64); 11] = [
        (68.0, 1.0, 84.0),
        (72.0, 36.0, 117.0),
        (65.0, 68.0, 135.0),
        (53.0, 95.0, 141.0),
        (42.0, 120.0, 142.0),
        (33.0, 145.0, 140.0),
        (34.0, 168.0, 132.0),
        (68.0, 191.0, 112.0),
        (122.0, 209.0, 81.0),
        (189.0, 223.0, 38.0),
        (253.0, 231.0, 37.0),
    ];
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) } * 10.0;
    let k = (t.floor() as usize).min(9);
    let f = t - k as f64;
    let (a, b) = (V[k], V[k + 1]);
    let mix = |x: f64, y: f64| (x + (y - x) * f).round().clamp(0.0, 255.0) as u8;
    RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

/// A text style of the shipped font.
pub(crate) fn style(size: f64, color: RGBColor, h: HPos, v: VPos) -> TextStyle<'static> {
    let mut st = TextStyle::from((FAMILY, size).into_font()).pos(Pos::new(h, v));
    st.color = color.to_backend_color();
    st
}

/// Draws `s` anchored at `pos`.
pub(crate) fn text<DB: DrawingBackend>(
    area: &Area<DB>,
    s: &str,
    pos: (i32, i32),
    size: f64,
    color: RGBColor,
    (h, v): (HPos, VPos),
) -> Result<(), String> {
    area.draw(&Text::new(s.to_string(), pos, style(size, color, h, v)))
        .map_err(de)
}

/// Captions a square data panel of side `side` at (`x0`, `y0`) with `name`, centred
/// `cap / 2` above it, and returns the panel's rectangle.
pub(crate) fn caption_square<DB: DrawingBackend>(
    area: &Area<DB>,
    name: &str,
    (x0, y0): (i32, i32),
    side: i32,
    cap: i32,
    size: f64,
    color: RGBColor,
) -> Result<super::PanelRect, String> {
    text(
        area,
        name,
        (x0 + side / 2, y0 - cap / 2),
        size,
        color,
        (HPos::Center, VPos::Center),
    )?;
    Ok(super::PanelRect {
        label: name.to_string(),
        x0,
        y0,
        x1: x0 + side,
        y1: y0 + side,
    })
}

/// Draws `s` rotated a quarter turn counter-clockwise (reading upwards), centred at
/// `pos`.
pub(crate) fn vtext<DB: DrawingBackend>(
    area: &Area<DB>,
    s: &str,
    pos: (i32, i32),
    size: f64,
    color: RGBColor,
) -> Result<(), String> {
    let st = style(size, color, HPos::Center, VPos::Center).transform(FontTransform::Rotate270);
    area.draw(&Text::new(s.to_string(), pos, st)).map_err(de)
}

/// A polyline.
pub(crate) fn line<DB: DrawingBackend>(
    area: &Area<DB>,
    pts: Vec<(i32, i32)>,
    color: RGBColor,
    width: u32,
) -> Result<(), String> {
    area.draw(&PathElement::new(pts, color.stroke_width(width.max(1))))
        .map_err(de)
}

/// A filled circle (a data point), with a thin white rim so that overlapping points
/// stay distinct.
pub(crate) fn dot<DB: DrawingBackend>(
    area: &Area<DB>,
    at: (i32, i32),
    r: i32,
    color: RGBColor,
) -> Result<(), String> {
    area.draw(&Circle::new(at, r.max(2) + 1, WHITE.filled()))
        .map_err(de)?;
    area.draw(&Circle::new(at, r.max(2), color.filled()))
        .map_err(de)
}

/// The light's direction (a ring at `light`) and the mirror direction (a cross at
/// `mirror`), `r` pixels across, each drawn twice — `halo` wide in one colour, then
/// `core` wide in the other — so that they read over any colour map.
pub(crate) fn light_and_mirror<DB: DrawingBackend>(
    area: &Area<DB>,
    light: (i32, i32),
    mirror: (i32, i32),
    r: i32,
    [(halo, halo_w), (core, core_w)]: [(RGBColor, i32); 2],
) -> Result<(), String> {
    let (mx, my) = mirror;
    for (color, width) in [(halo, halo_w), (core, core_w)] {
        let st = color.stroke_width(width.max(1) as u32);
        area.draw(&Circle::new(light, r, st)).map_err(de)?;
        area.draw(&PathElement::new(
            vec![(mx - r, my - r), (mx + r, my + r)],
            st,
        ))
        .map_err(de)?;
        area.draw(&PathElement::new(
            vec![(mx - r, my + r), (mx + r, my - r)],
            st,
        ))
        .map_err(de)?;
    }
    Ok(())
}

/// A filled triangle.
pub(crate) fn triangle<DB: DrawingBackend>(
    area: &Area<DB>,
    pts: [(i32, i32); 3],
    color: RGBColor,
) -> Result<(), String> {
    area.draw(&Polygon::new(pts.to_vec(), color.filled()))
        .map_err(de)
}

/// How a legend entry is marked.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Mark {
    /// A text-only row (a heading).
    Heading,
    /// A line.
    Line(RGBColor),
    /// A point.
    Point(RGBColor),
    /// A line with a point on it.
    LinePoint(RGBColor),
    /// A triangle pointing left (an incident direction).
    Triangle(RGBColor),
}

/// One row of a legend.
#[derive(Clone, Debug)]
pub(crate) struct Entry {
    pub mark: Mark,
    pub text: String,
}

impl Entry {
    pub(crate) fn new(mark: Mark, text: impl Into<String>) -> Entry {
        Entry {
            mark,
            text: text.into(),
        }
    }
}

/// Draws the mark of a legend entry centred at `(mid, cy)`.
fn mark<DB: DrawingBackend>(
    area: &Area<DB>,
    m: Mark,
    (mid, cy): (i32, i32),
    sz: &Sizes,
) -> Result<(), String> {
    let half = sz.px(15.0);
    let (mx0, mx1) = (mid - half, mid + half);
    let lw = sz.px(2.0).max(1) as u32;
    match m {
        Mark::Heading => Ok(()),
        Mark::Line(c) => line(area, vec![(mx0, cy), (mx1, cy)], c, lw),
        Mark::Point(c) => dot(area, (mid, cy), sz.px(4.0), c),
        Mark::LinePoint(c) => {
            line(area, vec![(mx0, cy), (mx1, cy)], c, lw)?;
            dot(area, (mid, cy), sz.px(4.0), c)
        }
        Mark::Triangle(c) => {
            let r = sz.px(6.0);
            triangle(
                area,
                [(mid - r, cy), (mid + r, cy - r), (mid + r, cy + r)],
                c,
            )
        }
    }
}

/// Draws a legend box with its top left at `(x, y)` and the given width; returns its
/// height.
pub(crate) fn legend<DB: DrawingBackend>(
    area: &Area<DB>,
    entries: &[Entry],
    (x, y): (i32, i32),
    width: i32,
    sz: &Sizes,
) -> Result<i32, String> {
    if entries.is_empty() {
        return Ok(0);
    }
    let row = (sz.legend * 1.55).round() as i32;
    let pad = sz.px(8.0);
    let h = row * entries.len() as i32 + 2 * pad;
    area.draw(&Rectangle::new(
        [(x, y), (x + width, y + h)],
        WHITE.filled(),
    ))
    .map_err(de)?;
    area.draw(&Rectangle::new(
        [(x, y), (x + width, y + h)],
        GRID.stroke_width(1),
    ))
    .map_err(de)?;
    let mw = sz.px(30.0);
    for (i, e) in entries.iter().enumerate() {
        let cy = y + pad + row * i as i32 + row / 2;
        mark(area, e.mark, (x + pad + mw / 2, cy), sz)?;
        let (tx, color) = match e.mark {
            Mark::Heading => (x + pad, MUTED),
            _ => (x + pad + mw + sz.px(8.0), INK),
        };
        text(
            area,
            &e.text,
            (tx, cy),
            sz.legend,
            color,
            (HPos::Left, VPos::Center),
        )?;
    }
    Ok(h)
}

/// Draws legend entries in rows, each row centred on `cx`, from `y` down; returns
/// the height taken.
pub(crate) fn legend_rows<DB: DrawingBackend>(
    area: &Area<DB>,
    rows: &[Vec<Entry>],
    (cx, y): (i32, i32),
    sz: &Sizes,
) -> Result<i32, String> {
    let row_h = (sz.legend * 1.6).round() as i32;
    let mw = sz.px(30.0);
    let sep = sz.px(26.0);
    let st = style(sz.legend, INK, HPos::Left, VPos::Center);
    for (r, entries) in rows.iter().enumerate() {
        let widths: Vec<i32> = entries
            .iter()
            .map(|e| {
                let tw = area
                    .estimate_text_size(&e.text, &st)
                    .map(|(w, _)| w as i32)
                    .unwrap_or((e.text.chars().count() as f64 * sz.legend * 0.6) as i32);
                match e.mark {
                    Mark::Heading => tw,
                    _ => mw + sz.px(8.0) + tw,
                }
            })
            .collect();
        let total: i32 = widths.iter().sum::<i32>() + sep * (widths.len() as i32 - 1).max(0);
        let mut x = cx - total / 2;
        let cy = y + r as i32 * row_h + row_h / 2;
        for (e, w) in entries.iter().zip(&widths) {
            match e.mark {
                Mark::Heading => {
                    text(
                        area,
                        &e.text,
                        (x, cy),
                        sz.legend,
                        MUTED,
                        (HPos::Left, VPos::Center),
                    )?;
                }
                m => {
                    mark(area, m, (x + mw / 2, cy), sz)?;
                    text(
                        area,
                        &e.text,
                        (x + mw + sz.px(8.0), cy),
                        sz.legend,
                        INK,
                        (HPos::Left, VPos::Center),
                    )?;
                }
            }
            x += w + sep;
        }
    }
    Ok(row_h * rows.len() as i32)
}

/// A "nice" spacing (1, 2 or 5 × 10^k) giving about `target` intervals over `span`.
pub(crate) fn nice_step(span: f64, target: usize) -> f64 {
    if !(span > 0.0 && span.is_finite()) {
        return 1.0;
    }
    let raw = span / target.max(1) as f64;
    let mag = 10f64.powf(raw.log10().floor());
    let f = raw / mag;
    let nf = if f < 1.5 {
        1.0
    } else if f < 3.0 {
        2.0
    } else if f < 7.0 {
        5.0
    } else {
        10.0
    };
    nf * mag
}

/// A tick value printed with the decimals its spacing needs, with a true minus sign.
pub(crate) fn fmt_tick(v: f64, step: f64) -> String {
    if v.abs() < step.abs() * 1e-9 {
        return "0".into();
    }
    let s = if step < 1e-3 || v.abs() >= 1e5 {
        format!("{v:.1e}")
    } else {
        let d = (-step.log10().floor()).max(0.0) as usize;
        format!("{v:.d$}")
    };
    s.replace('-', "−")
}

/// `m × 10^k` as a short number.
pub(crate) fn fmt_125(m: u32, k: i32) -> String {
    let s = match k {
        -4..=-1 => format!("{:.*}", (-k) as usize, m as f64 * 10f64.powi(k)),
        0..=4 => format!("{}", m as i64 * 10i64.pow(k as u32)),
        _ => format!("{m}e{k}"),
    };
    s.replace('-', "−")
}

/// Degrees for labels, with a true minus sign.
pub(crate) fn fmt_deg(v: f64) -> String {
    let s = if (v - v.round()).abs() < 1e-9 {
        format!("{}°", v.round() as i64)
    } else {
        format!("{v:.1}°")
    };
    s.replace('-', "−")
}

/// The most cells a raster has across its smaller side in vector output.
const MAX_CELLS: i32 = 72;

/// Values sampled over a pixel rectangle, one per cell of `cell × cell` pixels.
pub(crate) struct Cells<T> {
    pub x0: i32,
    pub y0: i32,
    pub w: i32,
    pub h: i32,
    pub cell: i32,
    pub cols: usize,
    pub rows: usize,
    /// Row-major, from the top left.
    pub v: Vec<T>,
}

impl<T: Send> Cells<T> {
    /// Evaluates `f` at the centre of every cell (in image pixel coordinates, y down),
    /// rows in parallel. A `cell` above 1 (vector output) grows so that the smaller
    /// side has at most 72 cells.
    pub(crate) fn sample<F>(rect: (i32, i32, i32, i32), cell: u32, f: F) -> Cells<T>
    where
        F: Fn(f64, f64) -> T + Sync,
    {
        let (x0, y0, w, h) = rect;
        let (w, h) = (w.max(0), h.max(0));
        // Vector output: at most MAX_CELLS cells across the smaller side.
        let cell = if cell > 1 {
            (cell as i32).max((w.min(h) + MAX_CELLS - 1) / MAX_CELLS)
        } else {
            1
        };
        let cols = ((w + cell - 1) / cell) as usize;
        let rows = ((h + cell - 1) / cell) as usize;
        let centre = |k: usize, start: i32, len: i32| {
            let a = start + k as i32 * cell;
            let b = (a + cell).min(start + len);
            0.5 * (a + b) as f64
        };
        let v = (0..rows)
            .into_par_iter()
            .flat_map_iter(|r| {
                let cy = centre(r, y0, h);
                let f = &f;
                (0..cols).map(move |c| f(centre(c, x0, w), cy))
            })
            .collect();
        Cells {
            x0,
            y0,
            w,
            h,
            cell,
            cols,
            rows,
            v,
        }
    }
}

impl<T> Cells<T> {
    /// The same cells with other values.
    pub(crate) fn map<U, F: Fn(&T) -> U>(&self, f: F) -> Cells<U> {
        Cells {
            x0: self.x0,
            y0: self.y0,
            w: self.w,
            h: self.h,
            cell: self.cell,
            cols: self.cols,
            rows: self.rows,
            v: self.v.iter().map(f).collect(),
        }
    }
}

/// Paints coloured cells (`None` is left untouched), merging runs of equal colour
/// along rows into one rectangle each.
pub(crate) fn paint<DB: DrawingBackend>(
    area: &Area<DB>,
    cells: &Cells<Option<RGBColor>>,
) -> Result<(), String> {
    let right = cells.x0 + cells.w;
    let bottom = cells.y0 + cells.h;
    for r in 0..cells.rows {
        let ya = cells.y0 + r as i32 * cells.cell;
        let yb = (ya + cells.cell).min(bottom);
        let row = &cells.v[r * cells.cols..(r + 1) * cells.cols];
        let mut c = 0;
        while c < cells.cols {
            let Some(color) = row[c] else {
                c += 1;
                continue;
            };
            let mut e = c + 1;
            while e < cells.cols && row[e] == Some(color) {
                e += 1;
            }
            let xa = cells.x0 + c as i32 * cells.cell;
            let xb = (cells.x0 + e as i32 * cells.cell).min(right);
            area.draw(&Rectangle::new([(xa, ya), (xb, yb)], color.filled()))
                .map_err(de)?;
            c = e;
        }
    }
    Ok(())
}

/// A layout of `n` panels in a grid over `w × h` pixels maximising the size a panel
/// of aspect `aspect` (width / height) can have: (rows, columns).
pub(crate) fn grid_for(n: usize, w: f64, h: f64, aspect: f64) -> (usize, usize) {
    let n = n.max(1);
    let mut best = (1, n, 0.0);
    for cols in 1..=n {
        let rows = n.div_ceil(cols);
        let (pw, ph) = (w / cols as f64, h / rows as f64);
        let scale = (pw / aspect).min(ph);
        if scale > best.2 {
            best = (rows, cols, scale);
        }
    }
    (best.0, best.1)
}

/// Splits the rectangle `(x, y, w, h)` into `rows × cols` cells, row by row.
pub(crate) fn split(
    (x, y, w, h): (i32, i32, i32, i32),
    rows: usize,
    cols: usize,
    n: usize,
) -> Vec<(i32, i32, i32, i32)> {
    let (cw, ch) = (w / cols.max(1) as i32, h / rows.max(1) as i32);
    (0..n)
        .map(|i| {
            let (r, c) = ((i / cols) as i32, (i % cols) as i32);
            (x + c * cw, y + r * ch, cw, ch)
        })
        .collect()
}

/// Draws the figure's title centred at the top; returns the height it took.
pub(crate) fn title<DB: DrawingBackend>(
    area: &Area<DB>,
    s: &str,
    sz: &Sizes,
) -> Result<i32, String> {
    if s.is_empty() {
        return Ok(sz.px(8.0));
    }
    let (w, _) = area.dim_in_pixel();
    let top = sz.px(10.0);
    text(
        area,
        s,
        (w as i32 / 2, top),
        sz.title,
        INK,
        (HPos::Center, VPos::Top),
    )?;
    Ok(top + (sz.title * 1.6).round() as i32)
}

/// Draws a muted line of text centred under the title at `y`; returns the height taken.
pub(crate) fn subtitle<DB: DrawingBackend>(
    area: &Area<DB>,
    s: &str,
    y: i32,
    sz: &Sizes,
) -> Result<i32, String> {
    let (w, _) = area.dim_in_pixel();
    text(
        area,
        s,
        (w as i32 / 2, y - sz.px(6.0)),
        sz.tick,
        MUTED,
        (HPos::Center, VPos::Top),
    )?;
    Ok((sz.tick * 1.5).round() as i32)
}
