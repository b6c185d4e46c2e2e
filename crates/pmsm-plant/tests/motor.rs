//! Motor model: energy balance, steady state against phasors, RK4 convergence, analytic
//! transients, saturation polarity, mechanics and error handling.

mod common;

use common::{motor_a, motor_b, rel};
use core::f64::consts::PI;
use pmsm_core::MotorParams;
use pmsm_plant::motor::{Mechanics, Motor, MotorModel, MotorState};
use pmsm_plant::{PlantError, Saturation, inverse_park};

/// Voltage test signal: a rotating vector of ramping frequency plus steps, V.
fn excitation(t: f64, amp_v: f64) -> [f64; 2] {
    // Frequency ramps 2 → 32 Hz over 0.3 s: θ_v = 2π (2 t + 50 t²).
    let th = 2.0 * PI * (2.0 * t + 50.0 * t * t);
    let step = if t < 0.1 {
        [0.0, 0.0]
    } else if t < 0.2 {
        [0.2 * amp_v, -0.1 * amp_v]
    } else {
        [-0.15 * amp_v, 0.25 * amp_v]
    };
    [
        amp_v * libm::cos(th) + step[0],
        amp_v * libm::sin(th) + step[1],
    ]
}

/// Integrates 0.3 s and returns (energy residual, input energy), J.
fn energy_balance(model: MotorModel, amp_v: f64, load_max_nm: f64) -> (f64, f64) {
    let p = model.params;
    let mut m = Motor::new(model, 0.3, 0.0).unwrap();
    let dt = 10e-6;
    let n = 30_000;
    let w0 = m.magnetic_energy_j() + m.kinetic_energy_j();
    let (mut e_in, mut e_cu, mut e_mech) = (0.0, 0.0, 0.0);
    let loss = |m: &Motor| {
        let i = m.i_alpha_beta();
        1.5 * p.rs_ohm * (i[0] * i[0] + i[1] * i[1])
    };
    for k in 0..n {
        let t = k as f64 * dt;
        let v = excitation(t, amp_v);
        let load = if t < 0.15 { 0.0 } else { load_max_nm };
        let (i0, w_0, l0) = (m.i_alpha_beta(), m.state().omega_m_rad_s, loss(&m));
        m.step(v[0], v[1], load, dt).unwrap();
        let (i1, w_1, l1) = (m.i_alpha_beta(), m.state().omega_m_rad_s, loss(&m));
        // Trapezoidal rule; v is constant over the step, so only i varies (error ~ (ω dt)²/12).
        e_in += dt * 1.5 * (v[0] * (i0[0] + i1[0]) + v[1] * (i0[1] + i1[1])) * 0.5;
        e_cu += dt * 0.5 * (l0 + l1);
        let pm = |w: f64| p.b_nm_s * w * w + load * w;
        e_mech += dt * 0.5 * (pm(w_0) + pm(w_1));
    }
    let dw = m.magnetic_energy_j() + m.kinetic_energy_j() - w0;
    (e_in - e_cu - e_mech - dw, e_in)
}

#[test]
fn power_balance_surface_with_harmonics() {
    // Default K_T = 1.5 p ψ (energy-consistent), Solsona, Valla, Muravchik's (2000) harmonics.
    let mut p = motor_a();
    p.kt_nm_per_a = 1.5 * p.p() * p.flux_wb;
    let mut model = MotorModel::new(p);
    model.emf_h5 = 0.042;
    model.emf_h7 = 0.025;
    assert!(!model.uses_dq_frame());
    let (res, e_in) = energy_balance(model, 60.0, 2.0);
    eprintln!("surface+harmonics: residual {res:e} J of {e_in:.3} J");
    assert!(e_in > 10.0);
    assert!(
        res.abs() < 1e-4 * e_in,
        "residual {res} J vs input {e_in} J"
    );
}

