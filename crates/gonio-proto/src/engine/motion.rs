//! The motion written once over the motion families (SMC100, APT), each a
//! [`Motion`]: the polling of moving axes with a pause that is an abort point, and
//! the end of a motion that failed, which stops every stage and, past a deadline,
//! reads where the axis stopped. Generic over the family's errors, so that the
//! families' modules use it without it using them.

use std::time::Duration;

use tracing::warn;

use super::{Link, Task};

/// The [`Halt`] of a family's session `S`.
pub(crate) type HaltOf<S> = Halt<<S as Motion>::AxisError, <S as Motion>::Error>;

/// Why a motion (a home search, a move) ended early: what ending takes is
/// [`settle`]'s.
pub(crate) enum Halt<A, E> {
    /// A fault at an axis: every stage is stopped first.
    Stop(usize, A),
    /// Axis `.0`'s `.1` (`move`, `home`) to `.2` past the `.3` it was allowed: every
    /// stage is stopped, and the axis' position read.
    Overdue(usize, &'static str, f64, Duration),
    /// Nothing to stop (before any move, or a stage still away from its target): the
    /// error as it is.
    End(E),
}

impl<A, E> From<E> for Halt<A, E> {
    fn from(e: E) -> Self {
        Halt::End(e)
    }
}

/// What the motion written once makes of a family's axis error: the operator's
/// abort, and an operation past its deadline.
pub(crate) trait AxisFault {
    /// The operator aborted at a pause.
    fn aborted() -> Self;
    /// `operation` to `target` not done after `waited`, the axis read at `position`.
    fn overdue(
        operation: &'static str,
        target: f64,
        position: Option<f64>,
        waited: Duration,
    ) -> Self;
}

/// A motion family's session, as the motion written once sees it: axes by index.
pub(crate) trait Motion {
    /// The family, for the log.
    const FAMILY: &'static str;
    /// An axis' status, as a poll reads it.
    type Status;
    /// A fault at one axis.
    type AxisError: AxisFault + std::fmt::Display;
    /// A fault naming its axis, what an operation returns.
    type Error: std::fmt::Display;
    /// The pause between status polls.
    fn poll_interval(&self) -> Duration;
    /// Axis `i`'s name.
    fn axis_name(&self, i: usize) -> &str;
    /// `e`, at axis `i`.
    fn at(&self, i: usize, e: Self::AxisError) -> Self::Error;
    /// Axis `i`'s status.
    async fn poll_status(&mut self, link: &Link, i: usize)
    -> Result<Self::Status, Self::AxisError>;
    /// Stops every stage.
    async fn stop_every(&mut self, link: &Link) -> Result<(), Self::Error>;
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
    mut busy: impl FnMut(&S, usize, f64, S::Status, Duration) -> Result<bool, HaltOf<S>>,
) -> Result<(), HaltOf<S>> {
    let start = link.now();
    while let Some(&(first, _)) = axes.first() {
        pause(s, link, operation)
            .await
            .map_err(|e| Halt::Stop(first, e))?;
        let mut still = Vec::new();
        for (i, target) in axes {
            let status = s.poll_status(link, i).await.map_err(|e| Halt::Stop(i, e))?;
            if busy(s, i, target, status, link.now().saturating_sub(start))? {
                still.push((i, target));
            }
        }
        axes = still;
    }
    Ok(())
}

/// The pause between status polls: an abort point.
pub(crate) async fn pause<S: Motion>(
    s: &S,
    link: &Link,
    operation: &str,
) -> Result<(), S::AxisError> {
    let until = link.now().saturating_add(s.poll_interval());
    link.poll_pause(until).await.map_err(|_| {
        warn!(family = S::FAMILY, operation, "aborted");
        S::AxisError::aborted()
    })
}

/// Runs the motion `op` on `s` as the operation `name`, ended as [`settle`] ends it.
pub(crate) fn task<'a, S: Motion + 'a, T: 'a>(
    s: &'a mut S,
    name: &'static str,
    now: Duration,
    op: impl AsyncFnOnce(&mut S, &Link) -> Result<T, HaltOf<S>> + 'a,
) -> Task<'a, T, S::Error> {
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
    r: Result<T, HaltOf<S>>,
) -> Result<T, S::Error> {
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
            Err(s.at(
                i,
                S::AxisError::overdue(operation, target, position, waited),
            ))
        }
    }
}
