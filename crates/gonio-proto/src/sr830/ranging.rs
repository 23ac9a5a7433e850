//! Autoranging: the range a reading moves to after it read a value at a range, for
//! the fixed reading (`session/read.rs`) and the reading to a target
//! (`session/targeted.rs`), and what those rules make of a steady signal, which is
//! what a plan's estimate counts the range changes with.

use super::Sensitivity;

/// An output overloads (OUTPUT OVLD, `LIAS?` bit 2) above this multiple of full scale
/// (manual p. 5-23; `instruments.md` §2.5).
pub const OUTPUT_OVERLOAD: f64 = 1.09;

/// A targeted reading's overload steps this many ranges less sensitive (a decade in
/// the 1-2-5 sequence): it only says the signal is over full scale, and the
/// small-signal jump comes back down to the range that fits in one step.
pub const OVERLOAD_STEPS: u8 = 3;

/// A targeted reading's autoranging on a small signal goes straight to the most
/// sensitive range whose full scale times this holds the mean and four standard
/// deviations of its snapshots (the instrument's own auto gain aims at the same fill).
pub const RANGE_FILL: f64 = 0.9;

/// After a fixed reading of mean `r` V at the range `at`: one range less sensitive
/// when it `overloaded`, one more when it is `clean` (no status bit) and under
/// `min_fraction` of full scale; `None` to keep it.
pub fn fixed_next(
    at: Sensitivity,
    r: f64,
    overloaded: bool,
    clean: bool,
    min_fraction: f64,
) -> Option<Sensitivity> {
    if overloaded {
        at.less_sensitive()
    } else if clean && r < min_fraction * at.volts() {
        at.more_sensitive()
    } else {
        None
    }
}

/// [`OVERLOAD_STEPS`] ranges less sensitive than `at`, or the least sensitive; `None`
/// there.
pub fn overload_range(at: Sensitivity) -> Option<Sensitivity> {
    let up = at
        .index()
        .saturating_add(OVERLOAD_STEPS)
        .min(Sensitivity::LEAST.index());
    Sensitivity::new(up).filter(|n| *n > at)
}

/// After a targeted reading of mean `r` V and snapshot deviation `r_std` at the
/// range `at`: [`overload_range`] when it `overloaded`; when it is `clean` and under
/// `min_fraction` of full scale, straight to the most sensitive range that holds
/// `r + 4 r_std` at [`RANGE_FILL`] of full scale (one range more if none is more
/// sensitive than `at`); `None` to keep it.
pub fn targeted_next(
    at: Sensitivity,
    r: f64,
    r_std: f64,
    overloaded: bool,
    clean: bool,
    min_fraction: f64,
) -> Option<Sensitivity> {
    if overloaded {
        overload_range(at)
    } else if clean && r < min_fraction * at.volts() {
        // Room for the snapshots' scatter: a range the noise clips is no range.
        Sensitivity::all()
            .find(|x| x.volts() * RANGE_FILL >= r + 4.0 * r_std)
            .filter(|x| *x < at)
            .or_else(|| at.more_sensitive())
    } else {
        None
    }
}

/// What a rule makes of readings that all read `r` V from the range `from`: the
/// changes it makes before it keeps one, and the range it ends on. A reading
/// overloads over [`OUTPUT_OVERLOAD`] of full scale and is clean otherwise.
fn settle_on(
    from: Sensitivity,
    r: f64,
    next: impl Fn(Sensitivity, bool) -> Option<Sensitivity>,
) -> (usize, Sensitivity) {
    let mut at = from;
    for changes in 0..=super::MAX_AUTORANGE_STEPS {
        match next(at, r > OUTPUT_OVERLOAD * at.volts()) {
            Some(n) => at = n,
            None => return (changes, at),
        }
    }
    (super::MAX_AUTORANGE_STEPS, at)
}

/// The range changes a fixed reading of a steady `r` V makes from the range `from`
/// ([`fixed_next`]), and the range it ends on.
pub fn fixed_changes(from: Sensitivity, r: f64, min_fraction: f64) -> (usize, Sensitivity) {
    settle_on(from, r, |at, over| {
        fixed_next(at, r, over, !over, min_fraction)
    })
}

/// The range changes a targeted reading of a steady `r` V, its snapshots scattered by
/// `r_std`, makes from the range `from` ([`targeted_next`]), and the range it ends on.
pub fn targeted_changes(
    from: Sensitivity,
    r: f64,
    r_std: f64,
    min_fraction: f64,
) -> (usize, Sensitivity) {
    settle_on(from, r, |at, over| {
        targeted_next(at, r, r_std, over, !over, min_fraction)
    })
}