#[test]
fn power_balance_interior_linear_and_saturated() {
    let p = motor_b();
    let mut linear = MotorModel::new(p);
    linear.saturation = Saturation::Linear;
    let saturated = MotorModel::new(p);
    assert!(matches!(saturated.saturation, Saturation::Tanh { .. }));
    // Saturated and with harmonics: the dq model's harmonic terms must balance too.
    let mut sat_h = saturated;
    sat_h.emf_h5 = 0.042;
    sat_h.emf_h7 = 0.025;
    for (name, model) in [
        ("linear", linear),
        ("saturated", saturated),
        ("saturated+h", sat_h),
    ] {
        assert!(model.uses_dq_frame());
        // 150 V pushes several amperes, well into saturation along +d at times.
        let (res, e_in) = energy_balance(model, 150.0, 1.0);
        eprintln!("interior {name}: residual {res:e} J of {e_in:.3} J");
        assert!(e_in > 10.0);
        assert!(
            res.abs() < 1e-4 * e_in,
            "{name}: residual {res} J vs input {e_in} J"
        );
    }
}

/// Drives the motor at constant speed with a synchronous voltage `v_dq` until steady state and
/// returns the dq currents.
fn steady_dq(model: MotorModel, omega_m: f64, v_dq: [f64; 2]) -> [f64; 2] {
    let w = model.params.p() * omega_m;
    let theta0 = 0.4;
    let mut m = Motor::new(model, theta0, 0.0).unwrap();
    m.set_mechanics(Mechanics::ConstantSpeed(omega_m)).unwrap();
    let dt = 5e-6;
    let n = 40_000; // 0.2 s: over 35 electrical time constants
    // Zero-order hold whose fundamental is exactly the wanted rotating vector: sample half a
    // step ahead (cancels the hold's delay) and divide by sinc (its gain).
    let half = 0.5 * w * dt;
    let gain = half / libm::sin(half);
    for k in 0..n {
        let th = theta0 + w * (k as f64 * dt) + half;
        let v = inverse_park([gain * v_dq[0], gain * v_dq[1]], th);
        m.step(v[0], v[1], 0.0, dt).unwrap();
    }
    m.i_dq()
}

/// Phasor (dq steady-state) solution of `v_d = R i_d − ω L_q i_q`, `v_q = R i_q + ω L_d i_d + ω ψ`.
fn phasor(p: &MotorParams, omega_m: f64, v_dq: [f64; 2]) -> [f64; 2] {
    let w = p.p() * omega_m;
    let (a, b, c, d) = (p.rs_ohm, -w * p.lq_h, w * p.ld_h, p.rs_ohm);
    let (r0, r1) = (v_dq[0], v_dq[1] - w * p.flux_wb);
    let det = a * d - b * c;
    [(r0 * d - b * r1) / det, (a * r1 - c * r0) / det]
}

#[test]
fn steady_state_matches_phasor_solution() {
    let mut b_linear = MotorModel::new(motor_b());
    b_linear.saturation = Saturation::Linear;
    let cases = [
        ("A", MotorModel::new(motor_a()), 100.0, [-20.0, 110.0]),
        ("B", b_linear, 200.0, [-60.0, 210.0]),
    ];
    for (name, model, omega_m, v_dq) in cases {
        let i = steady_dq(model, omega_m, v_dq);
        let i_ref = phasor(&model.params, omega_m, v_dq);
        let mag = libm::hypot(i_ref[0], i_ref[1]);
        let err = libm::hypot(i[0] - i_ref[0], i[1] - i_ref[1]) / mag;
        eprintln!("motor {name}: i_dq {i:?}, phasor {i_ref:?}, relative error {err:e}");
        assert!(mag > 1.0);
        assert!(err < 1e-4, "motor {name}: relative error {err}");
    }
}

/// Runs 20 ms of excitation in PWM-sized steps at sub-step scale `scale`.
fn run_for_convergence(model: MotorModel, scale: f64) -> MotorState {
    let mut m = Motor::new(model, 0.1, 5.0).unwrap();
    m.set_substep_scale(scale).unwrap();
    let dt = 1.0 / 14e3;
    for k in 0..280 {
        let v = excitation(k as f64 * dt, 150.0);
        m.step(v[0], v[1], 0.5, dt).unwrap();
    }
    m.state()
}

