//! The long-form spectral CSV: one row per direction pair per wavelength, for
//! spectral data that tools such as pandas, R or a spreadsheet pivot themselves.
//!
//! ```text
//! theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg,wavelength_nm,f_r_per_sr,sigma_per_sr
//! 30,0,30,180,450,0.25,0.002
//! 30,0,30,180,550,0.5,0.003
//! ```
//!
//! # What Gonio writes
//! The header of the wide CSV's direction columns (`gonio_process::file`, format 2:
//! units in the names), then `wavelength_nm`, `f_r_per_sr` (1/sr), `sigma_per_sr`
//! when every sample has uncertainties, and `flags` when any sample has flags (a
//! sample's flags repeat on each of its rows). The rows go sample by sample, and
//! within a sample wavelength by wavelength, increasing. Numbers are written in Rust's
//! shortest round-trip form, so write → read gives back the same `f64`s. A sidecar
//! (`PATH.json`, [`long_meta`]) says what the rows cannot: whether the data are
//! isotropic.
//!
//! Only wavelength channels have a long form: single-band and R/G/B data are refused
//! with an error that points to the wide CSV (`--format csv`), rather than written
//! with a wavelength column that would have to be invented.
//!
//! # What Gonio reads
//! - Before the header: blank lines and `#` lines, skipped. The header: the direction
//!   columns (`theta_i_deg,…` or `theta_i,…`), `wavelength_nm`, then `f_r_per_sr` (or
//!   `value`), then optionally `sigma_per_sr` (or `sigma`), then optionally `flags`.
//! - One row per pair and wavelength, in any order. Rows of the same pair (the four
//!   angles equal as numbers) are one sample. The file's wavelengths are every
//!   wavelength it names, increasing, and every pair must have exactly one row for
//!   each: a missing or repeated one is an error naming the line.
//! - Every field is a finite number; wavelengths are positive; flags are whole numbers
//!   and agree between the rows of a pair.
//!
//! Errors name the file, the line and the column.

use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::Path;

use gonio_core::dirfile::{HEADER, PairDeg};
use gonio_core::{Channels, SphericalDeg};
use gonio_process::file::{DIR_COLUMNS, Meta};
use gonio_process::{Sample, Samples};

use super::{Data, Format, FormatError};

/// The wavelength column (nm).
pub const WAVELENGTH: &str = "wavelength_nm";
/// The value column (1/sr).
pub const VALUE: &str = "f_r_per_sr";
/// The standard uncertainty column (1/sr).
pub const SIGMA: &str = "sigma_per_sr";
/// The flags column.
pub const FLAGS: &str = "flags";

/// The most distinct wavelengths a file may name: far beyond any monochromator scan
/// (a 1 nm step over 200–2500 nm is 2301), and a bound on the memory a hostile file
/// can make the reader reserve per sample.
pub const MAX_WAVELENGTHS: usize = 10_000;

/// The columns Gonio writes: with `sigma_per_sr` and `flags` when asked.
pub fn columns(sigma: bool, flags: bool) -> Vec<String> {
    let mut c: Vec<String> = DIR_COLUMNS.iter().map(|s| s.to_string()).collect();
    c.push(WAVELENGTH.into());
    c.push(VALUE.into());
    if sigma {
        c.push(SIGMA.into());
    }
    if flags {
        c.push(FLAGS.into());
    }
    c
}

/// Whether samples get the `sigma_per_sr` and `flags` columns: σ when every sample
/// has it, flags when any sample has some (as the wide CSV decides).
fn optional_columns(s: &Samples) -> (bool, bool) {
    let sigma = !s.samples.is_empty() && s.samples.iter().all(|x| x.sigma.is_some());
    let flags = s.samples.iter().any(|x| x.flags != 0);
    (sigma, flags)
}

/// The wavelengths of wavelength channels, or the error that says the long form
/// needs them.
fn wavelengths(channels: &Channels) -> Result<&[f64], FormatError> {
    match channels {
        Channels::Wavelengths(w) => Ok(w),
        other => Err(FormatError::whole(
            Some(Format::CsvLong),
            None,
            format!(
                "the long-form CSV has a row per wavelength, and these data have no \
                 wavelengths (channels {other}); write the wide CSV (--format csv) instead"
            ),
        )),
    }
}

