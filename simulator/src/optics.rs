//! The light path: source, sample, detector.
//!
//! The detector signal is `V = R_v · P_s · f_r(wi, wo) · cos θo · Ω` (DeYoung Eq. A.15
//! read backwards: the flux a detector of solid angle Ω collects from a sample lit by
//! the flux `P_s`), with `R_v` the detector's responsivity (photodiode and
//! transimpedance amplifier, V/W). Optionally `f_r cos θo` is averaged over the
//! detector's aperture and over the beam's divergence, which is what smooths a
//! measured specular peak. Two geometric effects of a real instrument are modelled:
//! the detector arm blocking the source beam when the arms come too close, and the
//! beam's footprint overfilling the sample at grazing incidence.

use gonio_brdf::Brdf;
use gonio_core::radiometry::Aperture;
use gonio_core::{Dir, DirPair, Frame, Vec3};

/// The optical set-up.
#[derive(Clone, Debug, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct OpticsConfig {
    /// Source power reaching the sample position, W.
    pub source_power_w: f64,
    /// Beam diameter at the sample (top-hat), m.
    pub beam_diameter_m: f64,
    /// Beam divergence, half-angle, degrees (0: collimated).
    pub beam_divergence_deg: f64,
    /// Detector aperture radius, m.
    pub detector_radius_m: f64,
    /// Sample-to-aperture distance, m.
    pub detector_distance_m: f64,
    /// Detector responsivity × transimpedance gain, V/W.
    pub responsivity_v_per_w: f64,
    /// Closest the source and detector may come, as seen from the sample, before the
    /// detector arm blocks the beam, degrees.
    pub min_arm_separation_deg: f64,
    /// Sample length along the plane of incidence, m (for overfilling).
    pub sample_length_m: f64,
    /// Average `f_r cos θo` over the aperture and the divergence (slower, smoother).
    pub integrate_aperture: bool,
    /// Relative source drift per hour (linear).
    pub drift_per_hour: f64,
    /// Relative amplitude of a slow periodic drift.
    pub drift_amplitude: f64,
    /// Period of that drift, s.
    pub drift_period_s: f64,
    /// Electrical pickup at the chopper frequency, V: present with the source dark,
    /// what a dark reading measures and the reduction subtracts.
    pub pickup_v: f64,
    /// The colour temperature of the tungsten-halogen lamp behind a monochromator or
    /// filter wheel, K: the shape of the source's spectrum (`crate::spectral`).
    pub lamp_colour_temperature_k: f64,
    /// Where the lamp's envelope and the optics before the grating start to pass
    /// light, nm (the 50 % point of a 20 nm-wide edge): no light below it reaches the
    /// grating, so no second order is seen below twice it.
    pub lamp_cut_on_nm: f64,
}

impl Default for OpticsConfig {
    fn default() -> Self {
        OpticsConfig {
            source_power_w: 1e-3,
            beam_diameter_m: 0.005,
            beam_divergence_deg: 0.0,
            detector_radius_m: 0.005,
            detector_distance_m: 0.3,
            responsivity_v_per_w: 1e4,
            min_arm_separation_deg: 8.0,
            sample_length_m: 0.05,
            integrate_aperture: false,
            drift_per_hour: 0.0,
            drift_amplitude: 0.0,
            drift_period_s: 600.0,
            pickup_v: 0.0,
            lamp_colour_temperature_k: 3100.0,
            lamp_cut_on_nm: 300.0,
        }
    }
}

/// Why no light reaches the detector, or only part of it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Geometry {
    /// A normal measurement.
    Clear,
    /// The source or the detector is at or below the sample's horizon.
    BelowHorizon,
    /// The detector arm is in the beam.
    Shadowed,
    /// The beam's footprint is longer than the sample: part of it misses.
    Overfilled,
}

/// What is in the light path: the state a bench (an operator, or the simulator's
/// automation) sets for calibrations.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LightPath {
    /// Source on, sample mounted: a BRDF measurement.
    Sample,
    /// Source blocked: only pickup and noise reach the detector.
    Dark,
    /// Sample removed, the beam through a neutral density filter of this
    /// transmittance straight into the detector (when the detector faces the source).
    Incident {
        /// Filter transmittance, in (0, 1].
        transmittance: f64,
    },
}

/// The optics with a sample in place.
pub struct Optics {
    cfg: OpticsConfig,
    sample: Box<dyn Brdf>,
    channel: usize,
    path: LightPath,
    /// The light a monochromator passes, `(nm, relative power)`; `None` without one
    /// (the source's power is all in the measured channel).
    spectrum: Option<Vec<(f64, f64)>>,
    omega: f64,
    /// Gauss–Legendre-on-a-disc points (unit disc) with weights summing to 1.
    disc: Vec<(f64, f64, f64)>,
}

impl std::fmt::Debug for Optics {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Optics")
            .field("cfg", &self.cfg)
            .field("channel", &self.channel)
            .field("omega_sr", &self.omega)
            .finish()
    }
}

