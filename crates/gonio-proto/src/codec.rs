//! What the line families' codecs (SR830, Keithley 6485, Cornerstone 130, FW102C)
//! share, written once: a line's encoding from its body and terminator, the fuzz
//! bodies' round trips, the manuals' coded enums, status registers as bit tables, and
//! the instruments' tables of ranges indexed by number.

use std::fmt::{self, Debug};

/// A command or reply that writes itself as the body of a line (no terminator).
pub(crate) trait Encode {
    /// Appends the body.
    fn encode_body(&self, out: &mut Vec<u8>);

    /// The body as bytes.
    fn body(&self) -> Vec<u8> {
        let mut v = Vec::new();
        self.encode_body(&mut v);
        v
    }
}

/// True when `line` is the echo of `command`: its body, case ignored (both echoing
/// instruments send back what they received).
pub(crate) fn echoes(command: &impl Encode, line: &[u8]) -> bool {
    line.eq_ignore_ascii_case(&command.body())
}

/// Gives a type with an inherent `encode_body` its `encode` and `to_bytes` (the body
/// and `$terminator`) and the [`Encode`] the fuzz bodies use.
macro_rules! line_encoding {
    ($ty:ty, $terminator:expr) => {
        impl $ty {
            /// Appends the line, terminator included (what goes on the wire).
            pub fn encode(&self, out: &mut Vec<u8>) {
                self.encode_body(out);
                out.extend_from_slice($terminator);
            }

            /// The line as bytes, terminator included.
            pub fn to_bytes(&self) -> Vec<u8> {
                let mut v = Vec::new();
                self.encode(&mut v);
                v
            }
        }

        impl $crate::codec::Encode for $ty {
            fn encode_body(&self, out: &mut Vec<u8>) {
                <$ty>::encode_body(self, out)
            }
        }
    };
}
pub(crate) use line_encoding;

/// What a fuzz body asserts of a value that parsed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum RoundTrip {
    /// Its encoding parses back to it.
    Exact,
    /// Its encoding parses and encodes to the same bytes: the first encoding may round
    /// (7 significant digits, three decimals).
    Stable,
}

/// The command fuzz body: every command `parse` reads from `data` is encoded, and its
/// body must parse back as that one command (or one encoding to the same bytes).
pub(crate) fn fuzz_commands<C, E>(
    data: &[u8],
    parse: impl Fn(&[u8]) -> Vec<Result<C, E>>,
    check: RoundTrip,
) where
    C: Encode + PartialEq + Debug,
    E: PartialEq + Debug,
{
    for command in parse(data).into_iter().flatten() {
        let body = command.body();
        let again = parse(&body);
        match (check, again.as_slice()) {
            (RoundTrip::Exact, _) => assert_eq!(again, vec![Ok(command)], "re-parse of {body:?}"),
            (RoundTrip::Stable, [Ok(again)]) => {
                assert_eq!(again.body(), body, "re-encode of {body:?}")
            }
            (RoundTrip::Stable, _) => panic!("re-parse of {body:?}: {again:?}"),
        }
    }
}

/// The reply fuzz body: `data[1..]` is parsed as the answer to the query `data[0]`
/// picks from `queries`; an answer that parses is encoded, and its body must parse
/// back as `check` says.
pub(crate) fn fuzz_replies<Q, R, E>(
    data: &[u8],
    queries: &[Q],
    parse: impl Fn(&Q, &[u8]) -> Result<R, E>,
    check: RoundTrip,
) where
    R: Encode + PartialEq + Debug,
    E: PartialEq + Debug,
{
    let Some((&selector, line)) = data.split_first() else {
        return;
    };
    let query = &queries[usize::from(selector) % queries.len()];
    if let Ok(reply) = parse(query, line) {
        let body = reply.body();
        match check {
            RoundTrip::Exact => assert_eq!(parse(query, &body), Ok(reply), "re-parse of {body:?}"),
            RoundTrip::Stable => {
                let again =
                    parse(query, &body).unwrap_or_else(|e| panic!("re-parse of {body:?}: {e:?}"));
                assert_eq!(again.body(), body, "re-encode of {body:?}");
            }
        }
    }
}

