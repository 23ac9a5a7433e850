//! Bench-hardware checks, ignored by default: they need the instruments attached.
//!
//! ```sh
//! GONIO_SMC100_PORT=/dev/ttyUSB0 GONIO_SR830_PORT=/dev/ttyUSB1 \
//! GONIO_KDC101_PORT=usb:27000001 GONIO_K10CR1_PORT=usb:55000001 \
//! GONIO_K6485_PORT=/dev/ttyUSB2 \
//!     cargo test --release -p gonio-driver --test it hardware:: -- --ignored
//! ```
//! Set only the variables of the instruments attached, and run only their tests by
//! name (`-- --ignored kdc101`). Nothing moves: the controllers are identified and
//! set up (channel enabled, velocity read back), and the detectors are set up and read.

use gonio_driver::apt::{AptAxis, AptAxisConfig, StageKind};
use gonio_driver::k6485::K6485;
use gonio_driver::smc100::{AxisConfig, ChainPolicy, Smc100Chain};
use gonio_driver::sr830::{Sr830, Sr830Config};
use gonio_driver::{FlowControl, SerialSettings, SerialTransport, SystemClock};

fn port(var: &str) -> String {
    std::env::var(var).unwrap_or_else(|_| panic!("set {var} to the instrument's port"))
}

#[test]
#[ignore = "needs an SMC100 on $GONIO_SMC100_PORT"]
fn smc100_identifies() {
    let t = SerialTransport::open(SerialSettings {
        path: port("GONIO_SMC100_PORT"),
        baud: 57600,
        flow: FlowControl::Software,
        framing: gonio_driver::Framing::Lines {
            terminator: b'\n',
            max_line: gonio_proto::smc100::MAX_LINE,
        },
    })
    .expect("port opens");
    let axis = AxisConfig {
        name: "axis1".into(),
        address: 1,
        units: "deg".into(),
        min: -1.0,
        max: 1.0,
        velocity: None,
        acceleration: None,
        tolerance: 0.01,
        home_timeout_s: 60.0,
    };
    let mut chain =
        Smc100Chain::new(t, SystemClock::new(), vec![axis], ChainPolicy::default()).expect("valid");
    let info = chain.identify().expect("controller 1 answers");
    println!("{info:?}");
    assert!(!info[0].version.is_empty());
    let p = chain.position("axis1").expect("TP answers");
    assert!(p.is_finite());
}

#[test]
#[ignore = "needs an SR830 on $GONIO_SR830_PORT"]
fn sr830_reads() {
    let t = SerialTransport::open(SerialSettings {
        path: port("GONIO_SR830_PORT"),
        baud: 9600,
        flow: FlowControl::None,
        framing: gonio_driver::Framing::Lines {
            terminator: b'\r',
            max_line: gonio_proto::sr830::MAX_LINE,
        },
    })
    .expect("port opens");
    let cfg = Sr830Config {
        samples: 3,
        ..Sr830Config::default()
    };
    let mut d = Sr830::new(t, SystemClock::new(), cfg).expect("valid");
    let id = d.setup().expect("answers *IDN?");
    println!("{id}");
    let r = d.read().expect("reads");
    println!("{r:?}");
    assert_eq!(r.n, 3);
    assert!(r.r_mean.is_finite());
}

/// An APT controller on `var`'s port: identified (model and stage checked), set up,
/// its status and velocity parameters read. Nothing moves.
fn apt_identifies(var: &str, stage: StageKind) {
    let t = SerialTransport::open(SerialSettings {
        path: port(var),
        baud: gonio_driver::apt::BAUD,
        flow: FlowControl::Hardware,
        framing: gonio_driver::Framing::Apt,
    })
    .expect("port opens");
    let axis = AptAxisConfig::new("axis", stage, -1.0, 1.0);
    let mut a =
        AptAxis::new(t, SystemClock::new(), axis, ChainPolicy::default(), None).expect("valid");
    let info = a.identify().expect("HW_GET_INFO answers");
    println!("{info}");
    let s = a.status().expect("status answers");
    println!("{s:?}");
    assert!(s.position_deg.is_finite());
    let (v, acc) = a.velocity_params().expect("GET_VELPARAMS answers");
    assert!(v > 0.0 && acc > 0.0, "{v} {acc}");
}

#[test]
#[ignore = "needs a KDC101 with a PRM1-Z8 on $GONIO_KDC101_PORT"]
fn kdc101_identifies() {
    apt_identifies("GONIO_KDC101_PORT", StageKind::Prm1Z8);
}

#[test]
#[ignore = "needs a K10CR1 on $GONIO_K10CR1_PORT"]
fn k10cr1_identifies() {
    apt_identifies("GONIO_K10CR1_PORT", StageKind::K10cr1);
}

#[test]
#[ignore = "needs a Keithley 6485 on $GONIO_K6485_PORT"]
fn k6485_reads() {
    let t = SerialTransport::open(SerialSettings {
        path: port("GONIO_K6485_PORT"),
        baud: 9600,
        flow: FlowControl::None,
        framing: gonio_driver::Framing::Lines {
            terminator: gonio_proto::k6485::REPLY_TERMINATOR,
            max_line: gonio_proto::k6485::MAX_LINE,
        },
    })
    .expect("port opens");
    let cfg = gonio_proto::k6485::K6485Config {
        samples: 3,
        ..Default::default()
    };
    let mut d = K6485::new(t, SystemClock::new(), cfg).expect("valid");
    let id = d.setup().expect("answers *IDN?");
    println!("{id}");
    let r = d.read().expect("reads");
    println!("{r:?}");
    assert_eq!(r.samples, 3);
}
