//! The CIE tables shipped in `crates/gonio-core/data/cie/` (their sources are named in
//! that folder's README), compiled into the crate and parsed once.

use std::sync::OnceLock;

use super::{Illuminant, Observer};

/// First wavelength of the working grid (nm): the first row of the CIE 1 nm
/// colour-matching function tables.
pub(crate) const GRID_FIRST_NM: usize = 360;
/// Last wavelength of the working grid (nm).
pub(crate) const GRID_LAST_NM: usize = 830;
/// Points of the 1 nm working grid, 360–830 nm.
pub(crate) const GRID_LEN: usize = GRID_LAST_NM - GRID_FIRST_NM + 1;

const CMF_1931: &str = include_str!("../../data/cie/cmf_1931_2deg.csv");
const CMF_1964: &str = include_str!("../../data/cie/cmf_1964_10deg.csv");
const D65: &str = include_str!("../../data/cie/illuminant_d65.csv");
const D50: &str = include_str!("../../data/cie/illuminant_d50.csv");
/// The CIE's tabulated illuminant A, used only to check [`illuminant_a`] against.
#[cfg(test)]
pub(crate) const A_TABLE: &str = include_str!("../../data/cie/illuminant_a.csv");

/// The parsed tables, on the 1 nm grid 360–830 nm.
pub(crate) struct Tables {
    pub cmf_1931: Vec<[f64; 3]>,
    pub cmf_1964: Vec<[f64; 3]>,
    pub d65: Vec<f64>,
    pub d50: Vec<f64>,
}

/// The tables, parsed on first use.
///
/// The text is compiled into the crate, so parsing either always succeeds or always
/// fails for a given build; the unit test `the_shipped_tables_parse` parses these same
/// bytes, so a failure here is a packaging defect caught before release, not bad input.
pub(crate) fn tables() -> &'static Tables {
    static TABLES: OnceLock<Tables> = OnceLock::new();
    TABLES.get_or_init(|| {
        #[allow(clippy::expect_used)]
        parse_all().expect("the CIE tables compiled into gonio-core parse (unit-tested)")
    })
}

pub(crate) fn parse_all() -> Result<Tables, String> {
    Ok(Tables {
        cmf_1931: cmf_on_grid("cmf_1931_2deg.csv", CMF_1931)?,
        cmf_1964: cmf_on_grid("cmf_1964_10deg.csv", CMF_1964)?,
        d65: spd_on_grid("illuminant_d65.csv", D65)?,
        d50: spd_on_grid("illuminant_d50.csv", D50)?,
    })
}

/// The rows of a shipped CSV table: a header line, then `wavelength,v1,…,vN`.
pub(crate) fn parse_rows<const N: usize>(
    name: &str,
    text: &str,
) -> Result<Vec<(f64, [f64; N])>, String> {
    let mut rows = Vec::new();
    for (i, line) in text.lines().enumerate().skip(1) {
        let line = line.trim();
        if line.is_empty() {
            continue;
        }
        let mut fields = line.split(',');
        let mut num = || -> Result<f64, String> {
            let f = fields
                .next()
                .ok_or_else(|| format!("{name}:{}: too few fields", i + 1))?;
            f.trim()
                .parse::<f64>()
                .map_err(|e| format!("{name}:{}: {f:?}: {e}", i + 1))
        };
        let w = num()?;
        let mut v = [0.0; N];
        for x in &mut v {
            *x = num()?;
        }
        rows.push((w, v));
    }
    Ok(rows)
}

/// A colour-matching function table, which must hold exactly 360, 361, …, 830 nm.
fn cmf_on_grid(name: &str, text: &str) -> Result<Vec<[f64; 3]>, String> {
    let rows = parse_rows::<3>(name, text)?;
    if rows.len() != GRID_LEN
        || rows
            .iter()
            .enumerate()
            .any(|(i, (w, _))| *w != (GRID_FIRST_NM + i) as f64)
    {
        return Err(format!("{name}: not the 1 nm grid 360–830 nm"));
    }
    Ok(rows.into_iter().map(|(_, v)| v).collect())
}

/// A relative spectral power distribution on the 1 nm grid: linear interpolation
/// between the table's rows, and the end row's value beyond them (the D50 table ends at
/// 780 nm; see `docs/colour.md`).
fn spd_on_grid(name: &str, text: &str) -> Result<Vec<f64>, String> {
    let rows = parse_rows::<1>(name, text)?;
    let w: Vec<f64> = rows.iter().map(|r| r.0).collect();
    let v: Vec<f64> = rows.iter().map(|r| r.1[0]).collect();
    if w.len() < 2 || w.windows(2).any(|p| p[0] >= p[1]) {
        return Err(format!("{name}: wavelengths not increasing"));
    }
    Ok((0..GRID_LEN)
        .map(|i| linear_at(&w, &v, (GRID_FIRST_NM + i) as f64))
        .collect())
}

/// Linear interpolation in `(w, v)` at `x`, the end value beyond either end. `w` is
/// strictly increasing and not empty.
pub(crate) fn linear_at(w: &[f64], v: &[f64], x: f64) -> f64 {
    let n = w.len();
    if x <= w[0] {
        return v[0];
    }
    if x >= w[n - 1] {
        return v[n - 1];
    }
    // The first node above x: 1..n-1 because of the checks above.
    let j = w.partition_point(|&wj| wj <= x);
    let (w0, w1) = (w[j - 1], w[j]);
    let t = (x - w0) / (w1 - w0);
    v[j - 1] + t * (v[j] - v[j - 1])
}

/// CIE standard illuminant A at `wavelength_nm`, from its definition (ISO 11664-2 /
/// CIE S 014-2; CIE 015:2018 §3.1, section number **UNCONFIRMED**):
/// `S_A(λ) = 100 · (560/λ)⁵ · (exp(c₂/(T·560 nm)) − 1) / (exp(c₂/(T·λ)) − 1)` with the
/// CIE's fixed `c₂ = 1.435 × 10⁻² m·K` and `T = 2848 K` (the same curve as 2856 K on
/// the ITS-68 value of c₂, 1.4388 × 10⁻², to the 4 figures the temperature is given;
/// the fixed pair is what reproduces the CIE's table, to its 6 figures).
pub fn illuminant_a(wavelength_nm: f64) -> f64 {
    const C2_NM_K: f64 = 1.435e7;
    const T_K: f64 = 2848.0;
    let l = wavelength_nm;
    100.0 * (560.0 / l).powi(5) * ((C2_NM_K / (T_K * 560.0)).exp() - 1.0)
        / ((C2_NM_K / (T_K * l)).exp() - 1.0)
}

/// The colour-matching functions of an observer on the 1 nm grid.
pub(crate) fn cmf(observer: Observer) -> &'static [[f64; 3]] {
    let t = tables();
    match observer {
        Observer::Cie1931 => &t.cmf_1931,
        Observer::Cie1964 => &t.cmf_1964,
    }
}

/// The relative spectral power of an illuminant at grid point `i` (360 + i nm).
pub(crate) fn spd(illuminant: Illuminant, i: usize) -> f64 {
    match illuminant {
        Illuminant::D65 => tables().d65[i],
        Illuminant::D50 => tables().d50[i],
        Illuminant::A => illuminant_a((GRID_FIRST_NM + i) as f64),
        Illuminant::E => 1.0,
    }
}
