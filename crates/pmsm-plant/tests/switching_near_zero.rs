//! The switching inverter at currents smaller than the PWM ripple: the dead-time error fades
//! out of the physics (a diode pair that blocks once its current reaches zero), not out of an
//! assumed sign band. Checked against a brute-force reference derived here for one leg.

mod common;

use common::{inverter_b, motor_a};
use pmsm_plant::motor::{Mechanics, Motor, MotorModel, MotorState};
use pmsm_plant::{Inverter, InverterKind, InverterModel, PlantError};

/// Leg `a` switching at duty `d` against legs `b` at duty 1 (upper switch on) and `c` at duty
/// 0 (lower switch on), into a surface motor with its rotor locked: a star R–L load, whose
/// phase `a` obeys `L di/dt = v_a − (v_a + V_DC)/3 − R i` on its own, whatever `i_b`, `i_c`.
///
/// Reference: that one equation integrated in 1 ns Euler steps over one PWM period from
/// `i(0) = i0`, with the leg's state at every step: lower switch until the rising command
/// edge, both off for the dead time, upper switch until the falling edge, both off for the
/// dead time, lower switch. While both are off, the lower diode conducts for `i > 0`
/// (`v_a = 0`), the upper one for `i < 0` (`v_a = V_DC`); a current that reaches zero there
/// stays at zero (both diodes block) with `v_a` at the value that holds it,
/// `v_a = V_DC/2 + 1.5 R·0 = V_DC/2`, which lies between the rails. Returns the period average
/// of `v_a` and `i(T)`.
fn reference(
    d: f64,
    i0: f64,
    r_ohm: f64,
    l_h: f64,
    vdc: f64,
    t_dead: f64,
    period: f64,
) -> (f64, f64) {
    let h = 1e-9;
    let n = (period / h).round() as usize;
    let h = period / n as f64;
    let (rise, fall) = (0.5 * (1.0 - d) * period, 0.5 * (1.0 + d) * period);
    let mut i = i0;
    let mut area = 0.0;
    let mut held = false;
    for k in 0..n {
        let t = (k as f64 + 0.5) * h;
        let dead = (t >= rise && t < rise + t_dead) || (t >= fall && t < fall + t_dead);
        if !dead {
            held = false;
        }
        let v_a = if !dead {
            if t >= rise && t < fall { vdc } else { 0.0 }
        } else if held {
            0.5 * vdc
        } else if i > 0.0 {
            0.0
        } else {
            vdc
        };
        let rate = |v: f64, i: f64| ((2.0 / 3.0) * v - vdc / 3.0 - r_ohm * i) / l_h;
        let di = rate(v_a, i) * h;
        if dead && !held && i != 0.0 && (i + di) * i < 0.0 {
            // The diode's current reaches zero within the step: the rest of it held at zero.
            let frac = -i / di;
            area += (v_a * frac + 0.5 * vdc * (1.0 - frac)) * h;
            i = 0.0;
            held = true;
        } else {
            area += v_a * h;
            i += di;
        }
    }
    (area / period, i)
}

/// The plant's switching inverter over one period from `i_a(0) = i0`: the period average of
/// leg `a` and `i_a(T)`.
fn plant(model: InverterModel, d: f64, i0: f64) -> Result<(f64, f64), PlantError> {
    let mut motor = Motor::new(MotorModel::new(motor_a()), 0.0, 0.0)?;
    motor.set_mechanics(Mechanics::Locked)?;
    motor.set_state(MotorState {
        i_alpha_a: i0,
        i_beta_a: 0.3,
        theta_e_rad: 0.0,
        omega_m_rad_s: 0.0,
    })?;
    // One period on a scratch motor first: leg b's switch to the upper rail (from the
    // inverter's initial all-low state) and its dead time are over before the measured one.
    let mut inv = Inverter::new(model)?;
    let mut scratch = motor.clone();
    inv.step_period(&mut scratch, [d, 1.0, 0.0], model.params.vdc_v, 0.0)?;
    inv.step_period(&mut motor, [d, 1.0, 0.0], model.params.vdc_v, 0.0)?;
    Ok((inv.leg_average_v()[0], motor.i_abc()[0]))
}