#[test]
fn rk4_converged_at_default_substep() {
    let mut a = MotorModel::new(motor_a());
    a.emf_h5 = 0.042;
    a.emf_h7 = 0.025;
    for (name, model) in [
        ("A+harmonics", a),
        ("B saturated", MotorModel::new(motor_b())),
    ] {
        let s1 = run_for_convergence(model, 1.0);
        let s2 = run_for_convergence(model, 0.5);
        let i_scale = libm::hypot(s1.i_alpha_a, s1.i_beta_a).max(1.0);
        let d = [
            (s1.i_alpha_a - s2.i_alpha_a).abs() / i_scale,
            (s1.i_beta_a - s2.i_beta_a).abs() / i_scale,
            (s1.theta_e_rad - s2.theta_e_rad).abs() / s1.theta_e_rad.abs().max(1.0),
            (s1.omega_m_rad_s - s2.omega_m_rad_s).abs() / s1.omega_m_rad_s.abs().max(1.0),
        ];
        let worst = d.iter().fold(0.0_f64, |a, &b| a.max(b));
        eprintln!(
            "{name}: |i| {i_scale:.3} A, halving the sub-step changes the state by {worst:e}"
        );
        assert!(worst < 1e-7, "{name}: {d:?}");
    }
}

#[test]
fn locked_rotor_step_matches_exponential() {
    // Linear magnetics, rotor held: i(t) = V/R (1 − e^{−R t / L}) along the voltage.
    for (model, l) in [
        (MotorModel::new(motor_a()), motor_a().ld_h),
        (
            MotorModel {
                saturation: Saturation::Linear,
                ..MotorModel::new(motor_b())
            },
            motor_b().lq_h,
        ),
    ] {
        let r = model.params.rs_ohm;
        // Motor B's rotor at θ = π/2: the β axis is the d axis... so a β voltage sees L_d;
        // choose θ so the α voltage lies on the q axis instead (θ = −π/2 → q along +α).
        let mut m = Motor::new(model, -0.5 * PI, 0.0).unwrap();
        m.set_mechanics(Mechanics::Locked).unwrap();
        let v = 50.0;
        let mut worst: f64 = 0.0;
        for k in 1..=200 {
            m.step(v, 0.0, 0.0, 50e-6).unwrap();
            let t = k as f64 * 50e-6;
            let exact = v / r * (1.0 - libm::exp(-r * t / l));
            worst = worst.max(rel(m.i_alpha_beta()[0], exact));
            assert!(m.i_alpha_beta()[1].abs() < 1e-12);
        }
        eprintln!("locked rotor: worst relative error {worst:e}");
        assert!(worst < 1e-9);
        assert!((m.state().theta_e_rad + 0.5 * PI).abs() < 1e-15);
        assert!(m.state().omega_m_rad_s.abs() < 1e-15);
    }
}

/// Peak current of a 700 µs pulse along ±d, rotor locked at `theta`.
fn pulse_peak(model: MotorModel, theta: f64, v: f64) -> f64 {
    let mut m = Motor::new(model, theta, 0.0).unwrap();
    m.set_mechanics(Mechanics::Locked).unwrap();
    let va = v * libm::cos(theta);
    let vb = v * libm::sin(theta);
    // Peak at the end of the pulse (the current rises monotonically).
    let mut peak: f64 = 0.0;
    for _ in 0..70 {
        m.step(va, vb, 0.0, 10e-6).unwrap();
        peak = peak.max(libm::hypot(m.i_alpha_beta()[0], m.i_alpha_beta()[1]));
    }
    peak
}

#[test]
fn saturation_gives_north_south_difference_on_motor_b() {
    let p = motor_b();
    let i_ref = Saturation::reference_current_a(&p);
    // Amplitude giving the linear model a peak of I_ref (2× rated peak) after 700 µs.
    let t = 700e-6;
    let v = i_ref * p.rs_ohm / (1.0 - libm::exp(-p.rs_ohm * t / p.ld_h));
    let theta = 1.1;
    let linear = MotorModel {
        saturation: Saturation::Linear,
        ..MotorModel::new(p)
    };
    let ln = pulse_peak(linear, theta, v);
    let ls = pulse_peak(linear, theta, -v);
    assert!(rel(ln, i_ref) < 1e-9, "linear peak {ln} vs {i_ref}");
    assert!(rel(ln, ls) < 1e-9, "linear N {ln} S {ls}");
    let sat = MotorModel::new(p);
    let n = pulse_peak(sat, theta, v);
    let s = pulse_peak(sat, theta, -v);
    let diff = (n - s) / s;
    eprintln!("motor B, {v:.1} V 700 µs pulse: N {n:.4} A, S {s:.4} A, (N−S)/S = {diff:.4}");
    assert!((0.05..=0.15).contains(&diff), "N/S difference {diff}");
}

