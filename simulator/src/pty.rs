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

fn serve(
    sim: SharedSim,
    port: Port,
    link: PathBuf,
    first: (TTYPort, TTYPort),
    stop: Arc<AtomicBool>,
) {
    let mut pair = Some(first);
    let mut buf = [0u8; 512];
    while !stop.load(Ordering::Relaxed) {
        let closed = lock(&sim).port_closed(port);
        let lost = match (&mut pair, closed) {
            // The adapter is pulled: the pty and its path disappear.
            (Some(_), true) => true,
            (None, false) => {
                pair = new_pair(&link).ok();
                false
            }
            (None, true) => {
                std::thread::sleep(Duration::from_millis(5));
                false
            }
            (Some((master, _slave)), false) => match master.read(&mut buf) {
                Ok(0) => !unasked(&sim, port, master),
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
                    !reply.is_empty() && master.write_all(&reply).is_err()
                }
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => !unasked(&sim, port, master),
                Err(_) => {
                    std::thread::sleep(Duration::from_millis(5));
                    false
                }
            },
        };
        if lost && pair.is_some() {
            // The path goes before the pty: once the pty is closed its number is free
            // for another one (another simulator's), and a driver reopening the old
            // path in between would be talking to that.
            let _ = std::fs::remove_file(&link);
            pair = None;
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
        // A directory of this name can only be left by a dead process that had this
        // one's id: its links point at pty numbers that other processes may hold now.
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir)?;
        let lines: Vec<(Port, PathBuf)> = lock(&sim)
            .ports()
            .into_iter()
            .map(|p| (p, dir.join(p.name())))
            .collect();
        // Every pair and link exists before a path is handed out.
        let pairs = lines
            .iter()
            .map(|(_, link)| new_pair(link))
            .collect::<std::io::Result<Vec<_>>>()?;
        let stop = Arc::new(AtomicBool::new(false));
        let threads = lines
            .iter()
            .cloned()
            .zip(pairs)
            .map(|((port, link), pair)| {
                let (s, st) = (sim.clone(), stop.clone());
                std::thread::spawn(move || serve(s, port, link, pair, st))
            })
            .collect();
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Links a dead process with this one's id left behind point at pty numbers another
    /// process may hold now: the paths handed out are the simulator's own from the
    /// start, never those.
    #[test]
    fn links_a_dead_process_left_are_not_handed_out() {
        let (_master, decoy) = TTYPort::pair().expect("a pty");
        let target = PathBuf::from(decoy.name().expect("its path"));
        for n in 0..16 {
            let dir = std::env::temp_dir().join(format!("gonio-sim-{}-{n}", std::process::id()));
            if std::fs::create_dir_all(&dir).is_ok() {
                for name in ["motion", "detector"] {
                    let _ = std::os::unix::fs::symlink(&target, dir.join(name));
                }
            }
        }
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../config");
        let cfg = crate::SimConfig::load(&root.join("sim-example.toml")).expect("config");
        let pty = PtySim::spawn(crate::instrument(&cfg).expect("sim")).expect("ptys");
        for path in [&pty.motion, &pty.detector] {
            let now = std::fs::read_link(path).expect("a link");
            assert_ne!(now, target, "{} is the decoy's", path.display());
        }
        drop(pty);
    }
}
