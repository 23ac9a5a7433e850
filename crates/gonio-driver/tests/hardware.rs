//! Bench-hardware checks, ignored by default: they need the instruments attached.
//!
//! ```sh
//! GONIO_SMC100_PORT=/dev/ttyUSB0 GONIO_SR830_PORT=/dev/ttyUSB1 \
//!     cargo test --release -p gonio-driver --test hardware -- --ignored
//! ```
//! Nothing moves: the controllers are identified, and the lock-in is set up and read.

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