/// The data as samples for the long form: samples as they are, a table's nodes, a
/// MERL table's valid bins.
fn samples_of(data: &Data) -> std::borrow::Cow<'_, Samples> {
    match data {
        Data::Samples(s) => std::borrow::Cow::Borrowed(s),
        d => std::borrow::Cow::Owned(d.to_samples()),
    }
}

/// Writes data in the long form (module docs); refuses data whose channels are not
/// wavelengths.
pub fn write_long(data: &Data) -> Result<String, FormatError> {
    let s = samples_of(data);
    let wl = wavelengths(&s.channels)?;
    let (sigma, flags) = optional_columns(&s);
    let mut out = columns(sigma, flags).join(",");
    out.push('\n');
    for x in &s.samples {
        let p = &x.pair;
        for (ch, w) in wl.iter().enumerate() {
            let _ = write!(
                out,
                "{},{},{},{},{w},{}",
                p.incident.theta_deg,
                p.incident.phi_deg,
                p.outgoing.theta_deg,
                p.outgoing.phi_deg,
                x.value[ch]
            );
            if sigma && let Some(sg) = &x.sigma {
                let _ = write!(out, ",{}", sg[ch]);
            }
            if flags {
                let _ = write!(out, ",{}", x.flags);
            }
            out.push('\n');
        }
    }
    Ok(out)
}

/// The sidecar of [`write_long`]'s file: the samples' sidecar (channels, isotropy)
/// with the long form's columns. Fails as [`write_long`] does.
pub fn long_meta(data: &Data) -> Result<Meta, FormatError> {
    let s = samples_of(data);
    wavelengths(&s.channels)?;
    let (sigma, flags) = optional_columns(&s);
    let mut m = Meta::for_samples(&s);
    m.columns = columns(sigma, flags);
    Ok(m)
}

/// Whether a header's fields (trimmed) start like the long form: four direction
/// columns, then `wavelength_nm`.
pub(crate) fn is_long_header(fields: &[&str]) -> bool {
    fields.len() >= 5
        && (fields[..4] == DIR_COLUMNS || fields[..4] == HEADER)
        && fields[4] == WAVELENGTH
}

/// The parsed header: where σ and flags are, if anywhere.
struct Header {
    names: Vec<String>,
    sigma: Option<usize>,
    flags: Option<usize>,
}

fn parse_header(fields: &[&str]) -> Result<Header, String> {
    let expected = format!(
        "expected {},{WAVELENGTH},{VALUE}[,{SIGMA}][,{FLAGS}] (or theta_i,phi_i,theta_o,phi_o \
         and value, sigma)",
        DIR_COLUMNS.join(",")
    );
    if !is_long_header(fields) {
        return Err(expected);
    }
    let rest = &fields[5..];
    let Some((value, rest)) = rest.split_first() else {
        return Err(format!("no value column: {expected}"));
    };
    if *value != VALUE && *value != "value" {
        return Err(format!("column 6 is {value:?}: {expected}"));
    }
    let (mut sigma, mut flags) = (None, None);
    for (k, c) in rest.iter().enumerate() {
        let at = 6 + k;
        match *c {
            SIGMA | "sigma" if sigma.is_none() && flags.is_none() => sigma = Some(at),
            FLAGS if flags.is_none() => flags = Some(at),
            other => return Err(format!("column {} is {other:?}: {expected}", at + 1)),
        }
    }
    Ok(Header {
        names: fields.iter().map(|s| s.to_string()).collect(),
        sigma,
        flags,
    })
}

/// One row, before the rows of a pair are gathered.
struct Row {
    line: usize,
    wavelength: f64,
    value: f64,
    sigma: Option<f64>,
    flags: u32,
}

/// The rows of one pair, in file order.
struct Pair {
    pair: PairDeg,
    rows: Vec<Row>,
}

