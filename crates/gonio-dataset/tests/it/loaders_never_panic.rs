//! Any bytes given as an `INPUT` are recognised and opened, or refused as bad input
//! naming the file, never a panic: arbitrary bytes, and inputs of every text kind
//! (model, table, samples, long-form samples, ASTM, separable, harmonics) with hostile changes
//! (`gonio_core::fuzz::mutate`: a number made `nan`, `inf`, `-0`, `1e308` or a huge
//! integer, a line deleted or repeated, a BOM). What opens becomes a table and
//! samples, or says why not.

use std::path::Path;
use std::sync::OnceLock;

use gonio_brdf::Model;
use gonio_core::fuzz::mutate;
use gonio_dataset::{Kind, detect, open_bytes};
use gonio_io::formats::{Data, write_astm, write_long};
use gonio_process::separable::SeparableBrdf;
use gonio_process::sh::{ShBrdf, ShOptions};
use gonio_process::{Grid, GridStep, Samples, Table};
use proptest::prelude::*;

const PAINT: &str = include_str!("../../../../config/models/blue-paint-550nm.toml");

/// One input of each text kind, as Gonio writes it.
fn inputs() -> &'static [(Kind, String)] {
    static I: OnceLock<Vec<(Kind, String)>> = OnceLock::new();
    I.get_or_init(|| {
        let paint = Model::from_toml(PAINT, None).expect("paint");
        let table = Table::from_brdf(&paint, Grid::hemisphere(3, 4)).expect("table");
        let mut samples = Samples::from_table(&table);
        samples.samples.truncate(12);
        vec![
            (Kind::Model, PAINT.to_string()),
            (Kind::Csv, gonio_process::file::write_table(&table)),
            (Kind::Csv, gonio_process::file::write_samples(&samples)),
            (
                Kind::Csv,
                write_long(&Data::Samples(samples.clone())).expect("550nm is a wavelength"),
            ),
            (Kind::Astm, write_astm(&samples)),
            (
                Kind::Separable,
                SeparableBrdf::from_table(&table, 1, false)
                    .expect("separable")
                    .to_toml(),
            ),
            (
                Kind::Harmonics,
                ShBrdf::from_table(&table, &ShOptions::new(2))
                    .expect("harmonics")
                    .to_toml(),
            ),
        ]
    })
}

fn open(bytes: &[u8]) -> Result<(), TestCaseError> {
    let path = Path::new("input");
    let _ = detect(bytes);
    match open_bytes(bytes, path) {
        Ok((_, d)) => {
            let step = GridStep::new(30.0, 90.0).expect("step");
            if let Ok(t) = d.to_table(Some(step), path) {
                prop_assert_eq!(&t.channels, d.channels());
            }
            let _ = d.to_samples(50, path);
        }
        Err(e) => {
            prop_assert!(e.is_bad_input(), "{e}");
            prop_assert!(e.to_string().starts_with("input"), "{e}");
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn any_bytes(bytes in prop::collection::vec(any::<u8>(), 0..600)) {
        open(&bytes)?;
    }

    #[test]
    fn any_text(text in any::<String>()) {
        open(text.as_bytes())?;
    }

    #[test]
    fn inputs_damaged(
        k in 0usize..7,
        seeds in prop::collection::vec(any::<u64>(), 1..4),
    ) {
        open(mutate(&inputs()[k].1, &seeds).as_bytes())?;
    }
}

#[test]
fn every_kind_is_recognised_and_opened_with_a_byte_order_mark() {
    for (kind, text) in inputs() {
        let with = format!("\u{feff}{text}");
        assert_eq!(detect(with.as_bytes()), Some(*kind), "{kind:?}");
        let (k, d) = open_bytes(with.as_bytes(), Path::new("bom")).expect("opens");
        let (_, plain) = open_bytes(text.as_bytes(), Path::new("plain")).expect("opens");
        assert_eq!(k, *kind);
        assert_eq!(d.describe(), plain.describe());
        assert_eq!(d.channels(), plain.channels());
    }
}

#[test]
fn a_wrong_csv_header_names_the_columns_expected() {
    let e = open_bytes(
        b"theta_in,phi_in,theta_out,phi_out,value\n0,0,0,0,1\n",
        Path::new("t.csv"),
    )
    .expect_err("refused");
    assert!(e.is_bad_input());
    assert_eq!(
        e.to_string(),
        format!(
            "t.csv:1: not a CSV header Gonio reads: expected the columns {}; found \
             \"theta_in,phi_in,theta_out,phi_out,value\"",
            gonio_process::file::EXPECTED_COLUMNS
        )
    );
    assert!(
        e.to_string()
            .contains("theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg")
    );
}
