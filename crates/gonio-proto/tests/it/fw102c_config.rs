//! The FW102C's configuration: a wheel's TOML, the lookups that pick a filter, and
//! its validation.

use gonio_proto::fw102c::{Filter, Fw102cConfig, Speed};

fn parse(text: &str) -> Result<Fw102cConfig, String> {
    toml::from_str::<Fw102cConfig>(text).map_err(|e| e.to_string())
}

const WHEEL: &str = r#"
        positions = 6
        [[filters]]
        position = 1
        kind = "open"
        [[filters]]
        position = 2
        kind = "bandpass"
        centre_nm = 550
        fwhm_nm = 10
        [[filters]]
        position = 3
        kind = "bandpass"
        centre_nm = 553.5
        fwhm_nm = 10
        peak_transmittance = 0.5
        [[filters]]
        position = 4
        kind = "longpass"
        cut_on_nm = 495
        [[filters]]
        position = 5
        kind = "longpass"
        cut_on_nm = 695
        [[filters]]
        position = 6
        kind = "dark"
"#;

#[test]
fn a_wheel_parses_with_defaults_and_validates() {
    let c = parse(WHEEL).unwrap();
    c.validate().unwrap();
    assert_eq!(c.speed, Speed::High);
    assert_eq!(c.filters.len(), 6);
    assert_eq!(
        c.filter_at(3),
        Some(&Filter::Bandpass {
            position: 3,
            centre_nm: 553.5,
            fwhm_nm: 10.0,
            peak_transmittance: 0.5
        })
    );
    assert_eq!(
        c.filter_at(4),
        Some(&Filter::Longpass {
            position: 4,
            cut_on_nm: 495.0,
            peak_transmittance: 1.0
        })
    );
}

#[test]
fn lookups_pick_by_the_documented_rules() {
    let c = parse(WHEEL).unwrap();
    assert_eq!(c.position_for_band(550.0), Some(2));
    assert_eq!(c.position_for_band(551.0), Some(2));
    // 552.0 is 2.0 from 550 and 1.5 from 553.5: the nearer wins.
    assert_eq!(c.position_for_band(552.0), Some(3));
    assert_eq!(c.position_for_band(555.5), Some(3));
    assert_eq!(c.position_for_band(555.6), None);
    assert_eq!(c.position_for_band(600.0), None);
    // 495 lies in (λ/2, λ) for λ in (495, 990); 695 for λ in (695, 1390).
    assert_eq!(c.position_for_order_sorting(600.0), Some(4));
    assert_eq!(c.position_for_order_sorting(495.0), None);
    assert_eq!(c.position_for_order_sorting(989.0), Some(5));
    // At 800: 495 has margin min(305, 95) = 95, 695 has min(105, 295) = 105.
    assert_eq!(c.position_for_order_sorting(800.0), Some(5));
    assert_eq!(c.position_for_order_sorting(700.0), Some(4));
    assert_eq!(c.position_for_order_sorting(400.0), None);
    assert_eq!(c.dark_position(), Some(6));
    assert_eq!(c.open_position(), Some(1));
    assert_eq!(Fw102cConfig::default().dark_position(), None);
}

#[test]
fn bad_values_name_their_field() {
    let field = |text: &str| match parse(text) {
        Ok(c) => c.validate().unwrap_err().field,
        Err(e) => format!("parse: {e}"),
    };
    assert_eq!(field("positions = 8"), "positions");
    assert_eq!(field("band_tolerance_nm = 0"), "band_tolerance_nm");
    assert_eq!(field("move_timeout_ms = 50"), "move_timeout_ms");
    assert_eq!(field("retries = 11"), "retries");
    assert_eq!(
        field("[[filters]]\nposition = 7\nkind = \"open\""),
        "filters[0].position"
    );
    assert_eq!(
        field(
            "[[filters]]\nposition = 1\nkind = \"open\"\n[[filters]]\nposition = 1\nkind = \"dark\""
        ),
        "filters[1].position"
    );
    assert_eq!(
        field("[[filters]]\nposition = 1\nkind = \"bandpass\"\ncentre_nm = 550\nfwhm_nm = -1"),
        "filters[0].fwhm_nm"
    );
    assert_eq!(
        field(
            "[[filters]]\nposition = 1\nkind = \"longpass\"\ncut_on_nm = 495\npeak_transmittance = 1.5"
        ),
        "filters[0].peak_transmittance"
    );
}

#[test]
fn unknown_keys_and_kinds_are_refused() {
    assert!(parse("position = 6").is_err());
    assert!(parse("[[filters]]\nposition = 1\nkind = \"open\"\ncentre_nm = 3").is_err());
    assert!(parse("[[filters]]\nposition = 1\nkind = \"notch\"").is_err());
    assert!(parse("[[filters]]\nposition = 1\nkind = \"bandpass\"\ncentre_nm = 550").is_err());
}