/// Reads the long form into samples (module docs for what is accepted), with the
/// sidecar `meta` when there is one: its columns must be the header's and its
/// channels the file's wavelengths; it gives the isotropy. `path` only labels
/// errors; a leading byte order mark is ignored.
pub fn read_long(
    text: &str,
    meta: Option<&Meta>,
    path: Option<&Path>,
) -> Result<Data, FormatError> {
    let text = gonio_core::text::strip_bom(text);
    let at = |line: usize, field: Option<&str>, msg: String| {
        FormatError::at_line(Format::CsvLong, path, line, field, msg)
    };
    let mut lines = text.split('\n').enumerate().map(|(i, l)| (i + 1, l.trim()));
    let (hline, header) = loop {
        let Some((ln, l)) = lines.next() else {
            return Err(FormatError::whole(
                Some(Format::CsvLong),
                path,
                "no header row",
            ));
        };
        if l.is_empty() || l.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> = l.split(',').map(str::trim).collect();
        break (
            ln,
            parse_header(&fields).map_err(|e| at(ln, None, format!("header: {e}")))?,
        );
    };
    let width = header.names.len();
    let mut pairs: Vec<Pair> = Vec::new();
    let mut index: HashMap<[u64; 4], usize> = HashMap::new();
    let mut wls: HashMap<u64, usize> = HashMap::new();
    for (ln, l) in lines {
        if l.is_empty() || l.starts_with('#') {
            continue;
        }
        let f: Vec<&str> = l.split(',').map(str::trim).collect();
        if f.len() != width {
            return Err(at(
                ln,
                None,
                format!("{} fields, the header names {width} columns", f.len()),
            ));
        }
        let (a, row) = row(ln, &f, &header, &at)?;
        let wavelength = row.wavelength;
        // +0.0 for −0.0: the same angle, the same pair.
        let key = a.map(|x| (x + 0.0).to_bits());
        let n = wls.len();
        wls.entry(wavelength.to_bits()).or_insert(n);
        if wls.len() > MAX_WAVELENGTHS {
            return Err(at(
                ln,
                Some(WAVELENGTH),
                format!("more than the {MAX_WAVELENGTHS} distinct wavelengths a file may name"),
            ));
        }
        let i = *index.entry(key).or_insert_with(|| {
            pairs.push(Pair {
                pair: PairDeg {
                    incident: SphericalDeg::new(a[0], a[1]),
                    outgoing: SphericalDeg::new(a[2], a[3]),
                },
                rows: Vec::new(),
            });
            pairs.len() - 1
        });
        pairs[i].rows.push(row);
    }
    if pairs.is_empty() {
        return Err(at(hline, None, "no data rows".into()));
    }
    let mut wl: Vec<f64> = wls.keys().map(|b| f64::from_bits(*b)).collect();
    wl.sort_by(f64::total_cmp);
    let channels = Channels::wavelengths(&wl)
        .map_err(|e| FormatError::whole(Some(Format::CsvLong), path, e.to_string()))?;
    let slot: HashMap<u64, usize> = wl
        .iter()
        .enumerate()
        .map(|(i, w)| (w.to_bits(), i))
        .collect();
    let mut samples = Vec::with_capacity(pairs.len());
    for p in pairs {
        samples.push(sample(p, &slot, &wl, header.sigma.is_some(), &at)?);
    }
    let isotropic = match meta {
        Some(m) => sidecar(m, &header, &channels, hline, &at, path)?,
        None => false,
    };
    Ok(Data::Samples(Samples {
        channels,
        samples,
        isotropic,
    }))
}

/// One data row's numbers (on line `ln`): its four angles and the row, the
/// wavelength positive and the flags a whole number.
fn row(
    ln: usize,
    f: &[&str],
    header: &Header,
    at: &impl Fn(usize, Option<&str>, String) -> FormatError,
) -> Result<([f64; 4], Row), FormatError> {
    let num = |k: usize| -> Result<f64, FormatError> {
        f[k].parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| {
                at(
                    ln,
                    Some(&header.names[k]),
                    format!("not a finite number: {:?}", clip(f[k])),
                )
            })
    };
    let a = [num(0)?, num(1)?, num(2)?, num(3)?];
    let wavelength = num(4)?;
    if wavelength <= 0.0 {
        return Err(at(
            ln,
            Some(WAVELENGTH),
            format!("a wavelength must be positive, got {wavelength}"),
        ));
    }
    let flags = match header.flags {
        Some(k) => f[k].parse::<u32>().map_err(|_| {
            at(
                ln,
                Some(FLAGS),
                format!("not a whole number of flags: {:?}", clip(f[k])),
            )
        })?,
        None => 0,
    };
    Ok((
        a,
        Row {
            line: ln,
            wavelength,
            value: num(5)?,
            sigma: header.sigma.map(num).transpose()?,
            flags,
        },
    ))
}

