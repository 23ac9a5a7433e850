//! What Gonio relies on about an instrument that no manual page checked confirms.
//!
//! Each family module lists its own ([`smc100::UNCONFIRMED`](crate::smc100::UNCONFIRMED)
//! and the others'); `docs/instruments/<family>.md` keeps the same list, and
//! `gonio instrument check --connect` names it for every device it finds, so that a lab
//! knows what to look at on its own hardware before it relies on it.

/// A fact taken without a source, and how to check it on the instrument.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct Unconfirmed {
    /// What Gonio assumes, as `docs/instruments/<family>.md` words it.
    pub fact: &'static str,
    /// What to do on the instrument to settle it.
    pub check: &'static str,
}

/// A family's list of [`Unconfirmed`] facts, written `"fact" => "check",` each.
macro_rules! unconfirmed {
    ($($fact:literal => $check:literal,)*) => {
        &[$($crate::Unconfirmed { fact: $fact, check: $check }),*]
    };
}
pub(crate) use unconfirmed;