impl Optics {
    /// The optics with `sample`, measuring its channel `channel`.
    pub fn new(cfg: OpticsConfig, sample: Box<dyn Brdf>, channel: usize) -> Self {
        let omega = Aperture {
            radius_m: cfg.detector_radius_m,
            distance_m: cfg.detector_distance_m,
        }
        .solid_angle_sr();
        Optics {
            cfg,
            sample,
            channel,
            path: LightPath::Sample,
            spectrum: None,
            omega,
            disc: disc_rule(),
        }
    }

    /// The configuration.
    pub fn config(&self) -> &OpticsConfig {
        &self.cfg
    }

    /// The detector's solid angle, sr.
    pub fn solid_angle_sr(&self) -> f64 {
        self.omega
    }

    /// The sample.
    pub fn sample(&self) -> &dyn Brdf {
        self.sample.as_ref()
    }

    /// The measured channel.
    pub fn channel(&self) -> usize {
        self.channel
    }

    /// Mounts another sample (a reference standard) measured in its channel
    /// `channel`; returns the one taken off and its channel.
    pub fn swap_sample(&mut self, sample: Box<dyn Brdf>, channel: usize) -> (Box<dyn Brdf>, usize) {
        let old = std::mem::replace(&mut self.sample, sample);
        let old_channel = std::mem::replace(&mut self.channel, channel);
        (old, old_channel)
    }

    /// Measures the sample's channel named `name` from now on; false (and no change)
    /// when the sample has no such channel.
    pub fn select_channel(&mut self, name: &str) -> bool {
        match self.sample.channels().index_of(name) {
            Some(i) => {
                self.channel = i;
                true
            }
            None => false,
        }
    }

    /// Sets the light a band selector passes (a monochromator's
    /// [`crate::spectral::passband`], a filter's [`crate::spectral::white`]):
    /// the source's power is then spread over these wavelengths with these relative
    /// weights, and the sample reflects each at its own `f_r(λ)`. `None`: no
    /// monochromator; an empty list: no light (shutter closed).
    pub fn set_spectrum(&mut self, spectrum: Option<Vec<(f64, f64)>>) {
        self.spectrum = spectrum;
    }

    /// The light a monochromator passes, if there is one.
    pub fn spectrum(&self) -> Option<&[(f64, f64)]> {
        self.spectrum.as_deref()
    }

    /// The source's power through the monochromator relative to `source_power_w`
    /// (1 without one).
    fn spectral_share(&self) -> f64 {
        self.spectrum
            .as_ref()
            .map_or(1.0, |s| s.iter().map(|(_, w)| w).sum())
    }

    /// The sample's `f_r` as the detector sees it, from one evaluation `buf` (a value
    /// per channel): the measured channel's, or, through a monochromator, the sum over
    /// its passband of the weight times `f_r(λ)` interpolated between the sample's
    /// wavelength channels (a sample without wavelengths is spectrally flat).
    fn seen(&self, buf: &[f64]) -> f64 {
        match (&self.spectrum, self.sample.channels()) {
            (None, _) => buf[self.channel],
            (Some(s), gonio_core::Channels::Wavelengths(w)) => s
                .iter()
                .map(|(nm, wt)| wt * crate::spectral::interpolate(w, buf, *nm))
                .sum(),
            (Some(s), _) => buf[self.channel] * s.iter().map(|(_, w)| w).sum::<f64>(),
        }
    }

    /// What is in the light path.
    pub fn light_path(&self) -> LightPath {
        self.path
    }

    /// Sets what is in the light path.
    pub fn set_light_path(&mut self, path: LightPath) {
        self.path = path;
    }

    /// The direct beam on the detector with the sample removed, V: all of it (through
    /// the filter) when the detector's axis is within its aperture's half-angle of the
    /// beam's axis, scaled by the aperture's share of a wider beam.
    fn direct_beam(&self, t: f64, pair: DirPair, transmittance: f64) -> f64 {
        // The beam leaves the source along −wi: the detector must sit opposite it.
        if std::f64::consts::PI - pair.wo.angle_to(pair.wi) > self.half_angle() {
            return 0.0;
        }
        let share = (2.0 * self.cfg.detector_radius_m / self.cfg.beam_diameter_m)
            .powi(2)
            .min(1.0);
        self.cfg.responsivity_v_per_w
            * self.source_power(t)
            * self.spectral_share()
            * transmittance
            * share
    }

    /// The detector aperture's half-angle seen from the sample, rad.
    fn half_angle(&self) -> f64 {
        self.cfg
            .detector_radius_m
            .atan2(self.cfg.detector_distance_m)
    }