#[test]
fn switching_leg_voltage_near_zero_current_matches_the_brute_force_reference() {
    let params = inverter_b(); // 540 V, 14 kHz, 2 µs
    let mut model = InverterModel::new(params, InverterKind::Switching);
    model.sign_band_a = 0.0; // the hard sign of the instantaneous current
    let m = motor_a();
    let (vdc, t_dead, period) = (params.vdc_v, params.dead_time_s, 1.0 / params.pwm_hz);
    // The ripple of phase a: ±V_DC/3 across L for half a period at d = 0.5, 0.48 A peak to peak.
    let ripple_pp = vdc / 3.0 * 0.5 * period / m.ld_h;
    assert!(ripple_pp > 0.4, "{ripple_pp}");
    let v_dead = model.dead_voltage_v(vdc);
    let mut worst_v: f64 = 0.0;
    let mut worst_i: f64 = 0.0;
    let mut inside = 0;
    for d in [0.3, 0.5, 0.62] {
        for k in -20..=20 {
            // Mean currents within ±0.3 A: inside and around the ripple.
            let i0 = 0.015 * k as f64;
            let (v_ref, i_ref) = reference(d, i0, m.rs_ohm, m.ld_h, vdc, t_dead, period);
            let (v, i) = plant(model, d, i0).expect("plant");
            worst_v = worst_v.max((v - v_ref).abs());
            worst_i = worst_i.max((i - i_ref).abs());
            // The error against the ideal leg d·V_DC lies between the two hard-sign values,
            // strictly inside where the ripple crosses zero in a dead time.
            let err = d * vdc - v;
            assert!(err.abs() <= v_dead + 0.05, "d {d} i0 {i0}: {err} V");
            if err.abs() < 0.9 * v_dead {
                inside += 1;
            }
        }
    }
    eprintln!("leg average: worst {worst_v:.2e} V; i(T): worst {worst_i:.2e} A; {inside} partial");
    // 0.02 V (the reference's own 1 ns edges: 540 V · 1 ns/T = 8 mV) against a dead-time voltage of 15.1 V, 0.1 mA against a 0.48 A ripple.
    assert!(
        worst_v < 0.05,
        "leg average off the reference by {worst_v} V"
    );
    assert!(worst_i < 1e-4, "current off the reference by {worst_i} A");
    // The physics does smooth the sign: several mean currents get a partial error.
    assert!(inside >= 6, "{inside}");
}

/// Motor A locked, all currents zero, duties `d` for `n` periods of the hard-sign switching
/// model: the largest phase current at the end, A.
fn from_zero_current(d: [f64; 3], n: usize) -> f64 {
    let mut model = InverterModel::new(inverter_b(), InverterKind::Switching);
    model.sign_band_a = 0.0;
    let mut motor = Motor::new(MotorModel::new(motor_a()), 0.0, 0.0).unwrap();
    motor.set_mechanics(Mechanics::Locked).unwrap();
    let mut inv = Inverter::new(model).unwrap();
    for _ in 0..n {
        inv.step_period(&mut motor, d, 540.0, 0.0).unwrap();
    }
    motor.i_abc().iter().fold(0.0, |a: f64, x| a.max(x.abs()))
}

#[test]
fn zero_current_clamp_from_the_dead_time() {
    // Equal duties at zero current: every node holds its rail through its dead time (nothing
    // moves it), each pulse is shifted by the dead time whole, and no current flows.
    assert!(from_zero_current([0.5; 3], 20) < 1e-9);
    // From zero current a leg's edge must lead another's by more than the dead time before
    // both are switched at once to different rails: with ideal devices, duties closer than
    // 2 T_dead/T (0.056 at 2 µs, 14 kHz) drive no current at all, wider ones do.
    let gap = 2.0 * 2e-6 * 14e3;
    assert!(from_zero_current([0.5 + 0.45 * gap, 0.5, 0.5 - 0.45 * gap], 20) < 1e-9);
    let i = from_zero_current([0.5 + 0.6 * gap, 0.5, 0.5 - 0.6 * gap], 20);
    assert!(i > 0.01, "{i}");
}
