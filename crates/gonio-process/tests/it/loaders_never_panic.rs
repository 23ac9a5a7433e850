//! The readers of this crate — table and sample CSV files, separable and
//! spherical-harmonics files — take any text to a value or a located error, never a
//! panic: arbitrary text, and files written by Gonio with hostile changes
//! (`gonio_core::fuzz::mutate`: a number made `nan`, `inf`, `-0`, `1e308` or a huge
//! integer, a line deleted or repeated, a BOM). What is accepted evaluates.

use std::sync::OnceLock;

use gonio_brdf::Model;
use gonio_core::dirfile::PairDeg;
use gonio_core::fuzz::mutate;
use gonio_core::{Dir, SphericalDeg};
use gonio_process::file::{self, Content};
use gonio_process::separable::SeparableBrdf;
use gonio_process::sh::{ShBrdf, ShOptions};
use gonio_process::{Grid, Samples, Table};
use proptest::prelude::*;

const PAINT: &str = include_str!("../../../../config/models/blue-paint-550nm.toml");

/// Files as Gonio writes them, to damage: a table, samples, a separable file and a
/// spherical-harmonics file, all of the blue paint on a coarse grid.
struct Written {
    table: String,
    samples: String,
    separable: String,
    harmonics: String,
}

fn written() -> &'static Written {
    static W: OnceLock<Written> = OnceLock::new();
    W.get_or_init(|| {
        let paint = Model::from_toml(PAINT, None).expect("paint");
        let t = Table::from_brdf(&paint, Grid::hemisphere(3, 4)).expect("table");
        let pairs: Vec<PairDeg> = [(10.0, 0.0, 20.0, 180.0), (45.0, 30.0, 60.0, 90.0)]
            .iter()
            .map(|&(a, b, c, d)| PairDeg {
                incident: SphericalDeg::new(a, b),
                outgoing: SphericalDeg::new(c, d),
            })
            .collect();
        Written {
            table: file::write_table(&t),
            samples: file::write_samples(&Samples::from_brdf(&paint, &pairs)),
            separable: SeparableBrdf::from_table(&t, 1, false)
                .expect("separable")
                .to_toml(),
            harmonics: ShBrdf::from_table(&t, &ShOptions::new(2))
                .expect("harmonics")
                .to_toml(),
        }
    })
}

fn dirs() -> [(Dir, Dir); 3] {
    let d = |t: f64, p: f64| Dir::from(SphericalDeg::new(t, p));
    [
        (d(0.0, 0.0), d(0.0, 0.0)),
        (d(30.0, 0.0), d(30.0, 180.0)),
        (d(89.0, 45.0), d(60.0, 300.0)),
    ]
}

fn csv(text: &str) -> Result<(), TestCaseError> {
    match file::read(text, None) {
        Ok(Content::Table(t)) => {
            let mut out = vec![0.0; t.channels.len()];
            for (wi, wo) in dirs() {
                t.eval(wi, wo, &mut out);
            }
        }
        Ok(Content::Samples(s)) => {
            prop_assert!(!s.samples.is_empty());
            let _ = s.validate();
        }
        Err(e) => prop_assert!(e.line.is_none_or(|l| l >= 1), "{e}"),
    }
    Ok(())
}

fn separable(text: &str) {
    if let Ok(s) = SeparableBrdf::from_toml(text, None) {
        let mut out = vec![0.0; gonio_brdf::Brdf::channels(&s).len()];
        for (wi, wo) in dirs() {
            s.eval(wi, wo, &mut out);
        }
    }
}

fn harmonics(text: &str) {
    if let Ok(s) = ShBrdf::from_toml(text, None) {
        let mut out = vec![0.0; s.channels.len()];
        for (wi, wo) in dirs() {
            s.eval(wi, wo, &mut out);
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn every_reader_on_any_text(text in any::<String>()) {
        csv(&text)?;
        separable(&text);
        harmonics(&text);
    }

    #[test]
    fn csv_like_text(
        text in "(# (grid|isotropic): [a-z_=0-9:. -]{0,60}\n)?\
                 theta_i,phi_i,theta_o,phi_o(,(value|R|G|B|550nm|sigma_value|sigma_R|flags)){0,4}\n\
                 ([-0-9e.na]{0,4}(,[-0-9e.na]{0,4}){3,6}\n){0,4}",
    ) {
        csv(&text)?;
    }

    #[test]
    fn tables_damaged(seeds in prop::collection::vec(any::<u64>(), 1..4)) {
        csv(&mutate(&written().table, &seeds))?;
    }

    #[test]
    fn samples_damaged(seeds in prop::collection::vec(any::<u64>(), 1..4)) {
        csv(&mutate(&written().samples, &seeds))?;
    }

    #[test]
    fn separable_files_damaged(seeds in prop::collection::vec(any::<u64>(), 1..4)) {
        separable(&mutate(&written().separable, &seeds));
    }

    #[test]
    fn harmonics_files_damaged(seeds in prop::collection::vec(any::<u64>(), 1..4)) {
        harmonics(&mutate(&written().harmonics, &seeds));
    }
}

#[test]
fn every_written_file_reads_with_a_byte_order_mark() {
    let w = written();
    let bom = |t: &str| format!("\u{feff}{t}");
    assert_eq!(
        file::read(&bom(&w.table), None).expect("table"),
        file::read(&w.table, None).expect("table")
    );
    assert_eq!(
        file::read(&bom(&w.samples), None).expect("samples"),
        file::read(&w.samples, None).expect("samples")
    );
    assert_eq!(
        SeparableBrdf::from_toml(&bom(&w.separable), None)
            .expect("separable")
            .to_toml(),
        w.separable
    );
    assert_eq!(
        ShBrdf::from_toml(&bom(&w.harmonics), None)
            .expect("harmonics")
            .to_toml(),
        w.harmonics
    );
}
