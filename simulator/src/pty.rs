//! The simulator behind pseudo-terminals: what a driver in another process (or the
//! real `SerialTransport` in this one) talks to.
//!
//! Each line gets a pty pair; a thread moves bytes between the master side and the
//! simulator. The ptys are reached through symlinks in a private directory, so a port
//! that closes (an outage fault) can come back at the same path, as a re-plugged USB
//! adapter does with a udev name. The slave handles stay open, so a driver can close
//! and reopen the port without the pty going away.

use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

use serialport::{SerialPort, TTYPort};

use crate::faults::Port;
use crate::transport::{SharedSim, lock};

/// A running pty server; dropping it stops the threads and removes the symlinks.
#[derive(Debug)]
pub struct PtySim {
    /// Path of the SMC100 line (a symlink to the pty slave).
    pub motion: PathBuf,
    /// Path of the detector line.
    pub detector: PathBuf,
    /// Paths of the APT controllers' lines, in the layout's role order.
    pub apt: Vec<PathBuf>,
    /// Path of the monochromator's line, when the simulator has one.
    pub monochromator: Option<PathBuf>,
    /// Path of the filter wheel's line, when the simulator has one.
    pub filter_wheel: Option<PathBuf>,
    dir: PathBuf,
    stop: Arc<AtomicBool>,
    threads: Vec<JoinHandle<()>>,
}

fn new_pair(link: &Path) -> std::io::Result<(TTYPort, TTYPort)> {
    let (mut master, slave) = TTYPort::pair().map_err(std::io::Error::other)?;
    let target = slave
        .name()
        .ok_or_else(|| std::io::Error::other("pty slave has no name"))?;
    let _ = std::fs::remove_file(link);
    std::os::unix::fs::symlink(target, link)?;
    master
        .set_timeout(Duration::from_millis(5))
        .map_err(std::io::Error::other)?;
    Ok((master, slave))
}

/// Sends what the instrument on `port` sends unasked by now (an APT controller's
/// completion messages and status updates).
/// False when the pty is gone.
fn unasked(sim: &SharedSim, port: Port, master: &mut TTYPort) -> bool {
    let bytes = {
        let mut s = lock(sim);
        let now = s.clock().seconds();
        match s.next_unsolicited(port) {
            Some(t) if t <= now => s.unsolicited(port, t),
            _ => return true,
        }
    };
    bytes.is_empty() || master.write_all(&bytes).is_ok()
}

fn serve(sim: SharedSim, port: Port, link: PathBuf, stop: Arc<AtomicBool>) {
    let mut pair = new_pair(&link).ok();
    let mut buf = [0u8; 512];
    while !stop.load(Ordering::Relaxed) {
        let closed = lock(&sim).port_closed(port);
        match (&mut pair, closed) {
            (Some(_), true) => {
                // The adapter is pulled: the pty and its path disappear.
                pair = None;
                let _ = std::fs::remove_file(&link);
            }
            (None, false) => pair = new_pair(&link).ok(),
            (None, true) => std::thread::sleep(Duration::from_millis(5)),
            (Some((master, _slave)), false) => match master.read(&mut buf) {
                Ok(0) => {
                    if !unasked(&sim, port, master) {
                        pair = None;
                    }
                }
                Ok(n) => {
                    let reply = {
                        let mut s = lock(&sim);
                        let r = s.port_bytes(port, &buf[..n]);
                        // Account the physical time of the exchange on a driven clock.
                        let lat = s.latency(port);
                        let t = s.wire_time(port, n + r.len());
                        let extra = if r.is_empty() { t } else { t + lat };
                        s.clock().advance(crate::clock::secs(extra));
                        r
                    };
                    if !reply.is_empty() && master.write_all(&reply).is_err() {
                        pair = None;
                    }
                }
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {
                    if !unasked(&sim, port, master) {
                        pair = None;
                    }
                }
                Err(_) => std::thread::sleep(Duration::from_millis(5)),
            },
        }
    }
    let _ = std::fs::remove_file(&link);
}

impl PtySim {
    /// Starts serving `sim` on new pseudo-terminals, one for each of its lines.
    pub fn spawn(sim: SharedSim) -> std::io::Result<PtySim> {
        static COUNT: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
        let n = COUNT.fetch_add(1, Ordering::Relaxed);
        let dir = std::env::temp_dir().join(format!("gonio-sim-{}-{n}", std::process::id()));
        std::fs::create_dir_all(&dir)?;
        let lines: Vec<(Port, PathBuf)> = lock(&sim)
            .ports()
            .into_iter()
            .map(|p| (p, dir.join(p.name())))
            .collect();
        let stop = Arc::new(AtomicBool::new(false));
        let mut threads = Vec::new();
        for (port, link) in lines.iter().cloned() {
            let (s, st) = (sim.clone(), stop.clone());
            threads.push(std::thread::spawn(move || serve(s, port, link, st)));
        }
        // The first pairs exist once every link does.
        for _ in 0..400 {
            if lines.iter().all(|(_, p)| p.exists()) {
                break;
            }
            std::thread::sleep(Duration::from_millis(5));
        }
        let path = |want: fn(&Port) -> bool| lines.iter().filter(move |(p, _)| want(p));
        let first = |want: fn(&Port) -> bool| path(want).next().map(|(_, l)| l.clone());
        Ok(PtySim {
            motion: dir.join(Port::Motion.name()),
            detector: dir.join(Port::Detector.name()),
            apt: path(|p| matches!(p, Port::Apt(_)))
                .map(|(_, l)| l.clone())
                .collect(),
            monochromator: first(|p| *p == Port::Monochromator),
            filter_wheel: first(|p| *p == Port::FilterWheel),
            dir,
            stop,
            threads,
        })
    }
}

impl Drop for PtySim {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}
