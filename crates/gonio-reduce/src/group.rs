//! The run's readings grouped for the reduction: the reading that counts for each
//! step, the instrument time of each, the channels the steps name, and the
//! readings of one kind for one channel ([`Grouped::of`]). Also the counts the
//! report states of them: the readings kept although capped, the sample steps
//! never measured, and why a sample reading was left out ([`flag_reason`]).

use std::collections::BTreeMap;

use gonio_core::Channels;
use gonio_plan::StepKind;
use gonio_run::{ReadingRecord, StoredStep, flags};

/// A step with the reading that counts for it.
pub(crate) type Read<'a> = (&'a StoredStep, &'a ReadingRecord);

/// The run's steps, each with the reading that counts for it and that reading's
/// instrument time.
pub(crate) struct Grouped<'a> {
    /// The schedule's steps.
    steps: &'a [StoredStep],
    /// The last reading of each step, by step id.
    pub by_step: BTreeMap<i64, &'a ReadingRecord>,
    /// The instrument time of each step's reading, s ([`timeline`]).
    pub time: BTreeMap<i64, f64>,
}

impl<'a> Grouped<'a> {
    /// Groups the readings by their steps. The last reading of a step is the one
    /// that counts: a step re-measured after a fault keeps only its final reading.
    pub(crate) fn new(steps: &'a [StoredStep], readings: &'a [ReadingRecord]) -> Grouped<'a> {
        let mut by_step: BTreeMap<i64, &ReadingRecord> = BTreeMap::new();
        for r in readings {
            by_step.insert(r.step_id, r);
        }
        let time = timeline(&by_step);
        Grouped {
            steps,
            by_step,
            time,
        }
    }

    /// The instrument time of a reading that counts, s.
    pub(crate) fn time_of(&self, r: &ReadingRecord) -> f64 {
        self.time[&r.step_id]
    }

    /// The readings that count and carry none of `reject_flags`, each with whether
    /// its step is a dark: what the noise law is fitted to.
    pub(crate) fn kept(&self, reject_flags: u32) -> Vec<(&'a ReadingRecord, bool)> {
        let kind_of: BTreeMap<i64, StepKind> =
            self.steps.iter().map(|s| (s.id, s.step.kind)).collect();
        self.by_step
            .values()
            .filter(|r| r.flags & reject_flags == 0)
            .map(|r| (*r, kind_of.get(&r.step_id) == Some(&StepKind::Dark)))
            .collect()
    }

    /// The readings kept although they reached the plan's time cap before their
    /// target (flag `capped`): the report counts them.
    pub(crate) fn capped(&self, reject_flags: u32) -> usize {
        self.by_step
            .values()
            .filter(|r| r.flags & reject_flags == 0 && r.flags & flags::CAPPED != 0)
            .count()
    }

    /// The channels the steps name, in the order they first appear (`None` for a
    /// step of no named band).
    pub(crate) fn channel_names(&self) -> Vec<Option<String>> {
        let mut v: Vec<Option<String>> = Vec::new();
        for s in self.steps {
            if !v.contains(&s.step.channel) {
                v.push(s.step.channel.clone());
            }
        }
        v
    }

    /// The measured steps of `kind` for the channel `ch`, in schedule order, each
    /// with its reading. A named channel without any takes the unnamed steps of
    /// that kind: a dark or a reference taken once serves every band.
    pub(crate) fn of(&self, kind: StepKind, ch: &Option<String>) -> Vec<Read<'a>> {
        let pick = |want: &Option<String>| {
            self.steps
                .iter()
                .filter(|s| s.step.kind == kind && &s.step.channel == want)
                .filter_map(|s| self.by_step.get(&s.id).map(|r| (s, *r)))
                .collect::<Vec<_>>()
        };
        let v = pick(ch);
        if v.is_empty() && ch.is_some() {
            pick(&None)
        } else {
            v
        }
    }

    /// The sample steps without a reading (pending or failed).
    pub(crate) fn unmeasured(&self) -> usize {
        self.steps
            .iter()
            .filter(|s| s.step.kind == StepKind::Sample && !self.by_step.contains_key(&s.id))
            .count()
    }
}

/// The run's instrument time of every reading, s: the instrument clock, continued
/// across sessions (each session's clock starts again at 0, so a session's first
/// reading follows the previous session's last). It is the clock the source drifts
/// by — in the laboratory the system clock, in a simulated run the simulator's.
pub(crate) fn timeline(by_step: &BTreeMap<i64, &ReadingRecord>) -> BTreeMap<i64, f64> {
    let mut out = BTreeMap::new();
    let (mut t, mut last) = (0.0, None::<f64>);
    for (id, r) in by_step {
        if let Some(prev) = last
            && r.physical_s >= prev
        {
            t += r.physical_s - prev;
        }
        last = Some(r.physical_s);
        out.insert(*id, t);
    }
    out
}

