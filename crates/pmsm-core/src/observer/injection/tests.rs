//! The injection against its `f64` reference, on a salient motor in the rotor frame (exact
//! discrete steps, currents quantised as a 12-bit ADC would), at standstill and turning.

use super::*;
use crate::fixtures::{base_b, inverter_b, motor_b};

/// [`Injection`] in `f64`, SI units: the reference.
struct Reference {
    theta: f64,
    omega: f64,
    /// The load's deceleration, rad/s².
    load: f64,
    i1: [f64; 2],
    i2: [f64; 2],
    positive: bool,
    settle: u8,
    /// `l₁`, `l₂`, `l₃` per A of `ε` (over `4K`), and `b` (rad/s² per A).
    k_theta: f64,
    k_omega: f64,
    k_load: f64,
    accel: f64,
    omega_max: f64,
    ts: f64,
}

impl Reference {
    fn new(
        c: &InjectionConfig,
        f: &InjectionFigures,
        design_wp: f64,
        theta: f64,
        ts: f64,
        base: &PerUnit,
    ) -> Self {
        let k = f.response_a;
        Self {
            theta,
            omega: 0.0,
            load: 0.0,
            i1: [0.0; 2],
            i2: [0.0; 2],
            positive: false,
            settle: c.settle,
            k_theta: 3.0 * design_wp / (4.0 * k),
            k_omega: 3.0 * design_wp * design_wp / (4.0 * k),
            k_load: design_wp * design_wp * design_wp / (4.0 * k),
            accel: {
                let m = motor_b();
                m.p() * m.kt_nm_per_a / m.j_kg_m2
            },
            omega_max: c.omega_max.to_num::<f64>() * base.omega_e_rad_s,
            ts,
        }
    }

    /// One sample on the measured `i` (αβ, A): this sample's angle, and the injection (V).
    fn update(&mut self, i: [f64; 2]) -> (f64, f64) {
        let d2 = [
            i[0] - 2.0 * self.i1[0] + self.i2[0],
            i[1] - 2.0 * self.i1[1] + self.i2[1],
        ];
        let (s, c) = libm::sincos(self.theta);
        let across = d2[1] * c - d2[0] * s;
        let along = d2[0] * c + d2[1] * s;
        let mean = [(i[0] + self.i1[0]) / 2.0, (i[1] + self.i1[1]) / 2.0];
        let i_q = mean[1] * c - mean[0] * s;
        let error = if self.settle > 0 {
            self.settle -= 1;
            0.0
        } else if along >= 0.0 {
            across
        } else {
            -across
        };
        let theta = self.theta;
        let ts = self.ts;
        self.theta += self.omega * ts + self.k_theta * ts * error;
        self.load -= self.k_load * ts * error;
        self.omega = (self.omega + (self.accel * i_q - self.load) * ts + self.k_omega * ts * error)
            .clamp(-self.omega_max, self.omega_max);
        self.i2 = self.i1;
        self.i1 = i;
        let v = if self.positive { 1.0 } else { -1.0 };
        self.positive = !self.positive;
        (theta, v)
    }
}

/// Motor B's windings in the rotor frame, turning at `omega_e` (rad/s) from `theta0`: each
/// sample applies the voltage of `delay` samples before (the PWM update delay), steps the
/// currents exactly for the period's mean voltage, and reads them through a 12-bit ADC of
/// ±10 A. Returns the true angle at each sample.
struct Plant {
    theta: f64,
    omega: f64,
    i_dq: [f64; 2],
    line: [[f64; 2]; 2],
    delay: usize,
}

impl Plant {
    fn measure(&self) -> [f64; 2] {
        let (s, c) = libm::sincos(self.theta);
        let [d, q] = self.i_dq;
        let lsb = 20.0 / 4096.0;
        let adc = |x: f64| libm::round(x / lsb) * lsb;
        [adc(d * c - q * s), adc(d * s + q * c)]
    }

    /// Applies `v_ab` (V) commanded now, advances one period `ts`.
    fn step(&mut self, v_ab: [f64; 2], ts: f64) {
        let m = motor_b();
        let applied = if self.delay == 0 {
            v_ab
        } else {
            let a = self.line[0];
            self.line[0] = v_ab;
            a
        };
        let (s, c) = libm::sincos(self.theta);
        let v = [
            applied[0] * c + applied[1] * s,
            applied[1] * c - applied[0] * s,
        ];
        let [d, q] = self.i_dq;
        let w = self.omega;
        let dd = (v[0] - m.rs_ohm * d + w * m.lq_h * q) / m.ld_h;
        let dq = (v[1] - m.rs_ohm * q - w * (m.ld_h * d + m.flux_wb)) / m.lq_h;
        self.i_dq = [d + dd * ts, q + dq * ts];
        self.theta += w * ts;
    }
}

