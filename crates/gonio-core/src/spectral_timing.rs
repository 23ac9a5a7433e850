//! How long the bench takes to change wavelength: the move-time model the planner
//! weighs against the stages' motion when it decides whether wavelength or geometry
//! is the inner loop of a spectral run.
//!
//! Two kinds of wavelength selector:
//! - a monochromator ([`MonochromatorTiming`]): the grating turns at a slew rate, the
//!   drive settles, and at given crossover wavelengths the order-sorting filter and
//!   the grating change (a Newport/Oriel Cornerstone 130 has both). A drive that takes
//!   up its backlash approaching every wavelength from below overshoots a move
//!   towards shorter wavelengths and comes back ([`MonochromatorTiming::backlash_nm`]).
//! - a filter wheel (or any selector whose every change costs about the same):
//!   one constant per change ([`WavelengthTiming::PerChange`]).
//!
//! The numbers come from the instrument's config; none are assumed here. The model is
//! a sum of its parts (slew, settle, filter change, grating change, taken one after
//! another): a controller that overlaps them is faster than the estimate, which then
//! errs on the side of the geometry loop. **UNCONFIRMED** for the Cornerstone 130:
//! whether its filter and grating changes overlap the slew.
//!
//! Pure and deterministic: no clock, no device.

use serde::{Deserialize, Serialize};

use crate::limits::{Fault, Range};

/// Slew rates, nm/s.
pub const SLEW: Range = Range::positive(1e6, "nm/s");
/// Settling, filter, grating and per-change times, s.
pub const CHANGE_TIME: Range = Range::closed(0.0, 3600.0, "s");
/// Backlash overshoot, nm.
pub const BACKLASH: Range = Range::closed(0.0, 1000.0, "nm");
/// Crossover wavelengths, nm.
pub const CROSSOVER: Range = Range::positive(1e5, "nm");
/// Most crossovers of one accessory (a filter wheel has a handful of positions).
pub const MAX_CROSSOVERS: usize = 64;

/// An accessory that changes position at given wavelengths (an order-sorting filter
/// wheel, a grating turret).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Crossovers {
    /// Time of one change, s (whatever the distance between the positions).
    pub change_s: f64,
    /// Wavelengths at which the next position takes over, nm, strictly increasing:
    /// position k serves `[at_nm[k-1], at_nm[k])` (a crossover wavelength itself is
    /// served by the position above it).
    pub at_nm: Vec<f64>,
}

impl Crossovers {
    /// The position that serves `nm`: how many crossovers lie at or below it.
    pub fn position(&self, nm: f64) -> usize {
        self.at_nm.iter().filter(|c| nm >= **c).count()
    }

    fn validate(&self, prefix: &str) -> Result<(), Fault> {
        CHANGE_TIME.at(format!("{prefix}.change_s"), self.change_s)?;
        if self.at_nm.len() > MAX_CROSSOVERS {
            return Err((
                format!("{prefix}.at_nm"),
                format!(
                    "{} crossovers, more than {MAX_CROSSOVERS}",
                    self.at_nm.len()
                ),
            ));
        }
        for (k, c) in self.at_nm.iter().enumerate() {
            let field = format!("{prefix}.at_nm[{k}]");
            CROSSOVER.at(field.clone(), *c)?;
            if k > 0 && *c <= self.at_nm[k - 1] {
                return Err((field, "crossovers must be strictly increasing".into()));
            }
        }
        Ok(())
    }
}

/// The serial statements of a change of wavelength around the drive's own moves, s,
/// as the monochromator's session makes them (its protocol fills them in).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ChangeExchanges {
    /// Before the drive starts: the statement that starts it, on the wire.
    pub lead_s: f64,
    /// Exchanged while the drive moves (echoes, the wait for the move): a change
    /// takes at least this long however short the move.
    pub during_s: f64,
    /// After the drive stops: the read-back's answer and the status check.
    pub trail_s: f64,
    /// The extra statement, exchanged while the drive moves, of a move that first
    /// goes below its wavelength (a move down, or from an unknown wavelength, with a
    /// backlash correction).
    pub approach_s: f64,
}

