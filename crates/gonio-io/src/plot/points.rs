//! Where an adaptive run's points went: the sample directions on the outgoing
//! hemisphere, one panel per incidence, each point coloured by the stage that chose
//! it (the coarse pass in grey, the later batches on viridis).
//!
//! The projection is azimuthal equidistant: the radius is θo (the centre is the
//! normal, the rim θo = 90°) and the angle is φo, counter-clockwise from the right
//! (the sample's +x), as in the hemisphere maps.

use gonio_core::dirfile::PairDeg;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, VPos};

use super::draw::{self, Area, Entry, GRID, INK, MUTED, Mark, Sizes};
use super::output::Figure;
use super::{PanelRect, PlotErrorKind, PointsOptions, check_size};

/// The coarse pass's colour: a neutral grey, outside the batches' viridis range.
const COARSE: RGBColor = RGBColor(150, 150, 150);
/// The top of the batches' range on viridis: its last tenth (pale yellow) is hard to
/// see on white.
const LAST_T: f64 = 0.85;
/// Colour-bar labels at most.
const MAX_LABELS: usize = 10;

/// The colour of `batch` (0 = the coarse pass) when the run has `batches` batches
/// after it: grey for the coarse pass; viridis from its dark end (batch 1) to
/// [`LAST_T`] (the last batch).
pub(crate) fn colour(batch: usize, batches: usize) -> RGBColor {
    if batch == 0 {
        return COARSE;
    }
    let t = if batches <= 1 {
        0.0
    } else {
        LAST_T * (batch - 1) as f64 / (batches - 1) as f64
    };
    draw::viridis(t)
}

/// The points of one incidence: (batch, θo, φo) in degrees, in drawing order.
struct Panel {
    theta_i: f64,
    phi_i: f64,
    points: Vec<(usize, f64, f64)>,
}

pub(crate) struct PointsFig {
    panels: Vec<Panel>,
    batches: usize,
    title: String,
}

pub(crate) fn build(
    points: &[(usize, PairDeg)],
    batches: usize,
    opts: &PointsOptions,
) -> Result<PointsFig, PlotErrorKind> {
    check_size(opts.size, (360, 240))?;
    if points.is_empty() {
        return Err(PlotErrorKind::Input("no sample points to draw".into()));
    }
    let mut panels: Vec<Panel> = Vec::new();
    for (k, (batch, p)) in points.iter().enumerate() {
        let (ti, pi) = (p.incident.theta_deg, p.incident.phi_deg);
        let (to, po) = (p.outgoing.theta_deg, p.outgoing.phi_deg);
        if !(0.0..90.0).contains(&ti) || !pi.is_finite() {
            return Err(PlotErrorKind::Input(format!(
                "point {}: the incident direction (θi = {ti}°, φi = {pi}°) is not above the \
                 surface",
                k + 1
            )));
        }
        if !(0.0..=90.0).contains(&to) || !po.is_finite() {
            return Err(PlotErrorKind::Input(format!(
                "point {}: the outgoing direction (θo = {to}°, φo = {po}°) is not on the \
                 hemisphere",
                k + 1
            )));
        }
        if *batch > batches {
            return Err(PlotErrorKind::Input(format!(
                "point {}: batch {batch} is past the last batch ({batches})",
                k + 1
            )));
        }
        // Incidences are the plan's own numbers, stored and read back exactly: equal
        // values are the same incidence.
        let at = match panels.iter().position(|q| q.theta_i == ti && q.phi_i == pi) {
            Some(i) => i,
            None => {
                panels.push(Panel {
                    theta_i: ti,
                    phi_i: pi,
                    points: Vec::new(),
                });
                panels.len() - 1
            }
        };
        panels[at].points.push((*batch, to, po));
    }
    panels.sort_by(|a, b| {
        a.theta_i
            .total_cmp(&b.theta_i)
            .then(a.phi_i.total_cmp(&b.phi_i))
    });
    for p in &mut panels {
        // Later stages on top; the order within a stage is kept (stable sort).
        p.points.sort_by_key(|q| q.0);
    }
    let title = opts
        .title
        .clone()
        .unwrap_or_else(|| "Sample directions by the stage that chose them".into());
    Ok(PointsFig {
        panels,
        batches,
        title,
    })
}