/// One pair's sample from its rows: a row at each of the file's wavelengths `wl`
/// (in the channels' order, `slot` by bits), none twice, all with the pair's flags.
fn sample(
    p: Pair,
    slot: &HashMap<u64, usize>,
    wl: &[f64],
    has_sigma: bool,
    at: &impl Fn(usize, Option<&str>, String) -> FormatError,
) -> Result<Sample, FormatError> {
    let nc = wl.len();
    let first = p.rows[0].line;
    let mut value = vec![f64::NAN; nc];
    let mut sigma = has_sigma.then(|| vec![f64::NAN; nc]);
    let mut line_of = vec![0usize; nc];
    for r in &p.rows {
        // Every wavelength read went into `slot`.
        let Some(&c) = slot.get(&r.wavelength.to_bits()) else {
            continue;
        };
        if line_of[c] != 0 {
            return Err(at(
                r.line,
                Some(WAVELENGTH),
                format!(
                    "a second row for this pair at {} nm (the first is line {})",
                    r.wavelength, line_of[c]
                ),
            ));
        }
        if r.flags != p.rows[0].flags {
            return Err(at(
                r.line,
                Some(FLAGS),
                format!(
                    "flags {} differ from the pair's {} at line {first}: flags belong \
                     to the pair, not to a wavelength",
                    r.flags, p.rows[0].flags
                ),
            ));
        }
        line_of[c] = r.line;
        value[c] = r.value;
        if let (Some(s), Some(v)) = (sigma.as_mut(), r.sigma) {
            s[c] = v;
        }
    }
    if let Some(c) = line_of.iter().position(|l| *l == 0) {
        return Err(at(
            first,
            Some(WAVELENGTH),
            format!(
                "this pair has no row at {} nm: every pair needs one row for each of \
                 the file's {nc} wavelengths",
                wl[c]
            ),
        ));
    }
    Ok(Sample {
        pair: p.pair,
        value,
        sigma,
        flags: p.rows[0].flags,
    })
}

/// Checks the sidecar against the file (the header's columns, the rows'
/// wavelengths) and gives its isotropy.
fn sidecar(
    m: &Meta,
    header: &Header,
    channels: &Channels,
    hline: usize,
    at: &impl Fn(usize, Option<&str>, String) -> FormatError,
    path: Option<&Path>,
) -> Result<bool, FormatError> {
    if m.columns != header.names {
        return Err(at(
            hline,
            None,
            format!(
                "the sidecar names the columns {:?}, the header {:?}: they do not \
                 belong together",
                m.columns.join(","),
                header.names.join(",")
            ),
        ));
    }
    if m.channels != channels.names() {
        return Err(FormatError::whole(
            Some(Format::CsvLong),
            path,
            format!(
                "the sidecar names the channels {}, the rows the wavelengths {channels}",
                m.channels.join(",")
            ),
        ));
    }
    Ok(m.isotropic)
}

