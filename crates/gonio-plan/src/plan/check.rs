//! Checking the pairs against an instrument: which it measures, at which stage
//! positions, and which it leaves out and why.

use gonio_core::DirPair;
use gonio_core::dirfile::PairDeg;

use super::{Mechanics, Rejection, SAME_PAIR};

/// A pair the plan measures, with its stage positions.
#[derive(Clone, Debug, PartialEq)]
pub struct Accepted {
    /// Index in the plan's own order.
    pub index: usize,
    /// The pair, degrees, as the plan gave it.
    pub pair: PairDeg,
    /// Stage positions, degrees, role order.
    pub stages: [f64; 4],
}

/// A pair the plan does not measure, and why.
#[derive(Clone, Debug, PartialEq)]
pub struct Rejected {
    /// Index in the plan's own order.
    pub index: usize,
    /// The pair, degrees.
    pub pair: PairDeg,
    /// Why.
    pub reason: Rejection,
}

/// The outcome of checking a plan against an instrument.
#[derive(Clone, Debug, PartialEq)]
pub struct Checked {
    /// Pairs to measure, plan order.
    pub accepted: Vec<Accepted>,
    /// Pairs left out, plan order.
    pub rejected: Vec<Rejected>,
}

/// True when two pairs are the same configuration.
fn same(a: DirPair, b: DirPair) -> bool {
    let close = |u: gonio_core::Vec3, v: gonio_core::Vec3| {
        (u.x - v.x).abs() <= SAME_PAIR
            && (u.y - v.y).abs() <= SAME_PAIR
            && (u.z - v.z).abs() <= SAME_PAIR
    };
    close(a.wi.vec(), b.wi.vec()) && close(a.wo.vec(), b.wo.vec())
}

/// Checks every pair of `pairs` (plan order) on `mech`.
pub fn check(mech: &Mechanics, pairs: &[PairDeg]) -> Checked {
    let mut accepted: Vec<Accepted> = Vec::new();
    let mut rejected = Vec::new();
    // Duplicates are found by hashing a quantised key, not by an O(n²) scan.
    let mut seen: std::collections::HashMap<[i64; 6], usize> = std::collections::HashMap::new();
    let key = |d: DirPair| {
        let q = |x: f64| (x * 1e8).round() as i64;
        [
            q(d.wi.x),
            q(d.wi.y),
            q(d.wi.z),
            q(d.wo.x),
            q(d.wo.y),
            q(d.wo.z),
        ]
    };
    for (index, pair) in pairs.iter().enumerate() {
        let dirs = pair.to_dirs();
        if let Some(&of) = seen.get(&key(dirs))
            && same(pairs[of].to_dirs(), dirs)
        {
            rejected.push(Rejected {
                index,
                pair: *pair,
                reason: Rejection::Duplicate { of },
            });
            continue;
        }
        match mech.accept(dirs) {
            Ok(stages) => {
                seen.insert(key(dirs), index);
                accepted.push(Accepted {
                    index,
                    pair: *pair,
                    stages,
                });
            }
            Err(reason) => rejected.push(Rejected {
                index,
                pair: *pair,
                reason,
            }),
        }
    }
    Checked { accepted, rejected }
}