#[test]
fn torque_formulas() {
    // Surface, no harmonics: T = K_T i_q.
    let mut m = Motor::new(MotorModel::new(motor_a()), 0.7, 0.0).unwrap();
    m.set_state(MotorState {
        i_alpha_a: 0.0,
        i_beta_a: 0.0,
        theta_e_rad: 0.7,
        omega_m_rad_s: 0.0,
    })
    .unwrap();
    let iab = inverse_park([1.0, 3.0], 0.7);
    m.set_state(MotorState {
        i_alpha_a: iab[0],
        i_beta_a: iab[1],
        theta_e_rad: 0.7,
        omega_m_rad_s: 0.0,
    })
    .unwrap();
    assert!((m.torque_nm() - 1.108 * 3.0).abs() < 1e-12);
    let i = m.i_abc();
    assert!((i[0] + i[1] + i[2]).abs() < 1e-12);
    // Interior, linear: T = 1.5 p (ψ i_q + (L_d − L_q) i_d i_q).
    let p = motor_b();
    let model = MotorModel {
        saturation: Saturation::Linear,
        ..MotorModel::new(p)
    };
    let mut m = Motor::new(model, 0.7, 0.0).unwrap();
    m.set_state(MotorState {
        i_alpha_a: iab[0],
        i_beta_a: iab[1],
        theta_e_rad: 0.7,
        omega_m_rad_s: 0.0,
    })
    .unwrap();
    let expected = 1.5 * 3.0 * (p.flux_wb * 3.0 + (p.ld_h - p.lq_h) * 1.0 * 3.0);
    assert!((m.torque_nm() - expected).abs() < 1e-12);
    let idq = m.i_dq();
    assert!((idq[0] - 1.0).abs() < 1e-12 && (idq[1] - 3.0).abs() < 1e-12);
}

#[test]
fn constant_speed_advances_angle_exactly() {
    let mut m = Motor::new(MotorModel::new(motor_b()), 0.0, 0.0).unwrap();
    m.set_mechanics(Mechanics::ConstantSpeed(100.0)).unwrap();
    for _ in 0..1000 {
        m.step(10.0, -5.0, 3.0, 1e-4).unwrap();
    }
    let s = m.state();
    assert!((s.omega_m_rad_s - 100.0).abs() < 1e-12);
    // Continuous (unwrapped) angle: 3 × 100 rad/s × 0.1 s = 30 rad.
    assert!((s.theta_e_rad - 30.0).abs() < 1e-9, "{}", s.theta_e_rad);
    assert_eq!(m.mechanics(), Mechanics::ConstantSpeed(100.0));
    let e = m.emf_alpha_beta_v();
    assert!(rel(libm::hypot(e[0], e[1]), 300.0 * 0.305) < 1e-12);
}

#[test]
fn free_rotor_coasts_down_with_friction() {
    // Voltage equal to the back-EMF keeps the current (and torque) near zero, so the speed
    // follows the friction law ω_m(t) = ω_0 e^{−B t / J}.
    let p = motor_a();
    let mut m = Motor::new(MotorModel::new(p), 0.0, 10.0).unwrap();
    let dt = 1e-4;
    for _ in 0..1000 {
        // EMF at mid-step: the hold's lag would otherwise drive a current.
        let s = m.state();
        let w = p.p() * s.omega_m_rad_s;
        let e = inverse_park([0.0, p.flux_wb * w], s.theta_e_rad + 0.5 * w * dt);
        m.step(e[0], e[1], 0.0, dt).unwrap();
    }
    let exact = 10.0 * libm::exp(-p.b_nm_s / p.j_kg_m2 * 0.1);
    let err = rel(m.state().omega_m_rad_s, exact);
    assert!(
        err < 1e-4,
        "{} vs {exact}: {err:e}",
        m.state().omega_m_rad_s
    );
    assert!(libm::hypot(m.i_alpha_beta()[0], m.i_alpha_beta()[1]) < 1e-3);
}