/// The channels of the run's channel names: [`Channels::Single`] when no step
/// names one, else the named ones (`Err` says why they are not a channel set).
pub(crate) fn channels(names: &[Option<String>]) -> Result<Channels, String> {
    if names.iter().all(Option::is_none) {
        Ok(Channels::Single)
    } else {
        let names: Vec<String> = names.iter().flatten().cloned().collect();
        Channels::from_names(&names).map_err(|e| format!("channels: {e}"))
    }
}

/// Why a sample reading with the flags `f` (those of the rejected ones it carries)
/// is left out, as the report counts it.
pub(crate) fn flag_reason(f: u32) -> String {
    if f & flags::UNLOCK != 0 {
        "unlock".into()
    } else if f & (flags::INPUT_OVERLOAD | flags::FILTER_OVERLOAD | flags::OUTPUT_OVERLOAD) != 0 {
        "overload".into()
    } else if f & flags::CAPPED != 0 {
        // Only when the caller asks for capped readings to be left out.
        "capped".into()
    } else {
        "overload".into()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::reading;

    fn step(id: i64, kind: StepKind, channel: Option<&str>) -> StoredStep {
        StoredStep {
            id,
            step: gonio_plan::Step {
                kind,
                channel: channel.map(String::from),
                repeat: 0,
                pair: None,
                stages: None,
                plan_index: None,
            },
            state: "done".into(),
            attempts: 1,
        }
    }

    fn at(step_id: i64, physical_s: f64) -> ReadingRecord {
        ReadingRecord {
            step_id,
            physical_s,
            ..reading()
        }
    }

    /// A second session's clock starts again at 0: its first reading follows the
    /// first session's last, and time goes on from there.
    #[test]
    fn the_timeline_continues_across_a_session_restart() {
        let rs = [at(1, 0.0), at(2, 5.0), at(3, 10.0), at(4, 2.0), at(5, 4.5)];
        let by_step: BTreeMap<i64, &ReadingRecord> = rs.iter().map(|r| (r.step_id, r)).collect();
        let t = timeline(&by_step);
        assert_eq!(
            t.values().copied().collect::<Vec<_>>(),
            [0.0, 5.0, 10.0, 10.0, 12.5]
        );
    }

    /// The last reading of a step counts; a named band without darks of its own
    /// takes the unnamed ones.
    #[test]
    fn the_last_reading_counts_and_a_band_falls_back_to_unnamed_steps() {
        let steps = [
            step(1, StepKind::Dark, None),
            step(2, StepKind::Sample, Some("red")),
            step(3, StepKind::Sample, Some("blue")),
            step(4, StepKind::Sample, Some("blue")),
        ];
        let first = ReadingRecord {
            x_mean: 1.0,
            ..at(2, 1.0)
        };
        let again = ReadingRecord {
            x_mean: 2.0,
            ..at(2, 3.0)
        };
        let readings = [at(1, 0.0), first, at(3, 2.0), again];
        let g = Grouped::new(&steps, &readings);
        let red = Some("red".to_string());
        let samples = g.of(StepKind::Sample, &red);
        assert_eq!(samples.len(), 1);
        assert_eq!(samples[0].1.x_mean, 2.0);
        assert_eq!(g.time_of(samples[0].1), 3.0);
        let darks = g.of(StepKind::Dark, &red);
        assert_eq!(darks.len(), 1);
        assert_eq!(darks[0].0.id, 1);
        assert_eq!(g.unmeasured(), 1);
        assert_eq!(
            g.channel_names(),
            [None, red.clone(), Some("blue".to_string())]
        );
        assert_eq!(g.kept(0).iter().filter(|(_, dark)| *dark).count(), 1);
    }

    #[test]
    fn capped_readings_are_counted_unless_rejected() {
        let steps = [
            step(1, StepKind::Sample, None),
            step(2, StepKind::Sample, None),
        ];
        let capped = ReadingRecord {
            flags: flags::CAPPED,
            ..at(1, 0.0)
        };
        let readings = [capped, at(2, 1.0)];
        let g = Grouped::new(&steps, &readings);
        assert_eq!(g.capped(0), 1);
        assert_eq!(g.capped(flags::CAPPED), 0);
        assert_eq!(flag_reason(flags::CAPPED), "capped");
        assert_eq!(flag_reason(flags::UNLOCK | flags::INPUT_OVERLOAD), "unlock");
        assert_eq!(flag_reason(flags::FILTER_OVERLOAD), "overload");
    }

    #[test]
    fn steps_naming_no_band_are_a_single_channel() {
        assert_eq!(channels(&[None]), Ok(Channels::Single));
        assert!(channels(&[Some("550nm".into())]).is_ok());
    }
}
