//! The real serial transport over pseudo-terminals: the same code path as a USB
//! adapter, with a scripted instrument on the master side.

use std::io::{Read, Write};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread;
use std::time::Duration;

use gonio_driver::{FlowControl, SerialSettings, SerialTransport, Transport, TransportError};
use serialport::{SerialPort, TTYPort};

fn settings(path: &str) -> SerialSettings {
    SerialSettings {
        path: path.to_string(),
        baud: 57600,
        flow: FlowControl::None,
        framing: gonio_driver::Framing::Lines {
            terminator: b'\n',
            max_line: 128,
        },
    }
}

/// An instrument on the master side: answers each line with `reply(line)`, until a
/// `QUIT` line, the `stop` flag, or the slave side's closing.
fn responder(
    mut master: TTYPort,
    reply: fn(&[u8]) -> Option<Vec<u8>>,
    stop: Arc<AtomicBool>,
) -> thread::JoinHandle<()> {
    thread::spawn(move || {
        let mut framer = gonio_proto::LineFramer::new(b'\n', 256);
        let mut buf = [0u8; 256];
        master.set_timeout(Duration::from_millis(20)).ok();
        while !stop.load(Ordering::SeqCst) {
            match master.read(&mut buf) {
                Ok(0) => continue,
                Ok(n) => {
                    framer.push(&buf[..n]);
                    while let Some(Ok(line)) = framer.next_line() {
                        if line == b"QUIT" {
                            return;
                        }
                        if let Some(r) = reply(&line)
                            && master.write_all(&r).is_err()
                        {
                            return;
                        }
                    }
                }
                // A signal to the process (another test's child ending, under a
                // loaded machine) interrupts the poll: not the end of the line.
                Err(e)
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::TimedOut | std::io::ErrorKind::Interrupted
                    ) =>
                {
                    continue;
                }
                Err(_) => return,
            }
        }
    })
}

#[test]
fn lines_cross_a_pseudo_terminal() {
    let (master, slave) = TTYPort::pair().expect("pty pair");
    let path = slave.name().expect("slave has a path");
    let h = responder(
        master,
        |l| match l {
            b"1TP" => Some(b"1TP12.5\r\n".to_vec()),
            _ => None,
        },
        Arc::new(AtomicBool::new(false)),
    );
    let mut t = SerialTransport::open(settings(&path)).expect("opens the pty slave");
    t.send(b"1TP\r\n").expect("sent");
    assert_eq!(
        t.receive_line(Duration::from_secs(2)).expect("reply"),
        b"1TP12.5"
    );
    // Silence is a timeout, not a hang.
    t.send(b"1XX\r\n").expect("sent");
    assert_eq!(
        t.receive_line(Duration::from_millis(50)),
        Err(TransportError::Timeout(Duration::from_millis(50)))
    );
    // Closing every slave descriptor ends the responder (its read fails). A `QUIT`
    // line would race: the responder could close the master before the send's drain
    // (tcdrain) returned, which then fails ("flush failed", seen on a loaded machine).
    drop(t);
    drop(slave);
    h.join().expect("responder");
}

fn answer_tp(l: &[u8]) -> Option<Vec<u8>> {
    (l == b"1TP").then(|| b"1TP4.25\r\n".to_vec())
}

/// A port that vanishes (the USB adapter unplugged: here the pseudo-terminal's master
/// closes and its path disappears) and returns at the same path (re-plugged: a new
/// pseudo-terminal behind the same symlink, as udev gives a stable name).
#[test]
fn port_vanishes_and_returns_at_the_same_path() {
    use gonio_driver::SystemClock;
    use gonio_driver::smc100::{AxisConfig, ChainPolicy, Smc100Chain};

    let dir = std::env::temp_dir().join(format!("gonio-pty-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("temp dir");
    let link = dir.join("ttyGONIO");
    let (master, slave) = TTYPort::pair().expect("pty pair");
    std::os::unix::fs::symlink(slave.name().expect("path"), &link).expect("symlink");
    let stop1 = Arc::new(AtomicBool::new(false));
    let h1 = responder(master, answer_tp, stop1.clone());

    let axis = AxisConfig {
        name: "source".into(),
        address: 1,
        units: "deg".into(),
        min: -10.0,
        max: 10.0,
        velocity: None,
        acceleration: None,
        tolerance: 0.01,
        home_timeout_s: 10.0,
    };
    let policy = ChainPolicy {
        reply_timeout: Duration::from_millis(200),
        reconnect_attempts: 40,
        reconnect_delay: Duration::from_millis(50),
        ..ChainPolicy::default()
    };
    let t = SerialTransport::open(settings(link.to_str().expect("utf-8"))).expect("opens");
    let mut chain = Smc100Chain::new(t, SystemClock::new(), vec![axis], policy).expect("valid");
    assert_eq!(chain.position("source").expect("first"), 4.25);

    // Unplug: the instrument side goes away with its path.
    stop1.store(true, Ordering::SeqCst);
    h1.join().expect("responder ends");
    drop(slave);
    std::fs::remove_file(&link).expect("unlink");

    // Re-plug after 300 ms, at the same path.
    let link2 = link.clone();
    let stop2 = Arc::new(AtomicBool::new(false));
    let stop2b = stop2.clone();
    let replug = thread::spawn(move || {
        thread::sleep(Duration::from_millis(300));
        let (master, slave) = TTYPort::pair().expect("pty pair");
        std::os::unix::fs::symlink(slave.name().expect("path"), &link2).expect("symlink");
        (responder(master, answer_tp, stop2b), slave)
    });
    // The next query finds the port gone, reopens it when it is back, and answers.
    assert_eq!(chain.position("source").expect("after re-plug"), 4.25);
    let (h2, slave2) = replug.join().expect("replugged");
    drop(chain);
    stop2.store(true, Ordering::SeqCst);
    h2.join().expect("responder ends");
    drop(slave2);
    let _ = std::fs::remove_dir_all(&dir);
}