/// A monochromator's wavelength drive.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MonochromatorTiming {
    /// Slew rate of the grating drive, nm/s.
    pub slew_nm_per_s: f64,
    /// Settling after every move, s.
    pub settle_s: f64,
    /// Overshoot of a move towards shorter wavelengths, nm: the drive goes this far
    /// past the target and approaches it from below, so that the gears' backlash is
    /// always taken up the same way. 0: no backlash correction.
    #[serde(default)]
    pub backlash_nm: f64,
    /// The order-sorting filter wheel.
    #[serde(default)]
    pub order_filter: Option<Crossovers>,
    /// The grating turret.
    #[serde(default)]
    pub grating: Option<Crossovers>,
    /// The statements around each change (none counted by default).
    #[serde(default)]
    pub exchanges: ChangeExchanges,
}

/// How long a change of wavelength takes.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum WavelengthTiming {
    /// A monochromator: slew, settle, filter and grating changes.
    Monochromator(MonochromatorTiming),
    /// A filter wheel, or any selector whose every change takes the same time.
    PerChange {
        /// Time of one change, s.
        change_s: f64,
    },
}

impl WavelengthTiming {
    /// A monochromator slewing at `slew_nm_per_s` and settling for `settle_s`, with
    /// neither backlash correction, order-sorting filter nor second grating (add them
    /// with [`with_backlash`](Self::with_backlash),
    /// [`with_order_filter`](Self::with_order_filter), [`with_grating`](Self::with_grating)).
    pub fn monochromator(slew_nm_per_s: f64, settle_s: f64) -> WavelengthTiming {
        WavelengthTiming::Monochromator(MonochromatorTiming {
            slew_nm_per_s,
            settle_s,
            backlash_nm: 0.0,
            order_filter: None,
            grating: None,
            exchanges: ChangeExchanges::default(),
        })
    }

    /// A selector whose every change takes `change_s` (a filter wheel).
    pub fn per_change(change_s: f64) -> WavelengthTiming {
        WavelengthTiming::PerChange { change_s }
    }

    fn mono(mut self, f: impl FnOnce(&mut MonochromatorTiming)) -> WavelengthTiming {
        if let WavelengthTiming::Monochromator(m) = &mut self {
            f(m);
        }
        self
    }

    /// The monochromator with a backlash overshoot of `nm` on moves down (no effect
    /// on a per-change selector).
    pub fn with_backlash(self, nm: f64) -> WavelengthTiming {
        self.mono(|m| m.backlash_nm = nm)
    }

    /// The monochromator with an order-sorting filter that changes at `at_nm`, each
    /// change taking `change_s` (no effect on a per-change selector).
    pub fn with_order_filter(self, change_s: f64, at_nm: &[f64]) -> WavelengthTiming {
        self.mono(|m| {
            m.order_filter = Some(Crossovers {
                change_s,
                at_nm: at_nm.to_vec(),
            })
        })
    }

    /// The monochromator with the statements `exchanges` around each change (no
    /// effect on a per-change selector).
    pub fn with_exchanges(self, exchanges: ChangeExchanges) -> WavelengthTiming {
        self.mono(|m| m.exchanges = exchanges)
    }

    /// The monochromator with gratings that change at `at_nm`, each change taking
    /// `change_s` (no effect on a per-change selector).
    pub fn with_grating(self, change_s: f64, at_nm: &[f64]) -> WavelengthTiming {
        self.mono(|m| {
            m.grating = Some(Crossovers {
                change_s,
                at_nm: at_nm.to_vec(),
            })
        })
    }