    /// Source power at physical time `t` (drift included), W.
    pub fn source_power(&self, t: f64) -> f64 {
        let c = &self.cfg;
        let periodic = if c.drift_period_s > 0.0 {
            c.drift_amplitude * (std::f64::consts::TAU * t / c.drift_period_s).sin()
        } else {
            0.0
        };
        c.source_power_w * (1.0 + c.drift_per_hour * t / 3600.0 + periodic)
    }

    /// What limits the light for this pair of directions.
    pub fn geometry(&self, pair: DirPair) -> Geometry {
        if !(pair.wi.is_above() && pair.wo.is_above()) {
            return Geometry::BelowHorizon;
        }
        if gonio_core::kinematics::arm_separation_deg(pair) < self.cfg.min_arm_separation_deg {
            return Geometry::Shadowed;
        }
        if self.overfill_fraction(pair.wi) < 1.0 {
            return Geometry::Overfilled;
        }
        Geometry::Clear
    }

    /// The fraction of the beam that lands on the sample: its footprint is the beam
    /// diameter over cos θi along the plane of incidence.
    pub fn overfill_fraction(&self, wi: Dir) -> f64 {
        if wi.z <= 0.0 {
            return 0.0;
        }
        (self.cfg.sample_length_m * wi.z / self.cfg.beam_diameter_m).min(1.0)
    }

    fn fr_cos(&self, wi: Dir, wo: Dir, buf: &mut [f64]) -> f64 {
        if !(wi.is_above() && wo.is_above()) {
            return 0.0;
        }
        self.sample.eval(wi, wo, buf);
        self.seen(buf) * wo.z
    }

    /// The detector signal, V, at physical time `t` for directions `pair`, in the
    /// current light path (pickup included).
    pub fn signal(&self, t: f64, pair: DirPair) -> f64 {
        self.cfg.pickup_v
            + match self.path {
                LightPath::Sample => self.reflected(t, pair),
                LightPath::Dark => 0.0,
                LightPath::Incident { transmittance } => self.direct_beam(t, pair, transmittance),
            }
    }

    /// The light the sample reflects into the detector, V.
    fn reflected(&self, t: f64, pair: DirPair) -> f64 {
        match self.geometry(pair) {
            Geometry::BelowHorizon | Geometry::Shadowed => return 0.0,
            Geometry::Clear | Geometry::Overfilled => {}
        }
        let mut buf = vec![0.0; self.sample.channels().len()];
        let frc = if self.cfg.integrate_aperture {
            let a = self.half_angle();
            let b = self.cfg.beam_divergence_deg.to_radians();
            let fo = Frame::from_normal(pair.wo);
            let fi = Frame::from_normal(pair.wi);
            let mut acc = 0.0;
            for &(x, y, w) in &self.disc {
                let wo = cone_dir(&fo, a, x, y);
                if b > 0.0 {
                    for &(u, v, w2) in &self.disc {
                        let wi = cone_dir(&fi, b, u, v);
                        acc += w * w2 * self.fr_cos(wi, wo, &mut buf);
                    }
                } else {
                    acc += w * self.fr_cos(pair.wi, wo, &mut buf);
                }
            }
            acc
        } else {
            self.fr_cos(pair.wi, pair.wo, &mut buf)
        };
        let p_sample = self.source_power(t) * self.overfill_fraction(pair.wi);
        self.cfg.responsivity_v_per_w * p_sample * frc * self.omega
    }
}

/// A direction in the cone of half-angle `a` about the frame's normal, at the point
/// (x, y) of the unit disc (equal areas of the disc are equal solid angles for small
/// cones).
fn cone_dir(f: &Frame, a: f64, x: f64, y: f64) -> Dir {
    let s = a.sin();
    let (lx, ly) = (x * s, y * s);
    let lz = (1.0 - lx * lx - ly * ly).max(0.0).sqrt();
    f.dir_to_parent(Dir::new(Vec3::new(lx, ly, lz)).unwrap_or(Dir::Z))
}

/// A product rule on the unit disc: 4 radial Gauss–Legendre nodes (in r², so rings of
/// equal area) × 8 azimuths; weights sum to 1.
fn disc_rule() -> Vec<(f64, f64, f64)> {
    // Gauss–Legendre on [0, 1] with 4 nodes.
    let x: [f64; 4] = [
        0.069_431_844_202_973_71,
        0.330_009_478_207_571_9,
        0.669_990_521_792_428_1,
        0.930_568_155_797_026_3,
    ];
    let w = [
        0.173_927_422_568_726_93,
        0.326_072_577_431_273_07,
        0.326_072_577_431_273_07,
        0.173_927_422_568_726_93,
    ];
    let n_phi = 8;
    let mut out = Vec::with_capacity(4 * n_phi);
    for (u, wu) in x.iter().zip(w) {
        let r = u.sqrt();
        for k in 0..n_phi {
            let phi = std::f64::consts::TAU * (k as f64 + 0.5) / n_phi as f64;
            out.push((r * phi.cos(), r * phi.sin(), wu / n_phi as f64));
        }
    }
    out
}