impl PointsFig {
    /// One panel: the polar grid, the points, the light and mirror marks.
    fn panel<DB: DrawingBackend>(
        &self,
        area: &Area<DB>,
        p: &Panel,
        (x0, y0, side): (i32, i32, i32),
        sz: &Sizes,
    ) -> Result<(), String> {
        let r = side as f64 / 2.0;
        let (cx, cy) = (x0 as f64 + r, y0 as f64 + r);
        let to_px = |theta: f64, phi: f64| {
            let rho = r * theta / 90.0;
            let a = phi.to_radians();
            (
                (cx + rho * a.cos()).round() as i32,
                (cy - rho * a.sin()).round() as i32,
            )
        };
        let c = (cx.round() as i32, cy.round() as i32);
        area.draw(&Circle::new(
            c,
            r.round() as i32,
            RGBColor(248, 248, 248).filled(),
        ))
        .map_err(draw::de)?;
        for k in 0..8 {
            let phi = 45.0 * k as f64;
            draw::line(area, vec![c, to_px(90.0, phi)], GRID, 1)?;
        }
        for t in [30.0, 60.0] {
            area.draw(&Circle::new(
                c,
                (r * t / 90.0).round() as i32,
                GRID.stroke_width(1),
            ))
            .map_err(draw::de)?;
            // Labelled along φo = 45°, between the spokes' labels.
            let (lx, ly) = to_px(t, 67.5);
            draw::text(
                area,
                &draw::fmt_deg(t),
                (lx, ly),
                sz.tick * 0.8,
                MUTED,
                (HPos::Center, VPos::Center),
            )?;
        }
        area.draw(&Circle::new(
            c,
            r.round() as i32,
            INK.stroke_width(sz.px(1.5).max(1) as u32),
        ))
        .map_err(draw::de)?;
        for (phi, anchor) in [
            (0.0, (HPos::Left, VPos::Center)),
            (90.0, (HPos::Center, VPos::Bottom)),
            (180.0, (HPos::Right, VPos::Center)),
            (270.0, (HPos::Center, VPos::Top)),
        ] {
            let (lx, ly) = to_px(90.0, phi);
            let a = phi.to_radians();
            let off = sz.px(5.0) as f64;
            draw::text(
                area,
                &draw::fmt_deg(phi),
                (
                    lx + (off * a.cos()).round() as i32,
                    ly - (off * a.sin()).round() as i32,
                ),
                sz.tick * 0.85,
                MUTED,
                anchor,
            )?;
        }
        let dot = sz.px(3.5);
        for &(batch, theta, phi) in &p.points {
            draw::dot(area, to_px(theta, phi), dot, colour(batch, self.batches))?;
        }
        // The light (retro-reflection) and the mirror direction, as the hemisphere
        // maps mark them, over the points.
        let m = sz.px(6.0);
        let (lx, ly) = to_px(p.theta_i, p.phi_i);
        let (mx, my) = to_px(p.theta_i, p.phi_i + 180.0);
        draw::light_and_mirror(
            area,
            (lx, ly),
            (mx, my),
            m,
            [(WHITE, sz.px(4.0)), (INK, sz.px(2.0))],
        )
    }

