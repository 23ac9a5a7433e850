//! What the motion families (SMC100, APT) share: the errors every motion family's
//! session returns, [`AxisError`] on one axis and [`MotionError`] naming it (they
//! began as the SMC100's, whose controller-specific variants they keep), and the
//! motion written once over the families ([`Motion`]): the polling of moving axes
//! with a pause that is an abort point, and the end of a motion that failed, which
//! stops every stage and, past a deadline, reads where the axis stopped.

use std::time::Duration;

use tracing::warn;

use crate::engine::{Link, Task, secs};
use crate::smc100::ChainPolicy;
pub use crate::smc100::{AxisError, MotionError};

/// Why a motion (a home search, a move) ended early: what ending takes is
/// [`settle`]'s.
pub(crate) enum Halt {
    /// A fault at an axis: every stage is stopped first.
    Stop(usize, AxisError),
    /// Axis `.0`'s `.1` (`move`, `home`) to `.2` past the `.3` it was allowed: every
    /// stage is stopped, and the axis' position read.
    Overdue(usize, &'static str, f64, Duration),
    /// Nothing to stop (before any move, or a stage still away from its target): the
    /// error as it is.
    End(MotionError),
}

impl From<MotionError> for Halt {
    fn from(e: MotionError) -> Self {
        Halt::End(e)
    }
}

/// A motion family's session, as the motion written once sees it: axes by index.
pub(crate) trait Motion {
    /// The family, for the log.
    const FAMILY: &'static str;
    /// An axis' status, as a poll reads it.
    type Status;
    /// The pause between status polls.
    fn poll_interval(&self) -> Duration;
    /// Axis `i`'s name.
    fn axis_name(&self, i: usize) -> &str;
    /// `e`, at axis `i`.
    fn at(&self, i: usize, e: AxisError) -> MotionError;
    /// Axis `i`'s status.
    async fn poll_status(&mut self, link: &Link, i: usize) -> Result<Self::Status, AxisError>;
    /// Stops every stage.
    async fn stop_every(&mut self, link: &Link) -> Result<(), MotionError>;
    /// Axis `i`'s position, if it can be read.
    async fn position_of(&mut self, link: &Link, i: usize) -> Option<f64>;
}

/// Polls the status of each of `axes` (with its target) every poll interval, after a
/// pause that is an abort point, while `busy(session, axis, target, status, elapsed)`
/// says it is still on its way; a status that cannot be read stops every stage.
pub(crate) async fn poll<S: Motion>(
    s: &mut S,
    link: &Link,
    mut axes: Vec<(usize, f64)>,
    operation: &str,
    mut busy: impl FnMut(&S, usize, f64, S::Status, Duration) -> Result<bool, Halt>,
) -> Result<(), Halt> {
    let start = link.now();
    while let Some(&(first, _)) = axes.first() {
        pause(s, link, operation).await.map_err(stop(first))?;
        let mut still = Vec::new();
        for (i, target) in axes {
            let status = s.poll_status(link, i).await.map_err(stop(i))?;
            if busy(s, i, target, status, link.now().saturating_sub(start))? {
                still.push((i, target));
            }
        }
        axes = still;
    }
    Ok(())
}

/// How long a move may take: the policy's margin plus its factor times the move's
/// estimated duration, `estimate_s`.
pub(crate) fn allowance(policy: &ChainPolicy, estimate_s: f64) -> Duration {
    let factor = policy.move_factor;
    policy.move_margin.saturating_add(secs(estimate_s * factor))
}

/// The pause between status polls: an abort point.
pub(crate) async fn pause<S: Motion>(s: &S, link: &Link, operation: &str) -> Result<(), AxisError> {
    let until = link.now().saturating_add(s.poll_interval());
    link.poll_pause(until).await.map_err(|_| {
        warn!(family = S::FAMILY, operation, "aborted");
        AxisError::Aborted
    })
}

/// An axis' failure during a motion, which stops every stage.
pub(crate) fn stop(axis: usize) -> impl FnOnce(AxisError) -> Halt {
    move |e| Halt::Stop(axis, e)
}

/// Runs the motion `op` on `s` as the operation `name`, ended as [`settle`] ends it.
pub(crate) fn task<'a, S: Motion + 'a, T: 'a>(
    s: &'a mut S,
    name: &'static str,
    now: Duration,
    op: impl AsyncFnOnce(&mut S, &Link) -> Result<T, Halt> + 'a,
) -> Task<'a, T, MotionError> {
    Task::run(name, now, s, async move |s, link| {
        let r = op(s, link).await;
        settle(s, link, r).await
    })
}

/// The end of a motion: after a fault every stage is stopped, since nothing may keep
/// moving; past a deadline also, and the axis' position read for the error.
pub(crate) async fn settle<S: Motion, T>(
    s: &mut S,
    link: &Link,
    r: Result<T, Halt>,
) -> Result<T, MotionError> {
    match r {
        Ok(v) => Ok(v),
        Err(Halt::End(e)) => Err(e),
        Err(Halt::Stop(i, e)) => {
            let error = s.at(i, e);
            warn!(family = S::FAMILY, %error, "stopping every stage after a fault");
            // The stop's own failure is not the news: the fault is.
            if let Err(e) = s.stop_every(link).await {
                warn!(family = S::FAMILY, error = %e, "the stop after a fault was not sent");
            }
            Err(error)
        }
        Err(Halt::Overdue(i, operation, target, waited)) => {
            let axis = s.axis_name(i);
            warn!(
                family = S::FAMILY,
                axis,
                operation,
                ?waited,
                "past the deadline; stopping every stage"
            );
            let _ = s.stop_every(link).await;
            let position = s.position_of(link, i).await;
            let e = AxisError::Timeout {
                operation,
                target,
                position,
                waited,
            };
            Err(s.at(i, e))
        }
    }
}

/// Named status bits, declared once: a row each, `NAME = value "its name in messages"`
/// under its doc, makes the constant and its row of `NAMES`, the table [`bit_names`]
/// reads. `impl` before the type declares them as associated constants.
macro_rules! status_bits {
    (impl $t:ty; $($(#[$doc:meta])* $name:ident = $v:literal $text:literal,)*) => {
        $($(#[$doc])* pub const $name: $t = $v;)*
        /// Every named bit, with its name for messages.
        pub(crate) const NAMES: &[($t, &str)] = &[$((Self::$name, $text)),*];
    };
    ($t:ty; $($(#[$doc:meta])* $name:ident = $v:literal $text:literal,)*) => {
        $($(#[$doc])* pub const $name: $t = $v;)*
        /// Every named bit, with its name for messages.
        const NAMES: &[($t, &str)] = &[$(($name, $text)),*];
    };
}
pub(crate) use status_bits;

/// The names of the bits set in `bits`, in the order of `names`.
pub(crate) fn bit_names<T>(bits: T, names: &[(T, &'static str)]) -> Vec<&'static str>
where
    T: Copy + Default + PartialEq + std::ops::BitAnd<Output = T>,
{
    names
        .iter()
        .filter(|(m, _)| bits & *m != T::default())
        .map(|(_, n)| *n)
        .collect()
}