#[test]
fn bad_inputs_are_errors_and_leave_state_unchanged() {
    let mut m = Motor::new(MotorModel::new(motor_b()), 0.2, 1.0).unwrap();
    m.step(10.0, 0.0, 0.0, 1e-4).unwrap();
    let before = m.state();
    assert_eq!(
        m.step(f64::NAN, 0.0, 0.0, 1e-4),
        Err(PlantError::NonFinite("v_alpha_v"))
    );
    assert_eq!(
        m.step(0.0, f64::INFINITY, 0.0, 1e-4),
        Err(PlantError::NonFinite("v_beta_v"))
    );
    assert_eq!(
        m.step(0.0, 0.0, f64::NAN, 1e-4),
        Err(PlantError::NonFinite("load_nm"))
    );
    assert_eq!(
        m.step(0.0, 0.0, 0.0, f64::NAN),
        Err(PlantError::NonFinite("dt_s"))
    );
    assert!(matches!(m.step(0.0, 0.0, 0.0, -1e-4), Err(PlantError::Param(e)) if e.key == "dt_s"));
    assert_eq!(m.step(0.0, 0.0, 0.0, 1e9), Err(PlantError::TooManySubsteps));
    let mut calls = 0;
    let r = m.step_with(1e-4, 0.0, |_| {
        calls += 1;
        if calls > 5 {
            [f64::NAN, 0.0]
        } else {
            [1.0, 0.0]
        }
    });
    assert_eq!(r, Err(PlantError::NonFinite("state")));
    assert_eq!(m.state(), before);
    assert_eq!(
        m.set_mechanics(Mechanics::ConstantSpeed(f64::NAN)),
        Err(PlantError::NonFinite("omega_m_rad_s"))
    );
    m.step(0.0, 0.0, 0.0, 0.0).unwrap();
    assert_eq!(m.state(), before);
}

#[test]
fn invalid_models_are_rejected_with_their_key() {
    let mut model = MotorModel::new(motor_b());
    model.emf_h5 = f64::NAN;
    assert_eq!(
        Motor::new(model, 0.0, 0.0).map(|_| ()).map_err(|e| e.key),
        Err("emf_h5")
    );
    let mut model = MotorModel::new(motor_b());
    model.saturation = Saturation::Tanh { psi_s_wb: 0.3 };
    assert_eq!(
        Motor::new(model, 0.0, 0.0).map(|_| ()).map_err(|e| e.key),
        Err("saturation.psi_s_wb")
    );
    let mut p = motor_b();
    p.rs_ohm = -1.0;
    assert_eq!(
        Motor::new(MotorModel::new(p), 0.0, 0.0)
            .map(|_| ())
            .map_err(|e| e.key),
        Err("rs_ohm")
    );
    assert_eq!(
        Motor::new(MotorModel::new(motor_b()), f64::NAN, 0.0)
            .map(|_| ())
            .map_err(|e| e.key),
        Err("theta_e0_rad")
    );
}

/// Test voltage for the cross-checks: rotating 150 V of ramping frequency plus a 30 V step.
fn cross_check_voltage(t: f64) -> [f64; 2] {
    let th = 2.0 * PI * (2.0 * t + 50.0 * t * t);
    let step = if t > 0.02 { 30.0 } else { 0.0 };
    [150.0 * libm::cos(th) + step, 150.0 * libm::sin(th)]
}

