//! Writing tables and samples as CSV, numbers in Rust's shortest round-trip form.

use std::fmt::Write as _;

use super::{columns, deg, sample_columns};
use crate::{Axis, Grid, Samples, Table};

fn axis_text(a: &Axis) -> String {
    format!("{}:{}:{}", deg(a.start), deg(a.step), a.n)
}

/// The grid line of format 1 (`# grid: …`), for tests and messages.
pub fn grid_line(g: &Grid) -> String {
    format!(
        "isotropic={} phi_i={} theta_i={} phi_o={} theta_o={}",
        g.isotropic,
        axis_text(&g.phi_i),
        axis_text(&g.theta_i),
        axis_text(&g.phi_o),
        axis_text(&g.theta_o)
    )
}

/// Writes a table as text that needs no sidecar: [`write_table`] below the grid
/// line of format 1 (`# grid: …`, which the reader still takes). For tables kept
/// where no file can sit beside them, such as the sample text a run file stores.
/// pandas reads it with `comment="#"`.
pub fn write_table_self_contained(t: &Table) -> String {
    format!("# grid: {}\n{}", grid_line(&t.grid), write_table(t))
}

/// Writes samples: the header row, then one row a sample. [`Meta::for_samples`](super::Meta::for_samples) is
/// its sidecar.
pub fn write_samples(s: &Samples) -> String {
    let (sigma, flags) = sample_columns(s);
    let mut out = columns(&s.channels, sigma, flags).join(",");
    out.push('\n');
    for x in &s.samples {
        let p = &x.pair;
        let _ = write!(
            out,
            "{},{},{},{}",
            p.incident.theta_deg, p.incident.phi_deg, p.outgoing.theta_deg, p.outgoing.phi_deg
        );
        for v in &x.value {
            let _ = write!(out, ",{v}");
        }
        if sigma && let Some(sg) = &x.sigma {
            for v in sg {
                let _ = write!(out, ",{v}");
            }
        }
        if flags {
            let _ = write!(out, ",{}", x.flags);
        }
        out.push('\n');
    }
    out
}

/// Writes a table, the header row then one row a node in grid order.
/// [`Meta::for_table`](super::Meta::for_table) is its sidecar, which carries the grid.
pub fn write_table(t: &Table) -> String {
    let n = t.grid.len();
    let nc = t.channels.len();
    // ~20 bytes a number: one allocation for the whole text.
    let width = 4 + nc * (1 + usize::from(t.sigma.is_some()));
    let mut out = String::with_capacity(n.saturating_mul(width * 20).min(1 << 32));
    out.push_str(&columns(&t.channels, t.sigma.is_some(), false).join(","));
    out.push('\n');
    for i in 0..n {
        let [pi, ti, po, to] = t.grid.angles(i);
        let _ = write!(out, "{},{},{},{}", deg(ti), deg(pi), deg(to), deg(po));
        for ch in 0..nc {
            let _ = write!(out, ",{}", t.values[ch * n + i]);
        }
        if let Some(s) = &t.sigma {
            for ch in 0..nc {
                let _ = write!(out, ",{}", s[ch * n + i]);
            }
        }
        out.push('\n');
    }
    out
}
