//! Moving bytes and lines to and from an instrument.

use std::fmt;
use std::io::{Read, Write};
use std::time::{Duration, Instant};

pub use gonio_proto::TransportError;
use gonio_proto::{Framer, LineFramer};

use crate::ports;

/// A byte link to an instrument, framed into lines (the text protocols) or messages
/// (binary ones): a "line" below is one frame of the link's [`Framing`].
///
/// Implemented by [`SerialTransport`] (a real port or pseudo-terminal) and by
/// [`ScriptedTransport`](crate::ScriptedTransport) (tests).
pub trait Transport: Send {
    /// Sends `bytes` (one command line, terminator included, or one message).
    fn send(&mut self, bytes: &[u8]) -> Result<(), TransportError>;
    /// The next line (or message) the instrument sends, terminator removed, waiting
    /// at most `timeout`.
    fn receive_line(&mut self, timeout: Duration) -> Result<Vec<u8>, TransportError>;
    /// Discards everything received and not yet read (stale replies after a timeout).
    fn clear_input(&mut self) -> Result<(), TransportError>;
    /// Opens the port again after it vanished.
    fn reconnect(&mut self) -> Result<(), TransportError>;
    /// The port's name, for error messages.
    fn name(&self) -> String;
}

/// A boxed transport is one: an instrument with several lines of different kinds
/// holds them all as `Box<dyn Transport>`.
impl Transport for Box<dyn Transport> {
    fn send(&mut self, bytes: &[u8]) -> Result<(), TransportError> {
        (**self).send(bytes)
    }
    fn receive_line(&mut self, timeout: Duration) -> Result<Vec<u8>, TransportError> {
        (**self).receive_line(timeout)
    }
    fn clear_input(&mut self) -> Result<(), TransportError> {
        (**self).clear_input()
    }
    fn reconnect(&mut self) -> Result<(), TransportError> {
        (**self).reconnect()
    }
    fn name(&self) -> String {
        (**self).name()
    }
}

/// How a link's byte stream is cut into frames.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Framing {
    /// Lines ending in `terminator` (a CR before an LF terminator is dropped), at most
    /// `max_line` bytes: the SMC100, the SR830, SCPI instruments.
    Lines {
        /// The byte that ends a received line.
        terminator: u8,
        /// The longest line accepted.
        max_line: usize,
    },
    /// Thorlabs APT binary messages (6-byte header, optional data packet).
    Apt,
    /// The SR830's: lines ending in CR, except the binary replies to `TRCB?` and
    /// `TRCL?`, cut by the length their query asks for
    /// ([`gonio_proto::sr830::Sr830Framer`]).
    Sr830 {
        /// The longest line accepted.
        max_line: usize,
    },
}

impl Framing {
    /// A framer for this framing.
    pub fn framer(self) -> Box<dyn Framer> {
        match self {
            Framing::Lines {
                terminator,
                max_line,
            } => Box::new(LineFramer::new(terminator, max_line)),
            Framing::Apt => Box::new(gonio_proto::apt::AptFramer::new()),
            Framing::Sr830 { max_line } => Box::new(gonio_proto::sr830::Sr830Framer::new(max_line)),
        }
    }
}

/// Software (Xon/Xoff) or hardware (RTS/CTS) flow control.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum FlowControl {
    /// None.
    None,
    /// Xon/Xoff (the SMC100's).
    Software,
    /// RTS/CTS (the SR830 can use it).
    Hardware,
}

/// How to open a serial port: 8 data bits, no parity, 1 stop bit, and these.
#[derive(Clone, Debug, PartialEq)]
pub struct SerialSettings {
    /// Port path (`/dev/ttyUSB0`, `/dev/pts/3`), or `usb:SERIAL`: the USB serial
    /// device with that serial number, found again at every (re)connection, since
    /// paths reorder when adapters are replugged or the machine reboots.
    pub path: String,
    /// Baud rate.
    pub baud: u32,
    /// Flow control.
    pub flow: FlowControl,
    /// How received bytes are cut into frames.
    pub framing: Framing,
}

/// A serial port (or pseudo-terminal) at a path, with its protocol's framing.
pub struct SerialTransport {
    settings: SerialSettings,
    port: Option<Box<dyn serialport::SerialPort>>,
    framer: Box<dyn Framer>,
}