    /// The batches' colour bar: one band a batch, batch 1 at the bottom.
    fn colour_bar<DB: DrawingBackend>(
        &self,
        area: &Area<DB>,
        (bx, by, bh): (i32, i32, i32),
        sz: &Sizes,
    ) -> Result<(), String> {
        let n = self.batches;
        let bw = sz.px(22.0);
        let band = bh as f64 / n as f64;
        let every = n.div_ceil(MAX_LABELS);
        for b in 1..=n {
            let ya = by + (bh as f64 - band * b as f64).round() as i32;
            let yb = by + (bh as f64 - band * (b - 1) as f64).round() as i32;
            area.draw(&Rectangle::new(
                [(bx, ya), (bx + bw, yb)],
                colour(b, n).filled(),
            ))
            .map_err(draw::de)?;
            if (b - 1) % every == 0 || b == n {
                let ty = (ya + yb) / 2;
                draw::line(
                    area,
                    vec![(bx + bw, ty), (bx + bw + sz.px(5.0), ty)],
                    INK,
                    1,
                )?;
                draw::text(
                    area,
                    &b.to_string(),
                    (bx + bw + sz.px(8.0), ty),
                    sz.tick,
                    INK,
                    (HPos::Left, VPos::Center),
                )?;
            }
        }
        area.draw(&Rectangle::new(
            [(bx, by), (bx + bw, by + bh)],
            INK.stroke_width(1),
        ))
        .map_err(draw::de)?;
        draw::vtext(
            area,
            "batch",
            (bx + bw + sz.px(50.0), by + bh / 2),
            sz.label,
            INK,
        )
    }
}