/// At most 40 characters of a field, for messages.
fn clip(s: &str) -> String {
    match s.char_indices().nth(40) {
        Some((i, _)) => format!("{}…", &s[..i]),
        None => s.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spectral() -> Samples {
        let pair = |ti: f64, pi: f64, to: f64, po: f64| PairDeg {
            incident: SphericalDeg::new(ti, pi),
            outgoing: SphericalDeg::new(to, po),
        };
        Samples {
            channels: Channels::wavelengths(&[450.0, 532.5, 650.0]).expect("valid"),
            samples: vec![
                Sample {
                    pair: pair(30.0, 0.0, 30.0, 180.0),
                    value: vec![0.1, 0.2 + 0.1, 1e-300],
                    sigma: Some(vec![1e-3, 2.5e-3, 0.0]),
                    flags: 0,
                },
                Sample {
                    pair: pair(30.0, 0.0, 45.5, 170.25),
                    value: vec![std::f64::consts::PI, 0.7, 1.0 / 3.0],
                    sigma: Some(vec![1e-4, 2e-4, 3e-4]),
                    flags: 4,
                },
            ],
            isotropic: true,
        }
    }

    #[test]
    fn writes_one_row_per_pair_per_wavelength() {
        let s = spectral();
        let text = write_long(&Data::Samples(s)).expect("wavelengths");
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(
            lines[0],
            "theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg,wavelength_nm,f_r_per_sr,sigma_per_sr,flags"
        );
        assert_eq!(lines.len(), 1 + 2 * 3);
        assert_eq!(lines[1], "30,0,30,180,450,0.1,0.001,0");
        assert_eq!(lines[2], "30,0,30,180,532.5,0.30000000000000004,0.0025,0");
        assert_eq!(lines[4], "30,0,45.5,170.25,450,3.141592653589793,0.0001,4");
    }

    #[test]
    fn round_trips_bit_exact_with_its_sidecar_in_any_row_order() {
        let s = spectral();
        let data = Data::Samples(s.clone());
        let text = write_long(&data).expect("writes");
        let meta = long_meta(&data).expect("meta");
        let back = read_long(&text, Some(&meta), None).expect("reads");
        assert_eq!(back, data);
        // Rows shuffled (the last first): the same samples, in the order pairs first
        // appear.
        let mut rows: Vec<&str> = text.lines().collect();
        let last = rows.pop().expect("rows");
        rows.insert(1, last);
        let shuffled = rows.join("\n");
        let Data::Samples(b) = read_long(&shuffled, Some(&meta), None).expect("reads") else {
            panic!("samples")
        };
        assert_eq!(b.samples[0], s.samples[1]);
        assert_eq!(b.samples[1], s.samples[0]);
        // Without the sidecar the isotropy is not known.
        let Data::Samples(b) = read_long(&text, None, None).expect("reads") else {
            panic!("samples")
        };
        assert!(!b.isotropic);
        assert_eq!(b.samples, s.samples);
    }

    #[test]
    fn refuses_non_wavelength_channels_and_incomplete_or_repeated_rows() {
        let mut rgb = spectral();
        rgb.channels = Channels::Rgb;
        let e = write_long(&Data::Samples(rgb)).unwrap_err();
        assert!(e.to_string().contains("--format csv"), "{e}");
        let head = "theta_i,phi_i,theta_o,phi_o,wavelength_nm,value\n";
        let missing =
            format!("{head}10,0,10,180,450,0.1\n10,0,10,180,550,0.2\n20,0,20,180,450,0.3\n");
        let e = read_long(&missing, None, None).unwrap_err();
        assert_eq!((e.line, e.field.as_deref()), (Some(4), Some(WAVELENGTH)));
        assert!(e.message.contains("no row at 550 nm"), "{e}");
        let twice = format!("{head}10,0,10,180,450,0.1\n10,0,10,180,450,0.2\n");
        let e = read_long(&twice, None, None).unwrap_err();
        assert_eq!(e.line, Some(3));
        assert!(e.message.contains("first is line 2"), "{e}");
        let bad = format!("{head}10,0,10,180,-450,0.1\n");
        let e = read_long(&bad, None, None).unwrap_err();
        assert_eq!((e.line, e.field.as_deref()), (Some(2), Some(WAVELENGTH)));
        let e = read_long(&format!("{head}10,0,10,180,450,x\n"), None, None).unwrap_err();
        assert_eq!((e.line, e.field.as_deref()), (Some(2), Some("value")));
        let e = read_long(
            "theta_i,phi_i,theta_o,phi_o,wavelength_nm,value,bogus\n",
            None,
            None,
        )
        .unwrap_err();
        assert_eq!(e.line, Some(1));
        assert!(e.message.contains("column 7 is \"bogus\""), "{e}");
    }

    #[test]
    fn hostile_variations_never_panic() {
        let text = write_long(&Data::Samples(spectral())).expect("writes");
        for k in 0..400u64 {
            let v = gonio_core::fuzz::mutate(&text, &[k, k.wrapping_mul(7919) + 1]);
            if let Ok(d) = read_long(&v, None, None) {
                // Whatever reads writes back and reads to the same data.
                let again = write_long(&d).expect("wavelengths");
                assert_eq!(read_long(&again, None, None).expect("reads"), d);
            }
        }
    }
}