impl std::fmt::Debug for SerialTransport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SerialTransport")
            .field("settings", &self.settings)
            .field("open", &self.port.is_some())
            .finish()
    }
}

/// How long one `read` call may block: short, so deadlines are kept to a few ms.
const POLL: Duration = Duration::from_millis(5);

impl SerialTransport {
    /// Opens the port.
    pub fn open(settings: SerialSettings) -> Result<Self, TransportError> {
        let framer = settings.framing.framer();
        let mut t = SerialTransport {
            settings,
            port: None,
            framer,
        };
        t.reconnect()?;
        Ok(t)
    }

    fn disconnected(&mut self, e: impl std::fmt::Display) -> TransportError {
        self.port = None;
        TransportError::Disconnected {
            port: self.settings.path.clone(),
            reason: e.to_string(),
        }
    }

    fn port(&mut self) -> Result<&mut Box<dyn serialport::SerialPort>, TransportError> {
        let path = self.settings.path.clone();
        self.port.as_mut().ok_or(TransportError::Disconnected {
            port: path,
            reason: "port closed after an earlier failure".into(),
        })
    }
}

impl Transport for SerialTransport {
    fn send(&mut self, bytes: &[u8]) -> Result<(), TransportError> {
        self.framer.sent(bytes);
        let r = {
            let port = self.port()?;
            port.write_all(bytes).and_then(|_| port.flush())
        };
        r.map_err(|e| self.disconnected(e))
    }

    fn receive_line(&mut self, timeout: Duration) -> Result<Vec<u8>, TransportError> {
        let deadline = Instant::now() + timeout;
        let mut buf = [0u8; 256];
        loop {
            if let Some(line) = self.framer.next_frame() {
                return line.map_err(TransportError::from);
            }
            let now = Instant::now();
            if now >= deadline {
                return Err(TransportError::Timeout(timeout));
            }
            let wait = (deadline - now).min(POLL);
            let r = {
                let port = self.port()?;
                port.set_timeout(wait)
                    .and_then(|_| match port.read(&mut buf) {
                        Ok(n) => Ok(n),
                        Err(e) if e.kind() == std::io::ErrorKind::TimedOut => Ok(0),
                        Err(e) => Err(e.into()),
                    })
            };
            match r {
                Ok(n) => self.framer.push(&buf[..n]),
                Err(e) => return Err(self.disconnected(e)),
            }
        }
    }

    fn clear_input(&mut self) -> Result<(), TransportError> {
        self.framer.clear();
        let r = self.port()?.clear(serialport::ClearBuffer::Input);
        r.map_err(|e| self.disconnected(e))
    }

    fn reconnect(&mut self) -> Result<(), TransportError> {
        self.port = None;
        self.framer.clear();
        let s = &self.settings;
        let flow = match s.flow {
            FlowControl::None => serialport::FlowControl::None,
            FlowControl::Software => serialport::FlowControl::Software,
            FlowControl::Hardware => serialport::FlowControl::Hardware,
        };
        let path = ports::resolve(&s.path).map_err(|reason| TransportError::Disconnected {
            port: s.path.clone(),
            reason,
        })?;
        let port = serialport::new(&path, s.baud)
            .data_bits(serialport::DataBits::Eight)
            .parity(serialport::Parity::None)
            .stop_bits(serialport::StopBits::One)
            .flow_control(flow)
            .timeout(POLL)
            .open()
            .map_err(|e| TransportError::Disconnected {
                port: s.path.clone(),
                reason: e.to_string(),
            })?;
        self.port = Some(port);
        Ok(())
    }

    fn name(&self) -> String {
        self.settings.path.clone()
    }
}

/// A line as log text: printable ASCII as is, `\r`, `\n`, `\0`, `\\` and other bytes
/// escaped.
pub(crate) struct Escaped<'a>(pub(crate) &'a [u8]);

impl fmt::Display for Escaped<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for &b in self.0 {
            match b {
                b'\r' => f.write_str("\\r")?,
                b'\n' => f.write_str("\\n")?,
                0 => f.write_str("\\0")?,
                b'\\' => f.write_str("\\\\")?,
                0x20..=0x7e => fmt::Write::write_char(f, char::from(b))?,
                _ => write!(f, "\\x{b:02x}")?,
            }
        }
        Ok(())
    }
}
