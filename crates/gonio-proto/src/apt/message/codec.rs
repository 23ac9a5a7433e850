//! The machinery behind the table of messages in `mod.rs`: the [`messages!`] macro
//! that makes of one row per message its variant, id, name, sender, form and data
//! layout, and the framing both directions share (the header with its addresses, the
//! checks of a whole message against its id's form).

use super::params::{Data, DcStatus, Rd};
use super::{AptError, Header, Message, Packet};
use crate::apt::{HEADER_LEN, HOST, LONG_FLAG, MAX_DATA_LEN, USB_UNIT};

/// What a known message looks like on the wire.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(in crate::apt) enum Form {
    /// Header only.
    Short,
    /// A data packet of this length.
    Long(u16),
    /// Either header only or this data packet (moves, completions).
    Either(u16),
    /// A data packet of either length (the stepper status: 14 or 28 bytes).
    Lengths(u16, u16),
}

impl Form {
    /// True when a header of `data_len` fits.
    pub(in crate::apt) fn admits(self, data_len: Option<u16>) -> bool {
        match (self, data_len) {
            (Form::Short, None) | (Form::Either(_), None) => true,
            (Form::Long(n) | Form::Either(n), Some(l)) => n == l,
            (Form::Lengths(a, b), Some(l)) => l == a || l == b,
            _ => false,
        }
    }
}

/// A message's body as written: a short message's two parameter bytes, or a data packet.
pub(super) enum Body {
    Short([u8; 2]),
    Long(Vec<u8>),
}

/// The parameter bytes of a short message, in order, zero where absent.
pub(super) fn short(p: &[u8]) -> Body {
    Body::Short([0, 1].map(|i| p.get(i).copied().unwrap_or(0)))
}

/// The fields of a long message, in order.
pub(super) fn long(fields: &[&dyn Data]) -> Body {
    let mut data = Vec::new();
    for f in fields {
        f.put(&mut data);
    }
    Body::Long(data)
}

/// A channel as a short message's parameter byte (255 for any channel beyond it,
/// which has no short form).
pub(super) fn short_chan(chan: u16) -> u8 {
    u8::try_from(chan).unwrap_or(u8::MAX)
}

/// A short header's first parameter byte as a long form's channel word.
pub(super) fn chan_of(h: &Header) -> u16 {
    u16::from(h.params[0])
}

/// The status that ends a move carries the channel of the long form.
pub(super) fn ended_status(r: &mut Rd<'_>) -> (u16, DcStatus) {
    let s = DcStatus::get(r);
    (s.chan, s)
}

