#![allow(missing_docs)] // criterion_group! generates undocumented functions
//! Driver overhead per command round trip over a pseudo-terminal, to set against the
//! time the same bytes take on the wire at the instrument's baud rate.
//!
//! `cargo bench -p gonio-driver --bench roundtrip`; figures in BENCHMARKS.md.

use std::hint::black_box;
use std::io::{Read, Write};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use gonio_driver::smc100::{AxisConfig, ChainPolicy, Smc100Chain};
use gonio_driver::{FlowControl, SerialSettings, SerialTransport, SystemClock, Transport};
use serialport::{SerialPort, TTYPort};

/// An SMC100 stand-in on the master side: answers `1TP` at once.
fn responder(mut master: TTYPort, stop: Arc<AtomicBool>) -> thread::JoinHandle<()> {
    thread::spawn(move || {
        let mut framer = gonio_proto::LineFramer::new(b'\n', 256);
        let mut buf = [0u8; 256];
        let _ = master.set_timeout(Duration::from_millis(20));
        while !stop.load(Ordering::Relaxed) {
            match master.read(&mut buf) {
                Ok(n) => {
                    framer.push(&buf[..n]);
                    while let Some(Ok(line)) = framer.next_line() {
                        if line == b"1TP" {
                            let _ = master.write_all(b"1TP12.5\r\n");
                        }
                    }
                }
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
                Err(_) => return,
            }
        }
    })
}

fn roundtrip(c: &mut Criterion) {
    let (master, slave) = TTYPort::pair().expect("pty pair");
    let path = slave.name().expect("slave path");
    let stop = Arc::new(AtomicBool::new(false));
    let h = responder(master, stop.clone());
    let settings = SerialSettings {
        path,
        baud: 57600,
        flow: FlowControl::Software,
        framing: gonio_driver::Framing::Lines {
            terminator: b'\n',
            max_line: 128,
        },
    };
    let mut g = c.benchmark_group("smc100-roundtrip-pty");
    {
        let mut t = SerialTransport::open(settings.clone()).expect("opens");
        g.bench_function("transport: send 1TP, receive line", |b| {
            b.iter(|| {
                t.send(b"1TP\r\n").expect("sent");
                black_box(t.receive_line(Duration::from_secs(1)).expect("reply"))
            })
        });
    }
    {
        let t = SerialTransport::open(settings).expect("opens");
        let axis = AxisConfig {
            name: "source".into(),
            address: 1,
            units: "deg".into(),
            min: -170.0,
            max: 170.0,
            velocity: None,
            acceleration: None,
            tolerance: 0.01,
            home_timeout_s: 60.0,
        };
        let mut chain = Smc100Chain::new(t, SystemClock::new(), vec![axis], ChainPolicy::default())
            .expect("valid");
        g.bench_function(
            "driver: position() (encode, send, frame, parse, check)",
            |b| b.iter(|| black_box(chain.position("source").expect("position"))),
        );
        // The chain's drop sends a stop the responder ignores.
    }
    g.finish();
    stop.store(true, Ordering::Relaxed);
    let _ = h.join();
    drop(slave);
}

criterion_group!(benches, roundtrip);
criterion_main!(benches);
