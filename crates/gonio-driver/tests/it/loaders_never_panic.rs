//! An instrument config of any content is a config or a located error, never a
//! panic: arbitrary text, and the shipped configs with hostile changes
//! (`gonio_core::fuzz::mutate`: a number made `nan`, `inf`, `-0`, `1e308` or a huge
//! integer, a line deleted or repeated, a BOM). An accepted config gives its policy,
//! ports, reading time and mechanics, and the mechanics check pairs, without a panic;
//! the SMC100 chain and the SR830 driver accept its axes and lock-in settings.

use gonio_core::fuzz::mutate;
use gonio_core::{Dir, DirPair, SphericalDeg};
use gonio_driver::smc100::Smc100Chain;
use gonio_driver::sr830::Sr830;
use gonio_driver::{InstrumentConfig, ManualClock, ScriptedTransport};
use proptest::prelude::*;

const CONFIGS: &[&str] = &[
    include_str!("../../../../config/instrument-example.toml"),
    include_str!("../../../../config/instrument-sim.toml"),
];

fn pair(ti: f64, pi: f64, to: f64, po: f64) -> DirPair {
    DirPair::new(
        Dir::from(SphericalDeg::new(ti, pi)),
        Dir::from(SphericalDeg::new(to, po)),
    )
}

fn load(text: &str) -> Result<(), TestCaseError> {
    let c = match InstrumentConfig::from_toml(text, None) {
        Ok(c) => c,
        Err(e) => {
            prop_assert!(e.line.is_none_or(|l| l >= 1), "{e}");
            return Ok(());
        }
    };
    let _ = c.motion.policy();
    prop_assert_eq!(c.motion.serial().path, c.motion.port.clone());
    prop_assert_eq!(c.detector.serial().baud, c.detector.baud);
    prop_assert_eq!(c.stages().len(), c.motion.axes.len());
    let _ = c.reading_seconds();
    // The drivers accept what the config accepted: nothing is sent until set-up.
    let clock = ManualClock::new();
    let (t, _) = ScriptedTransport::new(b'\r', 64, clock.clone());
    let chain = Smc100Chain::new(t, clock.clone(), c.motion.smc100_axes(), c.motion.policy());
    prop_assert!(chain.is_ok(), "{:?}", chain.err());
    let (t, _) = ScriptedTransport::new(b'\r', 64, clock.clone());
    let lockin = Sr830::new(t, clock, c.detector.lockin.clone());
    prop_assert!(lockin.is_ok(), "{:?}", lockin.err());
    if let Ok(m) = c.mechanics() {
        for p in [
            pair(0.0, 0.0, 0.0, 0.0),
            pair(30.0, 0.0, 45.0, 180.0),
            pair(89.0, 90.0, 10.0, -45.0),
        ] {
            let _ = m.accept(p);
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn configs_from_any_text(text in any::<String>()) {
        load(&text)?;
    }

    #[test]
    fn shipped_configs_damaged(
        file in prop::sample::select(CONFIGS),
        seeds in prop::collection::vec(any::<u64>(), 1..4),
    ) {
        load(&mutate(file, &seeds))?;
    }
}

#[test]
fn shipped_configs_read_with_a_byte_order_mark() {
    for text in CONFIGS {
        assert_eq!(
            InstrumentConfig::from_toml(&format!("\u{feff}{text}"), None).expect("BOM"),
            InstrumentConfig::from_toml(text, None).expect("plain")
        );
    }
}