/// One row per message makes the enum [`Message`] (each variant's doc begins with its
/// manual name and id) and, from the same row, its id constant (the manual's name
/// without `MGMSG_`), [`Message::id`], [`Message::name`], the sender
/// ([`Message::from_controller`]), the form on the wire (`form_of`), and the writing
/// and reading of its body. A row is
///
/// `Variant { fields } = NAME 0xID sender kind;`, or `Variant(binding: Type) = ...`
///
/// where `sender` is `host` or `controller` and `kind` says how the fields lie:
/// `short` (each field a parameter byte, [`ShortField`]), `long(n)` or `lengths(a, b)`
/// (each field a [`Data`] of the packet, in order), `either(n)` (`{ chan, value }`:
/// short without the value, the channel and value with it) or `ended(n)`
/// (`{ chan, status }`: short without the status, the status alone with it).
macro_rules! messages {
    ($(
        $(#[$doc:meta])*
        $v:ident
        $({ $($(#[$fdoc:meta])* $f:ident: $ft:ty,)* })?
        $(($tf:ident: $tt:ty))?
        = $id:ident $val:literal $from:ident $kind:ident $(($($n:literal),*))?;
    )*) => {
        /// One APT message, typed: what the sessions send and read, and what the
        /// simulated controllers read and send. Parameters that the manual marks unused
        /// are written as 0 and ignored when read.
        #[derive(Debug, Clone, PartialEq, Eq)]
        pub enum Message {
            $(
                #[doc = concat!("`", stringify!($id), "` `", stringify!($val), "`.")]
                $(#[$doc])*
                $v $({ $($(#[$fdoc])* $f: $ft,)* })? $(($tt))?,
            )*
            /// A message this codec does not know, kept whole so that it can be skipped
            /// (or relayed) rather than taken for garbage.
            Unknown {
                /// The id.
                id: u16,
                /// The parameter bytes (short form).
                params: [u8; 2],
                /// The data packet (long form).
                data: Option<Vec<u8>>,
            },
        }

        /// The message ids, the manual's `MGMSG_` names without the prefix.
        pub(in crate::apt) mod id {
            $(pub const $id: u16 = $val;)*
        }

        /// The form of a known message id; `None` for an id this codec does not know.
        pub(in crate::apt) fn form_of(message_id: u16) -> Option<$crate::apt::message::codec::Form> {
            use $crate::apt::message::codec::Form;
            match message_id {
                $(id::$id => Some(messages!(@form $kind $(($($n),*))?)),)*
                _ => None,
            }
        }

        /// The manual's name of a known message id.
        pub(in crate::apt) fn name_of(message_id: u16) -> Option<&'static str> {
            match message_id {
                $(id::$id => Some(stringify!($id)),)*
                _ => None,
            }
        }

        impl Message {
            /// The message id.
            pub fn id(&self) -> u16 {
                match self {
                    $(Message::$v { .. } => id::$id,)*
                    Message::Unknown { id, .. } => *id,
                }
            }

            /// The manual's name, without `MGMSG_` (`MOT_MOVE_ABSOLUTE`), for logs and
            /// errors.
            pub fn name(&self) -> &'static str {
                match self {
                    $(Message::$v { .. } => stringify!($id),)*
                    Message::Unknown { .. } => "unknown",
                }
            }

            /// True for what a controller sends (replies, notifications), false for what
            /// a host sends; it decides the addresses [`encode`](Self::encode) writes.
            pub fn from_controller(&self) -> bool {
                match self {
                    $(Message::$v { .. } => messages!(@from $from),)*
                    Message::Unknown { .. } => false,
                }
            }

            /// The parameter bytes or the data packet.
            fn body(&self) -> $crate::apt::message::codec::Body {
                use $crate::apt::message::codec::*;
                use $crate::apt::message::params::ShortField;
                match self {
                    $(
                        Message::$v $({ $($f),* })? $(($tf))? =>
                            messages!(@put $kind; $($($f),*)? $($tf)?),
                    )*
                    Message::Unknown { params, data: None, .. } => short(params),
                    Message::Unknown { data: Some(d), .. } => Body::Long(d.clone()),
                }
            }

            /// A known message from its header and data packet (checked against its
            /// form); refuses a parameter byte the manual does not define.
            fn from_wire(h: &Header, data: &[u8]) -> Result<Message, AptError> {
                use $crate::apt::message::codec::*;
                use $crate::apt::message::params::{Data, Rd, ShortField};
                let r = &mut Rd { b: data };
                Ok(match h.id {
                    $(id::$id => messages!(@get $kind, $v, h, r, $({ $($f),* })? $(($tf))?),)*
                    // `form_of` knows exactly the ids matched above.
                    _ => unknown(h, data),
                })
            }
        }
    };

    (@form short) => { Form::Short };
    (@form long($n:literal)) => { Form::Long($n) };
    (@form lengths($a:literal, $b:literal)) => { Form::Lengths($a, $b) };
    (@form either($n:literal)) => { Form::Either($n) };
    (@form ended($n:literal)) => { Form::Either($n) };

    (@from host) => { false };
    (@from controller) => { true };

    (@put short; $($f:ident),*) => { short(&[$(ShortField::byte($f)),*]) };
    (@put long; $($f:ident),*) => { long(&[$($f),*]) };
    (@put lengths; $($f:ident),*) => { long(&[$($f),*]) };
    (@put either; $chan:ident, $value:ident) => {
        match $value {
            None => short(&[short_chan(*$chan)]),
            Some(v) => long(&[$chan, v]),
        }
    };
    (@put ended; $chan:ident, $status:ident) => {
        match $status {
            None => short(&[short_chan(*$chan)]),
            Some(s) => long(&[s]),
        }
    };

    (@get short, $v:ident, $h:ident, $r:ident, ) => { Message::$v };
    (@get short, $v:ident, $h:ident, $r:ident, { $($f:ident),* }) => {{
        let mut p = $h.params.into_iter();
        Message::$v { $($f: ShortField::from_byte($h.id, p.next().unwrap_or(0))?),* }
    }};
    (@get $kind:ident, $v:ident, $h:ident, $r:ident, ($tf:ident)) => {
        Message::$v(Data::get($r))
    };
    (@get either, $v:ident, $h:ident, $r:ident, { $chan:ident, $value:ident }) => {
        match $h.data_len {
            None => Message::$v { $chan: chan_of($h), $value: None },
            Some(_) => Message::$v { $chan: Data::get($r), $value: Some(Data::get($r)) },
        }
    };
    (@get ended, $v:ident, $h:ident, $r:ident, { $chan:ident, $status:ident }) => {
        match $h.data_len {
            None => Message::$v { $chan: chan_of($h), $status: None },
            Some(_) => {
                let ($chan, s) = ended_status($r);
                Message::$v { $chan, $status: Some(s) }
            }
        }
    };
    (@get $kind:ident, $v:ident, $h:ident, $r:ident, { $($f:ident),* }) => {
        Message::$v { $($f: Data::get($r)),* }
    };
}
pub(super) use messages;

impl Message {
    /// Writes the message between a host and a USB unit: host (`0x01`) to unit
    /// (`0x50`) for what a host sends, unit to host for what a controller sends.
    pub fn encode(&self, out: &mut Vec<u8>) {
        let (dest, source) = if self.from_controller() {
            (HOST, USB_UNIT)
        } else {
            (USB_UNIT, HOST)
        };
        self.encode_to(dest, source, out);
    }

    /// The message as bytes, addressed as [`encode`](Self::encode) does.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::new();
        self.encode(&mut out);
        out
    }

    /// Writes the message from `source` to `dest`.
    pub fn encode_to(&self, dest: u8, source: u8, out: &mut Vec<u8>) {
        out.extend_from_slice(&self.id().to_le_bytes());
        match self.body() {
            Body::Short(params) => {
                out.extend_from_slice(&params);
                out.extend_from_slice(&[dest & !LONG_FLAG, source]);
            }
            Body::Long(mut data) => {
                // Every data packet built is at most 84 bytes, and an unknown message's
                // came from a parsed header; a longer one is cut rather than mis-framed.
                data.truncate(usize::from(u16::MAX));
                let len = u16::try_from(data.len()).unwrap_or(u16::MAX);
                out.extend_from_slice(&len.to_le_bytes());
                out.extend_from_slice(&[dest | LONG_FLAG, source]);
                out.extend_from_slice(&data);
            }
        }
    }

    /// Parses one whole message (header and data packet, nothing more), ignoring its
    /// addresses. See [`Packet::parse`] for them.
    pub fn parse(bytes: &[u8]) -> Result<Message, AptError> {
        Packet::parse(bytes).map(|p| p.message)
    }
}

impl Packet {
    /// The message as bytes.
    pub fn encode(&self, out: &mut Vec<u8>) {
        self.message.encode_to(self.dest, self.source, out);
    }

    /// Parses one whole message (header and data packet, nothing more).
    pub fn parse(bytes: &[u8]) -> Result<Packet, AptError> {
        let h = framed(bytes)?;
        let data = &bytes[HEADER_LEN..];
        let message = match super::form_of(h.id) {
            None => unknown(&h, data),
            Some(form) => {
                check_form(&h, form)?;
                Message::from_wire(&h, data)?
            }
        };
        Ok(Packet {
            dest: h.dest,
            source: h.source,
            message,
        })
    }
}

/// The header of `bytes` when they are exactly one message: a data length within
/// [`MAX_DATA_LEN`], and as many bytes as the header says, no fewer, no more.
fn framed(bytes: &[u8]) -> Result<Header, AptError> {
    let h = Header::parse(bytes)?;
    if let Some(n) = h.data_len
        && usize::from(n) > MAX_DATA_LEN
    {
        return Err(AptError::TooLong(usize::from(n)));
    }
    let total = h.total_len();
    if bytes.len() < total {
        return Err(AptError::Truncated {
            need: total,
            got: bytes.len(),
        });
    }
    if bytes.len() > total {
        return Err(AptError::Trailing {
            extra: bytes.len() - total,
        });
    }
    Ok(h)
}

/// A message this codec does not know (or, by `form_of`, cannot be), kept whole so
/// that it passes through.
pub(super) fn unknown(h: &Header, data: &[u8]) -> Message {
    Message::Unknown {
        id: h.id,
        params: h.params,
        data: h.data_len.map(|_| data.to_vec()),
    }
}

/// Refuses a known message whose header is not of its id's form.
fn check_form(h: &Header, form: Form) -> Result<(), AptError> {
    if form.admits(h.data_len) {
        return Ok(());
    }
    let (expected, wanted) = match form {
        Form::Short => ("a short message", "a short message".into()),
        Form::Long(n) => (
            "a long message of its data length",
            format!("{n} data bytes"),
        ),
        Form::Either(n) => (
            "a short message or a long one of its data length",
            format!("a short message or {n} data bytes"),
        ),
        Form::Lengths(a, b) => (
            "a long message of one of its data lengths",
            format!("{a} or {b} data bytes"),
        ),
    };
    Err(AptError::Form {
        id: h.id,
        expected,
        found: match h.data_len {
            None => "a short message".into(),
            Some(n) => format!("{n} data bytes (wanted {wanted})"),
        },
    })
}