    /// Checks every number against its range; a fault names the field under
    /// `prefix` (e.g. `wavelength`).
    pub fn validate(&self, prefix: &str) -> Result<(), Fault> {
        match self {
            WavelengthTiming::PerChange { change_s } => {
                CHANGE_TIME.at(format!("{prefix}.change_s"), *change_s)?;
            }
            WavelengthTiming::Monochromator(m) => {
                SLEW.at(format!("{prefix}.slew_nm_per_s"), m.slew_nm_per_s)?;
                CHANGE_TIME.at(format!("{prefix}.settle_s"), m.settle_s)?;
                BACKLASH.at(format!("{prefix}.backlash_nm"), m.backlash_nm)?;
                if let Some(c) = &m.order_filter {
                    c.validate(&format!("{prefix}.order_filter"))?;
                }
                if let Some(c) = &m.grating {
                    c.validate(&format!("{prefix}.grating"))?;
                }
            }
        }
        Ok(())
    }

    /// Time to go from `from_nm` to `to_nm`, s; 0 when they are the same.
    ///
    /// From an unknown wavelength (`None`, the start of a run) the selector is
    /// assumed to change everything it has — a settle, the order-sorting filter and
    /// the grating, or one change — without a slew, whose length is unknown.
    pub fn move_s(&self, from_nm: Option<f64>, to_nm: f64) -> f64 {
        if from_nm == Some(to_nm) {
            return 0.0;
        }
        match self {
            WavelengthTiming::PerChange { change_s } => *change_s,
            WavelengthTiming::Monochromator(m) => {
                let changed = |c: &Option<Crossovers>| match (c, from_nm) {
                    (None, _) => 0.0,
                    (Some(c), None) => c.change_s,
                    (Some(c), Some(f)) if c.position(f) != c.position(to_nm) => c.change_s,
                    (Some(_), Some(_)) => 0.0,
                };
                let slew = match from_nm {
                    None => 0.0,
                    Some(f) => {
                        let down = if to_nm < f { 2.0 * m.backlash_nm } else { 0.0 };
                        ((to_nm - f).abs() + down) / m.slew_nm_per_s
                    }
                };
                let drive = slew + m.settle_s + changed(&m.order_filter) + changed(&m.grating);
                // The statements: the first starts the drive; the echoes and the
                // wait overlap it, with one statement more for a move that comes
                // down (or from nowhere) with a backlash correction.
                let x = &m.exchanges;
                let approach = m.backlash_nm > 0.0 && from_nm.is_none_or(|f| to_nm < f);
                let during = x.during_s + if approach { x.approach_s } else { 0.0 };
                x.lead_s + drive.max(during) + x.trail_s
            }
        }
    }

