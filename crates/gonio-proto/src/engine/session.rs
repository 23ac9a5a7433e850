//! What every line family's session shares besides the link policy.

use std::time::Duration;

use tracing::{debug, warn};

use super::{Fault, Link};

/// What every line family's session keeps besides its own state: the configuration,
/// the port's name (for errors), the identity set-up read, and the counts a run log
/// reports. A session reaches it through `Deref`, so its getters are written once.
#[derive(Clone, Debug, PartialEq)]
pub struct SessionCore<C, I> {
    pub(crate) config: C,
    pub(crate) port: String,
    pub(crate) identity: Option<I>,
    pub(crate) reconnects: usize,
    pub(crate) retried: u64,
}

impl<C, I> SessionCore<C, I> {
    pub(crate) fn new(config: C, port: impl Into<String>) -> Self {
        SessionCore {
            config,
            port: port.into(),
            identity: None,
            reconnects: 0,
            retried: 0,
        }
    }

    /// The configuration.
    pub fn config(&self) -> &C {
        &self.config
    }

    /// The identity set-up read, once it has run.
    pub fn identity(&self) -> Option<&I> {
        self.identity.as_ref()
    }

    /// How many times the port was reopened.
    pub fn reconnects(&self) -> usize {
        self.reconnects
    }

    /// Commands sent again (or read cycles restarted) after a lost, late or garbled
    /// answer: what a run log reports as retries.
    pub fn retried(&self) -> u64 {
        self.retried
    }
}

/// For `$session`, whose [`SessionCore`]`<$config, $identity>` is its field `core`:
/// `Deref` to the core, and the engine's [`Wire`](super::Wire) from the core and
/// `$error`'s `Transport`, `Disconnected` and `Protocol` variants (a garbled reply,
/// like a lost one, is worth sending again). A reopening is counted, then handed to
/// the session's own `fn reopened(&mut self, now: Duration)` (what it forgets).
///
/// Also writes the family module's `name` (a command as sent, without terminator:
/// how errors and the log name it), `protocol` and `unexpected` (a reply of another
/// kind than the query's, which `Reply::parse` cannot give: a protocol error rather
/// than a panic).
macro_rules! line_session {
    ($session:ty: $family:literal, $config:ty, $identity:ty, $error:ident;
        $command:ty, $reply:ty, $reply_error:ident $(; after_reopen: $first:expr)?) => {
        fn name(command: &$command) -> String {
            let mut body = Vec::new();
            command.encode_body(&mut body);
            String::from_utf8_lossy(&body).into_owned()
        }

        fn protocol(command: &$command, reply: &[u8], source: $reply_error) -> $error {
            let (command, reply) = (name(command), reply.to_vec());
            $error::Protocol { command, reply, source }
        }

        fn unexpected(command: &$command, reply: Option<$reply>) -> $error {
            let reply = reply.map(|r| r.to_bytes()).unwrap_or_default();
            protocol(command, &reply, $reply_error::BadValue)
        }

        impl std::ops::Deref for $session {
            type Target = $crate::engine::SessionCore<$config, $identity>;

            fn deref(&self) -> &Self::Target {
                &self.core
            }
        }

        impl $crate::engine::Wire for $session {
            type Error = $error;
            const FAMILY: &'static str = $family;

            fn policy(&self) -> $crate::engine::Policy {
                $crate::engine::Policy {
                    reconnect_attempts: self.core.config.reconnect_attempts,
                    reconnect_delay: self.core.config.reconnect_delay(),
                }
            }

            fn port(&self) -> &str {
                &self.core.port
            }

            fn transport(command: String, source: $crate::TransportError) -> $error {
                $error::Transport { command, source }
            }

            fn disconnected(&self, attempts: u32, source: $crate::TransportError) -> $error {
                let port = self.core.port.clone();
                $error::Disconnected { port, attempts, source }
            }

            fn is_transient(e: &$error) -> bool {
                match e {
                    $error::Protocol { .. } => true,
                    $error::Transport { source, .. } => source.is_transient(),
                    _ => false,
                }
            }

            fn retried(&mut self) {
                self.core.retried += 1;
            }

            $(fn after_reopen(&self) -> Option<(&'static str, Vec<u8>)> {
                Some($first)
            })?

            fn reopened(&mut self, now: std::time::Duration) {
                self.core.reconnects += 1;
                <$session>::reopened(self, now);
            }
        }
    };
}
pub(crate) use line_session;

/// Lines due by `due`, each read by the family's `rule` (`None`: not part of the
/// answer, such as a blank line or a prompt; `Err`: a refusal or a garbled line),
/// until one ends the answer.
pub(crate) async fn receive<T, E>(
    link: &Link,
    due: Duration,
    mut rule: impl FnMut(&[u8]) -> Option<Result<T, E>>,
) -> Result<T, Fault<E>> {
    loop {
        if let Some(answer) = rule(&link.line(due).await?) {
            return answer.map_err(Fault::Answer);
        }
    }
}

/// A read's count of restarts and range changes, and the errors that end it.
pub(crate) struct Read {
    /// The family, for the log.
    pub(crate) family: &'static str,
    /// Consecutive restarts: only these count towards giving up.
    pub(crate) restarts: usize,
    /// Range changes made.
    pub(crate) steps: usize,
}

/// Most times one read starts over in a row after the port was lost and reopened (or,
/// on the SR830, the flags' answer was lost).
pub(crate) const MAX_RESTARTS: usize = 2;

impl Read {
    pub(crate) fn new(family: &'static str) -> Self {
        Read {
            family,
            restarts: 0,
            steps: 0,
        }
    }

    /// One more restart: `interrupted(restarts)` once that has happened more than
    /// [`MAX_RESTARTS`] times in a row.
    pub(crate) fn restart<E>(&mut self, interrupted: impl FnOnce(usize) -> E) -> Result<(), E> {
        self.restarts += 1;
        let (family, restarts) = (self.family, self.restarts);
        if restarts > MAX_RESTARTS {
            warn!(restarts, "{family}: reading interrupted too often");
            return Err(interrupted(restarts));
        }
        debug!(restarts, "{family}: read starts again");
        Ok(())
    }

    /// Whether `max` range changes have been made: autoranging gives up (logged).
    pub(crate) fn exhausted(&self, max: usize) -> bool {
        let done = self.steps >= max;
        if done {
            warn!(steps = self.steps, "{}: autorange gives up", self.family);
        }
        done
    }
}
