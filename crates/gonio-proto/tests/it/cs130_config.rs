//! The Cornerstone 130's configuration: its defaults, the grating and order-sorting
//! filter it chooses for a wavelength, its TOML and its validation.

use gonio_proto::cs130::{Cs130Config, OrderFilterSpec, SelectError};

#[test]
fn defaults_validate_and_crossovers_fall_where_documented() {
    let c = Cs130Config::default();
    c.validate().unwrap();
    let f = |nm| c.order_filter_for(nm).unwrap();
    assert_eq!(f(250.0), 1);
    assert_eq!(f(499.9), 1);
    assert_eq!(f(500.0), 2);
    assert_eq!(f(599.9), 2);
    assert_eq!(f(600.0), 3);
    assert_eq!(f(1009.9), 3);
    assert_eq!(f(1010.0), 4);
    assert_eq!(f(1509.9), 4);
    assert_eq!(f(1510.0), 5);
    assert_eq!(f(2000.0), 5);
    assert_eq!(c.grating_for(900.0).unwrap().index, 1);
    assert_eq!(c.grating_for(900.1).unwrap().index, 2);
    assert!(matches!(
        c.grating_for(2000.5),
        Err(SelectError::OutOfRange { .. })
    ));
    assert!(matches!(
        c.grating_for(f64::NAN),
        Err(SelectError::OutOfRange { .. })
    ));
}

#[test]
fn every_chosen_filter_blocks_half_lambda_and_passes_lambda() {
    let c = Cs130Config::default();
    let mut nm = 250.0;
    while nm <= 2000.0 {
        let p = c.order_filter_for(nm).unwrap();
        match c.cut_on_nm(p) {
            None => assert!(nm / 2.0 < c.shortest_nm, "{nm}"),
            Some(cut) => {
                assert!(cut >= nm / 2.0 + c.filter_margin_nm, "{nm}: {cut}");
                assert!(cut <= nm - c.filter_margin_nm, "{nm}: {cut}");
            }
        }
        nm += 0.5;
    }
}

#[test]
fn a_gap_in_the_filters_is_refused() {
    let c = Cs130Config {
        filters: vec![OrderFilterSpec {
            position: 2,
            cut_on_nm: 335.0,
        }],
        ..Cs130Config::default()
    };
    // 335 blocks λ/2 only up to λ = 650.
    assert_eq!(c.order_filter_for(650.0), Ok(2));
    assert_eq!(
        c.order_filter_for(700.0),
        Err(SelectError::NoOrderFilter {
            nm: 700.0,
            low: 360.0,
            high: 690.0
        })
    );
}

#[test]
fn the_documented_toml_parses_and_unknown_keys_are_refused() {
    let text = "auto_order_filter = false\nshortest_nm = 300.0\n\
                [[gratings]]\nindex = 1\nlines_per_mm = 1200\nmin_nm = 250.0\nmax_nm = 900.0\n\
                [[filters]]\nposition = 2\ncut_on_nm = 335.0\n";
    let c: Cs130Config = toml::from_str(text).unwrap();
    c.validate().unwrap();
    assert!(!c.auto_order_filter);
    assert_eq!(c.gratings.len(), 1);
    assert_eq!(c.cut_on_nm(2), Some(335.0));
    assert_eq!(c.timeout_ms, 1000);
    assert!(toml::from_str::<Cs130Config>("speed = 1").is_err());
    assert!(toml::from_str::<Cs130Config>("[[filters]]\nposition = 2\ncut_on = 3.0").is_err());
}

#[test]
fn the_filter_wheel_defaults_to_present_and_without_it_needs_no_auto_filter() {
    // A config written before the field: a wheel, as before.
    let c: Cs130Config = toml::from_str("auto_order_filter = true").unwrap();
    assert!(c.filter_wheel);
    c.validate().unwrap();
    // No wheel: order sorting must be turned off in so many words.
    let c: Cs130Config = toml::from_str("filter_wheel = false").unwrap();
    let e = c.validate().unwrap_err();
    assert_eq!(e.field, "auto_order_filter");
    assert!(e.reason.contains("set auto_order_filter = false"), "{e}");
    let c: Cs130Config = toml::from_str("filter_wheel = false\nauto_order_filter = false").unwrap();
    c.validate().unwrap();
}

#[test]
fn validation_names_the_field() {
    let mut c = Cs130Config::default();
    c.gratings[1].max_nm = 800.0;
    assert_eq!(c.validate().unwrap_err().field, "gratings[1].max_nm");
    let mut c = Cs130Config::default();
    c.filters[0].position = 1;
    assert_eq!(c.validate().unwrap_err().field, "filters[0].position");
    let c = Cs130Config {
        timeout_ms: 0,
        ..Cs130Config::default()
    };
    assert_eq!(c.validate().unwrap_err().field, "timeout_ms");
    let c = Cs130Config {
        shortest_nm: f64::NAN,
        ..Cs130Config::default()
    };
    assert_eq!(c.validate().unwrap_err().field, "shortest_nm");
}