    /// Time to visit `nm` in order starting from `from_nm`, s.
    pub fn sweep_s(&self, from_nm: Option<f64>, nm: &[f64]) -> f64 {
        let mut at = from_nm;
        let mut t = 0.0;
        for &w in nm {
            t += self.move_s(at, w);
            at = Some(w);
        }
        t
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A monochromator at 100 nm/s settling 0.2 s, the filter changing at 600 nm
    /// (1.5 s), the grating at 650 nm (4 s), 5 nm of backlash.
    fn mono() -> WavelengthTiming {
        WavelengthTiming::monochromator(100.0, 0.2)
            .with_backlash(5.0)
            .with_order_filter(1.5, &[600.0])
            .with_grating(4.0, &[650.0])
    }

    #[test]
    fn monochromator_moves_add_slew_settle_and_changes() {
        let m = mono();
        assert_eq!(m.move_s(Some(500.0), 500.0), 0.0);
        // Up 50 nm, no crossover: 0.5 s slew + 0.2 s settle.
        assert!((m.move_s(Some(500.0), 550.0) - 0.7).abs() < 1e-12);
        // Down 50 nm: 60 nm of travel with the overshoot.
        assert!((m.move_s(Some(550.0), 500.0) - 0.8).abs() < 1e-12);
        // Across the filter's crossover (600 is served by the filter above it).
        assert!((m.move_s(Some(590.0), 600.0) - (0.1 + 0.2 + 1.5)).abs() < 1e-12);
        // Across both: 200 nm slew, settle, filter and grating.
        assert!((m.move_s(Some(500.0), 700.0) - (2.0 + 0.2 + 1.5 + 4.0)).abs() < 1e-12);
        // From nowhere: everything changes, no slew.
        assert!((m.move_s(None, 700.0) - (0.2 + 1.5 + 4.0)).abs() < 1e-12);
        // A sweep is its moves.
        assert!((m.sweep_s(Some(500.0), &[550.0, 500.0]) - 1.5).abs() < 1e-12);
    }

    #[test]
    fn the_statements_of_a_change_surround_the_drive() {
        let x = ChangeExchanges {
            lead_s: 0.02,
            during_s: 0.05,
            trail_s: 0.03,
            approach_s: 0.04,
        };
        let m = mono().with_exchanges(x);
        // Up 50 nm: the first statement, the drive (0.7 s, longer than what overlaps
        // it), the answer and the status.
        assert!((m.move_s(Some(500.0), 550.0) - (0.02 + 0.7 + 0.03)).abs() < 1e-12);
        // A short move takes no less than the statements exchanged while it runs;
        // down, with the approach from below.
        let quick = WavelengthTiming::monochromator(1e6, 0.0)
            .with_backlash(5.0)
            .with_exchanges(x);
        assert!((quick.move_s(Some(500.0), 501.0) - (0.02 + 0.05 + 0.03)).abs() < 1e-9);
        assert!((quick.move_s(Some(501.0), 500.0) - (0.02 + 0.09 + 0.03)).abs() < 1e-9);
        assert_eq!(quick.move_s(Some(500.0), 500.0), 0.0);
    }

    #[test]
    fn per_change_costs_one_constant() {
        let w = WavelengthTiming::per_change(2.5);
        assert_eq!(w.move_s(Some(450.0), 450.0), 0.0);
        assert_eq!(w.move_s(Some(450.0), 650.0), 2.5);
        assert_eq!(w.move_s(None, 650.0), 2.5);
        // The monochromator's builders leave it alone.
        assert_eq!(w.clone().with_backlash(3.0), w);
    }

    #[test]
    fn crossover_positions_and_validation() {
        let c = Crossovers {
            change_s: 1.0,
            at_nm: vec![500.0, 700.0],
        };
        assert_eq!(
            [
                c.position(400.0),
                c.position(500.0),
                c.position(699.9),
                c.position(700.0)
            ],
            [0, 1, 1, 2]
        );
        assert_eq!(mono().validate("wavelength"), Ok(()));
        let bad = WavelengthTiming::monochromator(0.0, 0.2);
        assert_eq!(
            bad.validate("wavelength").unwrap_err().0,
            "wavelength.slew_nm_per_s"
        );
        let bad = WavelengthTiming::monochromator(10.0, 0.2).with_grating(1.0, &[700.0, 500.0]);
        assert_eq!(
            bad.validate("wavelength").unwrap_err(),
            (
                "wavelength.grating.at_nm[1]".to_string(),
                "crossovers must be strictly increasing".to_string()
            )
        );
        let bad = WavelengthTiming::per_change(f64::NAN);
        assert_eq!(
            bad.validate("w").unwrap_err(),
            (
                "w.change_s".to_string(),
                "must be finite, got NaN".to_string()
            )
        );
    }

    #[test]
    fn reads_from_toml() {
        let t: WavelengthTiming = toml::from_str(
            "kind = \"monochromator\"\nslew_nm_per_s = 100\nsettle_s = 0.2\nbacklash_nm = 5\n\
             order_filter = { change_s = 1.5, at_nm = [600] }\n\
             grating = { change_s = 4, at_nm = [650] }\n",
        )
        .expect("reads");
        assert_eq!(t, mono());
        let t: WavelengthTiming =
            toml::from_str("kind = \"per-change\"\nchange_s = 2.5\n").expect("reads");
        assert_eq!(t, WavelengthTiming::per_change(2.5));
    }
}