#[test]
fn interior_model_matches_independent_flux_formulation() {
    // Independent statement of the same motor: state = stationary flux linkages ψ_αβ and the
    // mechanics, dψ/dt = v − R i, i = L(θ)⁻¹ (ψ − ψ_m(θ)) with the saliency matrix
    // L(θ) = [[Σ + Δ cos 2θ, Δ sin 2θ], [Δ sin 2θ, Σ − Δ cos 2θ]], T = 1.5 p (ψ_α i_β − ψ_β i_α);
    // integrated with RK4 at 1/40 of the plant's sub-step.
    let p = motor_b();
    let (sig, del) = (0.5 * (p.ld_h + p.lq_h), 0.5 * (p.ld_h - p.lq_h));
    let current = |x: &[f64; 4]| {
        let (s2, c2) = libm::sincos(2.0 * x[2]);
        let f = [
            x[0] - p.flux_wb * libm::cos(x[2]),
            x[1] - p.flux_wb * libm::sin(x[2]),
        ];
        let (a, b, d) = (sig + del * c2, del * s2, sig - del * c2);
        let det = a * d - b * b;
        [(d * f[0] - b * f[1]) / det, (a * f[1] - b * f[0]) / det]
    };
    let f = |x: &[f64; 4], v: [f64; 2], tl: f64| {
        let i = current(x);
        let t = 1.5 * p.p() * (x[0] * i[1] - x[1] * i[0]);
        [
            v[0] - p.rs_ohm * i[0],
            v[1] - p.rs_ohm * i[1],
            p.p() * x[3],
            (t - p.b_nm_s * x[3] - tl) / p.j_kg_m2,
        ]
    };
    let theta0 = 0.3;
    let mut x = [
        p.flux_wb * libm::cos(theta0),
        p.flux_wb * libm::sin(theta0),
        theta0,
        2.0,
    ];
    let model = MotorModel {
        saturation: Saturation::Linear,
        ..MotorModel::new(p)
    };
    let mut m = Motor::new(model, theta0, 2.0).unwrap();
    let dt = 1.0 / 14e3;
    let sub = 40 * (dt / m.max_substep_s()).ceil() as usize;
    let h = dt / sub as f64;
    let (mut worst_i, mut worst_th, mut worst_w): (f64, f64, f64) = (0.0, 0.0, 0.0);
    for k in 0..700 {
        let t = k as f64 * dt;
        let v = cross_check_voltage(t);
        let tl = if t > 0.03 { 1.0 } else { 0.0 };
        m.step(v[0], v[1], tl, dt).unwrap();
        for _ in 0..sub {
            let k1 = f(&x, v, tl);
            let y = |a: f64, k: &[f64; 4]| core::array::from_fn::<f64, 4, _>(|j| x[j] + a * k[j]);
            let k2 = f(&y(0.5 * h, &k1), v, tl);
            let k3 = f(&y(0.5 * h, &k2), v, tl);
            let k4 = f(&y(h, &k3), v, tl);
            for j in 0..4 {
                x[j] += h / 6.0 * (k1[j] + 2.0 * (k2[j] + k3[j]) + k4[j]);
            }
        }
        let i_ref = current(&x);
        let s = m.state();
        let i_mag = libm::hypot(i_ref[0], i_ref[1]).max(1.0);
        worst_i = worst_i.max(libm::hypot(s.i_alpha_a - i_ref[0], s.i_beta_a - i_ref[1]) / i_mag);
        worst_th = worst_th.max((s.theta_e_rad - x[2]).abs());
        worst_w = worst_w.max((s.omega_m_rad_s - x[3]).abs() / x[3].abs().max(1.0));
    }
    eprintln!("independent check: current {worst_i:e}, angle {worst_th:e} rad, speed {worst_w:e}");
    assert!(worst_i < 1e-8 && worst_th < 1e-8 && worst_w < 1e-8);
}

#[test]
fn dq_harmonics_match_alpha_beta_harmonics() {
    // A surface motor with harmonics in αβ, and the same motor forced into the dq frame by a
    // practically linear saturation (ψ_s = 1000 ψ: L_d0 = L_d (1 + 1e-6)).
    let mut p = motor_a();
    p.kt_nm_per_a = 1.5 * p.p() * p.flux_wb;
    let mut ab = MotorModel::new(p);
    ab.emf_h5 = 0.042;
    ab.emf_h7 = 0.025;
    let dq = MotorModel {
        saturation: Saturation::Tanh {
            psi_s_wb: 1000.0 * p.flux_wb,
        },
        ..ab
    };
    assert!(!ab.uses_dq_frame() && dq.uses_dq_frame());
    let mut m1 = Motor::new(ab, 0.3, 2.0).unwrap();
    let mut m2 = Motor::new(dq, 0.3, 2.0).unwrap();
    let dt = 1.0 / 14e3;
    let mut worst: f64 = 0.0;
    for k in 0..1400 {
        let v = cross_check_voltage(k as f64 * dt);
        m1.step(v[0], v[1], 0.5, dt).unwrap();
        m2.step(v[0], v[1], 0.5, dt).unwrap();
        let (s1, s2) = (m1.state(), m2.state());
        let mag = libm::hypot(s1.i_alpha_a, s1.i_beta_a).max(1.0);
        worst =
            worst.max(libm::hypot(s1.i_alpha_a - s2.i_alpha_a, s1.i_beta_a - s2.i_beta_a) / mag);
        worst = worst.max((s1.theta_e_rad - s2.theta_e_rad).abs());
        worst = worst.max(((m1.torque_nm() - m2.torque_nm()) / p.kt_nm_per_a / mag).abs());
    }
    eprintln!("αβ vs dq with harmonics: worst relative difference {worst:e}");
    assert!(worst < 1e-4, "{worst}");
}
