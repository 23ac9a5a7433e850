//! One command on a line, with the link policy every family shares: send; receive
//! (the family's part); after a fault, clear the input and send again while the fault
//! may be retried; reopen a vanished port after a pause, a bounded number of times.

use std::time::Duration;

use tracing::{debug, warn};

use super::Link;
use crate::link::TransportError;

/// A family's link policy, from its configuration.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Policy {
    /// Reopenings of a vanished port allowed per command.
    pub(crate) reconnect_attempts: u32,
    /// The pause before each reopening.
    pub(crate) reconnect_delay: Duration,
}

/// Why one attempt at an exchange failed.
#[derive(Debug)]
pub(crate) enum Fault<E> {
    /// The link failed: a vanished port is reopened, anything else is the family's
    /// transport error.
    Link(TransportError),
    /// The answer was refused or garbled: the family's error.
    Answer(E),
}

impl<E> From<TransportError> for Fault<E> {
    fn from(e: TransportError) -> Self {
        Fault::Link(e)
    }
}

/// What the engine needs of a session to run its exchanges.
pub(crate) trait Wire {
    /// The session's error.
    type Error: std::fmt::Display;
    /// The family, for the log (`fw102c`).
    const FAMILY: &'static str;
    /// The link policy.
    fn policy(&self) -> Policy;
    /// The port's name, for the log.
    fn port(&self) -> &str;
    /// A link fault during `command`.
    fn transport(command: String, source: TransportError) -> Self::Error;
    /// The port lost for good after `attempts` reopenings.
    fn disconnected(&self, attempts: u32, source: TransportError) -> Self::Error;
    /// Whether sending the command again may cure `e` (a lost, late or garbled answer).
    fn is_transient(e: &Self::Error) -> bool;
    /// Counts one command sent again.
    fn retried(&mut self);
    /// What must be sent first on a reopened port, with its name (the SR830's
    /// `OUTX 0`); `None` for nothing.
    fn after_reopen(&self) -> Option<(&'static str, Vec<u8>)> {
        None
    }
    /// The port was reopened (and `after_reopen` sent): the device may have been
    /// power-cycled meanwhile, so forget what the session knew of its state.
    fn reopened(&mut self, now: Duration);
}

/// Sends `bytes` (named `command`) and returns what `receive` makes of the answer
/// (given the session, to note what it changes), sending again up to `retries` times
/// after a transient fault and reopening a vanished port as [`Policy`] allows.
pub(crate) async fn exchange<S: Wire, T>(
    s: &mut S,
    link: &Link,
    command: &str,
    bytes: &[u8],
    mut retries: u32,
    mut receive: impl AsyncFnMut(&mut S) -> Result<T, Fault<S::Error>>,
) -> Result<T, S::Error> {
    let policy = s.policy();
    let mut budget = policy.reconnect_attempts;
    loop {
        let attempt = match link.send(bytes.to_vec()).await {
            Ok(()) => receive(&mut *s).await,
            Err(e) => Err(Fault::Link(e)),
        };
        let e = match attempt {
            Ok(v) => return Ok(v),
            Err(Fault::Link(lost @ TransportError::Disconnected { .. })) => {
                reopen(s, link, command, &mut budget, lost).await?;
                continue;
            }
            Err(Fault::Link(e)) => S::transport(command.to_string(), e),
            Err(Fault::Answer(e)) => e,
        };
        link.clear_input();
        if retries > 0 && S::is_transient(&e) {
            warn!(family = S::FAMILY, command, error = %e, "no usable reply; sending again");
            retries -= 1;
            s.retried();
            continue;
        }
        warn!(family = S::FAMILY, command, error = %e, "command failed");
        return Err(e);
    }
}

/// Reopens the port after a pause, as often as `budget` allows, and sends what the
/// session needs first on a reopened port.
async fn reopen<S: Wire>(
    s: &mut S,
    link: &Link,
    command: &str,
    budget: &mut u32,
    mut lost: TransportError,
) -> Result<(), S::Error> {
    let policy = s.policy();
    loop {
        if *budget == 0 {
            warn!(family = S::FAMILY, port = %s.port(), "port lost; no reconnection left");
            return Err(s.disconnected(policy.reconnect_attempts, lost));
        }
        *budget -= 1;
        warn!(family = S::FAMILY, port = %s.port(), error = %lost, "port lost; reopening it after a pause");
        link.sleep(link.now().saturating_add(policy.reconnect_delay))
            .await;
        let first = s.after_reopen();
        let name = first.as_ref().map_or(command, |(name, _)| name);
        let reopened = match link.reconnect().await {
            Ok(()) => match &first {
                Some((_, bytes)) => link.send(bytes.clone()).await,
                None => Ok(()),
            },
            Err(e) => Err(e),
        };
        match reopened {
            Ok(()) => {
                s.reopened(link.now());
                debug!(family = S::FAMILY, port = %s.port(), "port reopened");
                return Ok(());
            }
            Err(e @ TransportError::Disconnected { .. }) => lost = e,
            Err(e) => return Err(S::transport(name.to_string(), e)),
        }
    }
}

/// Reopens a vanished port the motion controllers' way: at once, then up to
/// `attempts` more times, `delay` apart; the last failure is the error.
pub(crate) async fn reopen_at_once(
    link: &Link,
    family: &'static str,
    attempts: usize,
    delay: Duration,
    lost: &TransportError,
) -> Result<(), TransportError> {
    warn!(family, error = %lost, "port lost; reopening it");
    let mut attempt = 0;
    while let Err(e) = link.reconnect().await {
        if attempt >= attempts {
            warn!(family, attempts = attempt + 1, error = %e, "port still gone; giving up");
            return Err(e);
        }
        attempt += 1;
        warn!(family, attempt, error = %e, "reopening the port failed");
        link.sleep(link.now().saturating_add(delay)).await;
    }
    debug!(family, "port reopened");
    Ok(())
}

/// Sends `bytes`; a vanished port is reopened ([`reopen_at_once`]) and the bytes sent
/// once more: they never left, so even a command that may not be repeated may go.
pub(crate) async fn send_reopening(
    link: &Link,
    family: &'static str,
    attempts: usize,
    delay: Duration,
    bytes: &[u8],
) -> Result<(), TransportError> {
    match link.send(bytes.to_vec()).await {
        Err(lost @ TransportError::Disconnected { .. }) => {
            reopen_at_once(link, family, attempts, delay, &lost).await?;
            link.send(bytes.to_vec()).await
        }
        r => r,
    }
}