impl Figure for PointsFig {
    fn draw<DB: DrawingBackend>(
        &self,
        root: &Area<DB>,
        _cell: u32,
    ) -> Result<Vec<PanelRect>, String> {
        root.fill(&WHITE).map_err(draw::de)?;
        let sz = Sizes::for_area(root);
        let (w, h) = root.dim_in_pixel();
        let (w, h) = (w as i32, h as i32);
        let mut top = draw::title(root, &self.title, &sz)?;
        top += draw::subtitle(
            root,
            "radius ∝ θo (the rim is θo = 90°), angle φo counter-clockwise from the sample's +x",
            top,
            &sz,
        )?;
        let cbw = if self.batches > 0 { sz.px(100.0) } else { 0 };
        let foot = (sz.legend * 1.6).round() as i32 + sz.px(8.0);
        let cap = (sz.label * 1.7).round() as i32;
        // Room for the azimuth labels around each disk.
        let lab = sz.px(34.0);
        let (ax, aw) = (sz.px(6.0), w - cbw - sz.px(12.0));
        let ah = h - top - foot;
        // The layout that gives the disks the largest side.
        let n = self.panels.len();
        let side_of = |rows: usize, cols: usize| {
            (aw / cols as i32 - 2 * lab).min(ah / rows as i32 - cap - 2 * lab)
        };
        let (rows, cols) = (1..=n)
            .map(|cols| (n.div_ceil(cols), cols))
            .max_by_key(|&(r, c)| (side_of(r, c), std::cmp::Reverse(c)))
            .unwrap_or((1, 1));
        let cells = draw::split((ax, top, aw, ah), rows, cols, self.panels.len());
        let side = cells
            .first()
            .map_or(0, |&(_, _, cw, ch)| (cw - 2 * lab).min(ch - cap - 2 * lab));
        if side < 60 {
            return Err("the image is too small for the sample directions".into());
        }
        let mut out = Vec::new();
        for (p, &(x, y, cw, ch)) in self.panels.iter().zip(&cells) {
            let x0 = x + (cw - side) / 2;
            let y0 = y + cap + lab + (ch - cap - 2 * lab - side) / 2;
            self.panel(root, p, (x0, y0, side), &sz)?;
            let name = format!(
                "θi = {}, φi = {}: {} points",
                draw::fmt_deg(p.theta_i),
                draw::fmt_deg(p.phi_i),
                p.points.len()
            );
            out.push(draw::caption_square(
                root,
                &name,
                (x0, y0 - lab),
                side,
                cap,
                sz.label,
                INK,
            )?);
            // The panel's rectangle is the disk, not its labels' margin.
            if let Some(last) = out.last_mut() {
                last.y0 = y0;
                last.y1 = y0 + side;
            }
        }
        if self.batches > 0 {
            let by = top + cap;
            self.colour_bar(
                root,
                (
                    w - cbw + sz.px(4.0),
                    by,
                    (h - foot - by - sz.px(10.0)).max(20),
                ),
                &sz,
            )?;
        }
        let mut legend = vec![Entry::new(Mark::Point(COARSE), "coarse pass")];
        if self.batches > 0 {
            legend.push(Entry::new(
                Mark::Heading,
                format!(
                    "batches 1–{} (colour bar){}",
                    self.batches,
                    if self.batches == 1 {
                        ""
                    } else {
                        ": later is lighter"
                    }
                ),
            ));
        }
        legend.push(Entry::new(Mark::Heading, "○ towards the light"));
        legend.push(Entry::new(Mark::Heading, "× mirror direction"));
        draw::legend_rows(root, &[legend], (w / 2, h - foot), &sz)?;
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plot::{Output, sample_points};
    use gonio_core::SphericalDeg;

    fn pair(ti: f64, to: f64, po: f64) -> PairDeg {
        PairDeg {
            incident: SphericalDeg::new(ti, 0.0),
            outgoing: SphericalDeg::new(to, po),
        }
    }

    fn rgb(c: RGBColor) -> [u8; 3] {
        [c.0, c.1, c.2]
    }

    /// Each point is drawn in its batch's colour where the projection puts it (radius
    /// θo / 90° of the disk's, angle φo from the right, counter-clockwise), one panel
    /// per incidence, and the mirror direction is marked over the points.
    #[test]
    fn points_sit_at_their_directions_in_their_batch_colour() {
        let points = vec![
            (0, pair(30.0, 45.0, 90.0)),
            (0, pair(30.0, 30.0, 200.0)),
            (1, pair(30.0, 60.0, 270.0)),
            (2, pair(30.0, 90.0, 0.0)),
            (2, pair(60.0, 45.0, 90.0)),
            (1, pair(60.0, 60.0, 225.0)),
        ];
        let mut buf = Vec::new();
        let drawn =
            sample_points(Output::Rgb(&mut buf), &points, 2, &PointsOptions::default()).unwrap();
        assert_eq!(drawn.panels.len(), 2);
        assert_eq!(drawn.panels[0].label, "θi = 30°, φi = 0°: 4 points");
        assert_eq!(drawn.panels[1].label, "θi = 60°, φi = 0°: 2 points");
        let w = drawn.size.0 as usize;
        let at = |x: i32, y: i32| {
            let i = (y as usize * w + x as usize) * 3;
            [buf[i], buf[i + 1], buf[i + 2]]
        };
        let place = |p: &PanelRect, theta: f64, phi: f64| {
            let r = (p.x1 - p.x0) as f64 / 2.0;
            assert_eq!(p.x1 - p.x0, p.y1 - p.y0, "a disk's square");
            let (cx, cy) = (p.x0 as f64 + r, p.y0 as f64 + r);
            let a = phi.to_radians();
            (
                (cx + r * theta / 90.0 * a.cos()).round() as i32,
                (cy - r * theta / 90.0 * a.sin()).round() as i32,
            )
        };
        let (a, b) = (&drawn.panels[0], &drawn.panels[1]);
        let expect = [
            (a, 45.0, 90.0, 0),
            (a, 30.0, 200.0, 0),
            (a, 60.0, 270.0, 1),
            (a, 90.0, 0.0, 2),
            (b, 45.0, 90.0, 2),
            (b, 60.0, 225.0, 1),
        ];
        for (p, theta, phi, batch) in expect {
            let (x, y) = place(p, theta, phi);
            assert_eq!(
                at(x, y),
                rgb(colour(batch, 2)),
                "{} θo {theta} φo {phi}",
                p.label
            );
        }
        // Where no point, spoke or circle is: the disk's background.
        let (x, y) = place(a, 15.0, 22.5);
        assert_eq!(at(x, y), [248, 248, 248]);
        // The mirror direction (θo = θi, φo = φi + 180°) is marked in ink at its centre.
        for (p, ti) in [(a, 30.0), (b, 60.0)] {
            let (x, y) = place(p, ti, 180.0);
            assert_eq!(at(x, y), rgb(INK), "{}", p.label);
        }
    }

    #[test]
    fn the_coarse_pass_is_apart_from_every_batch_and_batches_are_ordered() {
        for n in 1..=12 {
            let cs: Vec<RGBColor> = (0..=n).map(|b| colour(b, n)).collect();
            for (i, c) in cs.iter().enumerate() {
                for d in &cs[i + 1..] {
                    assert_ne!(rgb(*c), rgb(*d), "{n} batches");
                }
            }
            assert_eq!(rgb(cs[1]), rgb(draw::viridis(0.0)));
            if n > 1 {
                assert_eq!(rgb(cs[n]), rgb(draw::viridis(LAST_T)));
            }
        }
        // Viridis grows lighter along its length: later batches are lighter.
        let luma = |c: RGBColor| 0.2126 * c.0 as f64 + 0.7152 * c.1 as f64 + 0.0722 * c.2 as f64;
        for b in 1..8 {
            assert!(luma(colour(b + 1, 8)) > luma(colour(b, 8)));
        }
    }

    #[test]
    fn bad_points_are_refused_by_name() {
        let mut s = String::new();
        let e = sample_points(Output::Svg(&mut s), &[], 0, &PointsOptions::default()).unwrap_err();
        assert!(
            e.is_input() && e.to_string().contains("no sample points"),
            "{e}"
        );
        let e = sample_points(
            Output::Svg(&mut s),
            &[(0, pair(30.0, 10.0, 0.0)), (3, pair(30.0, 20.0, 0.0))],
            2,
            &PointsOptions::default(),
        )
        .unwrap_err();
        assert!(
            e.to_string()
                .contains("point 2: batch 3 is past the last batch (2)"),
            "{e}"
        );
        let e = sample_points(
            Output::Svg(&mut s),
            &[(0, pair(30.0, 95.0, 0.0))],
            0,
            &PointsOptions::default(),
        )
        .unwrap_err();
        assert!(e.to_string().contains("θo = 95°"), "{e}");
        let e = sample_points(
            Output::Svg(&mut s),
            &[(0, pair(f64::NAN, 5.0, 0.0))],
            0,
            &PointsOptions::default(),
        )
        .unwrap_err();
        assert!(
            e.to_string().contains("point 1: the incident direction"),
            "{e}"
        );
    }

    /// In SVG every point is one filled circle of its batch's colour (the coarse
    /// pass's colour once more for its legend mark; the batches' colour bar is made
    /// of rectangles).
    #[test]
    fn svg_has_one_circle_a_point() {
        let mut points = Vec::new();
        for k in 0..20 {
            let batch = k % 4;
            let ti = if k % 2 == 0 { 30.0 } else { 60.0 };
            points.push((batch, pair(ti, 4.0 * k as f64, 37.0 * k as f64)));
        }
        let mut s = String::new();
        sample_points(Output::Svg(&mut s), &points, 3, &PointsOptions::default()).unwrap();
        for b in 0..=3 {
            let c = colour(b, 3);
            let fill = format!("fill=\"#{:02X}{:02X}{:02X}\"", c.0, c.1, c.2);
            let circles = s
                .lines()
                .flat_map(|l| l.split("<circle").skip(1))
                .filter(|t| t.split("/>").next().is_some_and(|t| t.contains(&fill)))
                .count();
            let want = points.iter().filter(|p| p.0 == b).count() + usize::from(b == 0);
            assert_eq!(circles, want, "batch {b} ({fill})");
        }
        assert!(s.contains("θi = 30°, φi = 0°: 10 points"));
        assert!(s.contains("θi = 60°, φi = 0°: 10 points"));
    }
}