/// Runs the fixed-point loop and the reference side by side for `n` samples on a plant at
/// `theta0` turning at `omega_e`, both started `offset` rad from the rotor; returns the
/// largest error of each against the rotor over the last half, and their largest difference.
fn run(offset: f64, omega_e: f64, n: usize) -> (f64, f64, f64) {
    let (m, inv, base) = (motor_b(), inverter_b(), base_b());
    let design = InjectionDesign::default();
    let (c, f) = InjectionConfig::new(&m, &inv, &base, design, 1).unwrap();
    let ts = base.sample_s;
    let wp = f.bandwidth_rad_s;
    let theta0 = 0.7;
    let mut fixed = Injection::default();
    fixed.restart(&c, Angle::from_rad(theta0 + offset), Pu::ZERO);
    let mut reference = Reference::new(&c, &f, wp, theta0 + offset, ts, &base);
    let mut plant = Plant {
        theta: theta0,
        omega: omega_e,
        i_dq: [0.0; 2],
        line: [[0.0; 2]; 2],
        delay: 1,
    };
    let wrap = |x: f64| libm::remainder(x, core::f64::consts::TAU);
    let (mut worst_fixed, mut worst_ref, mut apart) = (0.0f64, 0.0f64, 0.0f64);
    for k in 0..n {
        let i = plant.measure();
        let (est, _) = fixed.update(
            &c,
            AlphaBeta {
                alpha: pu_from_f64(i[0] / base.current_a),
                beta: pu_from_f64(i[1] / base.current_a),
            },
        );
        let v = fixed.voltage().to_num::<f64>() * base.voltage_v;
        let (theta_ref, sign) = reference.update(i);
        // The two inject the same way (signs ±1).
        assert!((sign - v.signum()).abs() < 0.5);
        // Injected along the reference's d axis; the EMF's own voltage added, so that the
        // current stays near zero (the current loops' job in the drive).
        let (s, co) = libm::sincos(theta_ref);
        let (sr, cr) = libm::sincos(plant.theta);
        let e = omega_e * m.flux_wb;
        let v_ab = [v * co - e * sr, v * s + e * cr];
        plant.step(v_ab, ts);
        if k > n / 2 {
            worst_fixed =
                worst_fixed.max(wrap(est.theta.to_rad() - plant_theta_at(&plant, ts)).abs());
            worst_ref = worst_ref.max(wrap(theta_ref - plant_theta_at(&plant, ts)).abs());
        }
        apart = apart.max(wrap(est.theta.to_rad() - theta_ref).abs());
    }
    (worst_fixed, worst_ref, apart)
}

/// The rotor's angle at the sample just taken (the plant has stepped past it).
fn plant_theta_at(p: &Plant, ts: f64) -> f64 {
    p.theta - p.omega * ts
}

#[test]
fn at_standstill_both_find_the_axis_from_a_third_of_a_radian_off() {
    let (fixed, reference, apart) = run(0.35, 0.0, 6000);
    assert!(reference < 0.02, "reference {reference}");
    assert!(fixed < 0.02, "fixed point {fixed}");
    assert!(apart < 0.01, "apart {apart}");
}

#[test]
fn turning_slowly_both_follow_the_rotor() {
    // 2 % of motor B's rated speed, electrical.
    let w = 0.02 * 3000.0 * 3.0 * core::f64::consts::TAU / 60.0;
    let (fixed, reference, apart) = run(-0.2, w, 8000);
    // The ADC's steps show in the angle as it turns (a response of 8 steps): up to ±0.02 rad
    // about a lag of 0.012.
    assert!(reference < 0.05, "reference {reference}");
    assert!(fixed < 0.05, "fixed point {fixed}");
    assert!(apart < 0.01, "apart {apart}");
}

#[test]
fn the_design_is_refused_on_a_surface_motor_and_named() {
    let mut m = motor_b();
    m.lq_h = m.ld_h * 1.05;
    let e = InjectionConfig::new(&m, &inverter_b(), &base_b(), InjectionDesign::default(), 1)
        .unwrap_err();
    assert!(
        matches!(
            e,
            ConfigError::Param(ParamError {
                key: "injection",
                ..
            })
        ),
        "{e:?}"
    );
    let ConfigError::Param(ParamError {
        reason: ParamReason::Inconsistent(why),
        ..
    }) = e
    else {
        unreachable!()
    };
    assert!(why.contains("L_q/L_d of at least 1.1"), "{why}");
}

#[test]
fn the_amplitude_moves_the_current_by_the_designed_adc_steps() {
    let (_, c) = InjectionConfig::new(
        &motor_b(),
        &inverter_b(),
        &base_b(),
        InjectionDesign::default(),
        1,
    )
    .unwrap();
    let lsb = 20.0 / 4096.0;
    assert!(
        (c.response_a / lsb - 8.0).abs() < 1e-9,
        "{}",
        c.response_a / lsb
    );
    // 540 V bus: V_b = 312 V, the amplitude well below its quarter.
    assert!(
        c.amplitude_v > 30.0 && c.amplitude_v < 78.0,
        "{}",
        c.amplitude_v
    );
}