/// An enum whose variants a manual numbers (`OUTX 0|1`, `speed=0|1`, `SYST:LFR?`
/// 50|60): each variant's number is its discriminant. Generates `ALL` and the two
/// named conversions, `$code(self)` and `$from(number)`.
macro_rules! coded_enum {
    (
        $(#[$meta:meta])*
        pub enum $name:ident: $repr:ty, $code:ident / $from:ident {
            $( $(#[$vmeta:meta])* $variant:ident = $value:literal, )+
        }
    ) => {
        $(#[$meta])*
        pub enum $name {
            $( $(#[$vmeta])* $variant = $value, )+
        }

        impl $name {
            /// Every value, in the manual's order.
            pub const ALL: [$name; [$($value),+].len()] = [$($name::$variant),+];

            /// The number on the wire.
            pub fn $code(self) -> $repr {
                self as $repr
            }

            /// The value a number stands for, if the manual lists it.
            pub fn $from(code: $repr) -> Option<Self> {
                Self::ALL.into_iter().find(|v| v.$code() == code)
            }
        }
    };
}
pub(crate) use coded_enum;

/// A status register as its manual's table lists it: one row per named bit (its
/// constant, mask and mnemonic). Generates the newtype, the constants, `has` (`any`:
/// true when a bit of the mask is set; `all`: when every one is), `is_empty`, and a
/// `Display` naming the set bits (`FILTR|UNLK`, unnamed ones in hex, `none`).
macro_rules! status_register {
    (
        $(#[$meta:meta])*
        pub struct $name:ident($repr:ty), has: $has:ident {
            $( $(#[$bmeta:meta])* $bit:ident = $mask:expr, $label:literal; )+
        }
    ) => {
        $(#[$meta])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
        pub struct $name(pub $repr);

        impl $name {
            $( $(#[$bmeta])* pub const $bit: $repr = $mask; )+

            const NAMES: &'static [($repr, &'static str)] = &[$((Self::$bit, $label)),+];

            $crate::codec::status_register!(@has $has $repr);

            /// True when no bit is set.
            pub fn is_empty(self) -> bool {
                self.0 == 0
            }
        }

        impl std::fmt::Display for $name {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                $crate::codec::write_bits(f, self.0, Self::NAMES)
            }
        }
    };
    (@has any $repr:ty) => {
        /// True when any bit of `mask` is set.
        pub fn has(self, mask: $repr) -> bool {
            self.0 & mask != 0
        }
    };
    (@has all $repr:ty) => {
        /// True when every bit of `mask` is set.
        pub fn has(self, mask: $repr) -> bool {
            self.0 & mask == mask
        }
    };
}
pub(crate) use status_register;

/// Writes the names of the set bits of `value`, `|`-separated, then any unnamed set
/// bits in hex (as wide as the register), or `none`.
pub(crate) fn write_bits<T>(
    f: &mut fmt::Formatter<'_>,
    value: T,
    names: &[(T, &str)],
) -> fmt::Result
where
    T: Copy + Into<u32>,
{
    let value: u32 = value.into();
    let mut parts: Vec<String> = names
        .iter()
        .filter(|(mask, _)| value & (*mask).into() != 0)
        .map(|(_, name)| name.to_string())
        .collect();
    let unnamed = value & !names.iter().fold(0, |acc, (m, _)| acc | (*m).into());
    if unnamed != 0 {
        let width = 2 * std::mem::size_of::<T>();
        parts.push(format!("0x{unnamed:0width$X}"));
    }
    if parts.is_empty() {
        return f.write_str("none");
    }
    f.write_str(&parts.join("|"))
}

/// A table of the manual's indexed by number (`SENS 0..=26`, the 6485's ranges),
/// labelled by `$labels` in index order. Generates the ordered newtype with `COUNT`,
/// `new`, `all`, `index`, a `Display` of the label and a `FromStr` reading it back
/// ([`find_label`]), which refuses with `$unknown`.
macro_rules! index_table {
    (
        $(#[$meta:meta])*
        pub struct $name:ident, labels: $labels:ident, unknown: $err:ty = |$text:ident| $unknown:expr;
    ) => {
        $(#[$meta])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
        pub struct $name(u8);

        impl $name {
            /// Number of entries.
            pub const COUNT: u8 = $labels.len() as u8;

            /// The entry with index `index`, if the table has it.
            pub fn new(index: u8) -> Option<Self> {
                (index < Self::COUNT).then_some($name(index))
            }

            /// Every entry, by index.
            pub fn all() -> impl Iterator<Item = $name> {
                (0..Self::COUNT).map($name)
            }

            /// The index.
            pub fn index(self) -> u8 {
                self.0
            }

        }

        impl std::str::FromStr for $name {
            type Err = $err;

            /// Reads a label as `Display` writes it (`"10 mV"`), by `find_label`'s rule.
            fn from_str($text: &str) -> Result<Self, Self::Err> {
                $crate::codec::find_label(&$labels, $text).map($name).ok_or_else(|| $unknown)
            }
        }

        impl std::fmt::Display for $name {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str($labels[usize::from(self.0)])
            }
        }
    };
}
pub(crate) use index_table;

/// Finds `text` among `labels`, ignoring spaces, and accepting `u` or the Greek `μ`
/// for the micro sign `µ`. Prefixes stay case-sensitive (`mV` is not `MV`).
pub(crate) fn find_label(labels: &[&str], text: &str) -> Option<u8> {
    let norm = |s: &str| -> String {
        s.chars()
            .filter(|c| !c.is_whitespace())
            .map(|c| if matches!(c, 'u' | 'μ') { 'µ' } else { c })
            .collect()
    };
    let want = norm(text);
    let i = labels.iter().position(|l| norm(l) == want)?;
    u8::try_from(i).ok()
}

/// Splits a received line into its commands as the SCPI-style instruments read it:
/// `;`-separated, and `\r` and `\n` inside also separate (either ends a line on
/// RS-232); `parse` returns `None` for an empty command, which is skipped.
pub(crate) fn parse_commands<T>(line: &[u8], parse: impl FnMut(&[u8]) -> Option<T>) -> Vec<T> {
    line.split(|b| matches!(b, b';' | b'\r' | b'\n'))
        .filter_map(parse)
        .collect()
}

/// Why a parameter (or its absence) does not fit its command's row.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Refusal {
    /// Not a parameter of this form at all (missing, extra, not a number).
    Syntax,
    /// The right form, outside the allowed values.
    OutOfRange,
    /// No row of this shape: the family reports the command as unknown.
    Unknown,
}

/// A command's parameter in one family's grammar: written after its mnemonic (with its
/// separator), read from `I`, the family's view of the received parameters. `()` is
/// the rule for a command that takes none.
pub(crate) trait Param<I>: Sized {
    /// Appends the separator and the parameter.
    fn write(&self, out: &mut Vec<u8>);
    /// Reads the parameter.
    fn read(input: I) -> Result<Self, Refusal>;
}

/// A family's command set as the manual's table: one row per command, its variant
/// (with at most one parameter), its mnemonic, `query` or `set`, and optionally
/// `read: f` for a row whose parameter has its own bounds (`f(input)`). Generates the
/// enum, `MNEMONICS`, the mnemonic accessor (`$mnemonic`), `is_query`, the encoding
/// (`encode_row`) and `from_row`, which reads a received command's
/// parameters once the family's grammar has found its mnemonic and query flag.
macro_rules! command_table {
    (
        $(#[$meta:meta])*
        pub enum $name:ident, $mnemonic:ident, input: $input:ty {
            $(
                $(#[$vmeta:meta])*
                $variant:ident $(($field:ty))? = $mnem:literal $kind:ident $(, read: $read:expr)?;
            )+
        }
    ) => {
        $(#[$meta])*
        pub enum $name {
            $( $(#[$vmeta])* $variant $(($field))?, )+
        }

        impl $name {
            /// Every mnemonic of the table, as written on the line.
            #[allow(dead_code)]
            pub(crate) const MNEMONICS: &'static [&'static str] = &[$($mnem),+];

            /// The mnemonic, as written on the line.
            pub fn $mnemonic(&self) -> &'static str {
                match self {
                    $( $name::$variant { .. } => $mnem, )+
                }
            }

            /// True for queries: exactly the commands that reply.
            pub fn is_query(&self) -> bool {
                match self {
                    $( $name::$variant { .. } => $crate::codec::command_table!(@query $kind), )+
                }
            }

            /// Appends the mnemonic, `?` for a query, then the parameter, if any, with
            /// its separator.
            fn encode_row(&self, out: &mut Vec<u8>) {
                out.extend_from_slice(self.$mnemonic().as_bytes());
                if self.is_query() {
                    out.push(b'?');
                }
                #[allow(unused_variables)]
                match self {
                    $( $name::$variant $(($crate::codec::command_table!(@bind $field, p)))? => {
                        $( <$field as $crate::codec::Param<$input>>::write(p, out); )?
                    } )+
                }
            }

            /// The command of the row `mnemonic` (`query` or not) read from `input`, with
            /// the row's name as written (`?` included); `None` when the table has no
            /// such row.
            fn from_row(
                mnemonic: &str,
                query: bool,
                input: $input,
            ) -> Option<(&'static str, Result<Self, $crate::codec::Refusal>)> {
                $(
                    if mnemonic.eq_ignore_ascii_case($mnem)
                        && query == $crate::codec::command_table!(@query $kind)
                    {
                        let read = $crate::codec::command_table!(
                            @read $input, input, $name::$variant $(, $field)? $(; $read)?
                        );
                        return Some(($crate::codec::command_table!(@name $kind $mnem), read));
                    }
                )+
                None
            }
        }
    };
    (@query query) => { true };
    (@query set) => { false };
    (@name query $mnem:literal) => { concat!($mnem, "?") };
    (@name set $mnem:literal) => { $mnem };
    (@bind $field:ty, $p:ident) => { $p };
    (@read $input:ty, $i:ident, $path:path) => {
        <() as $crate::codec::Param<$input>>::read($i).map(|()| $path)
    };
    (@read $input:ty, $i:ident, $path:path; $read:expr) => {
        ($read)($i).map(|()| $path)
    };
    (@read $input:ty, $i:ident, $path:path, $field:ty) => {
        <$field as $crate::codec::Param<$input>>::read($i).map($path)
    };
    (@read $input:ty, $i:ident, $path:path, $field:ty; $read:expr) => {
        ($read)($i).map($path)
    };
}
pub(crate) use command_table;

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
