//! The design's defaults and resolutions.

#[cfg(not(feature = "ipd"))]
extern crate std;

use super::*;
use crate::fixtures::{inverter_b, motor_b};

/// The 24 V, 25 kHz inverter of the gimbal motors' tests (0.5 µs dead time, 2 A full scale).
fn gimbal_inverter() -> InverterParams {
    InverterParams {
        vdc_v: 24.0,
        pwm_hz: 25e3,
        dead_time_s: 0.5e-6,
        current_full_scale_a: 2.0,
    }
}

fn resolved(ld_h: f64, lq_h: f64) -> (f64, StartupMode) {
    let mut m = motor_b();
    m.ld_h = ld_h;
    m.lq_h = lq_h;
    let base = PerUnit::new(&m, &inverter_b(), 14e3).unwrap();
    let design = DriveDesign::default_for(&m, &inverter_b(), &base, EstimatorKind::MrasCurrent);
    assert_eq!(design.startup, StartupMode::Auto);
    let config = DriveConfig::new(&m, &inverter_b(), 14e3, design).unwrap();
    (StartupMode::saliency(&m), config.design.startup)
}

#[cfg(feature = "ipd")]
#[test]
fn auto_start_up_follows_the_saliency() {
    // Motor B: (40.17 − 25)/(40.17 + 25) mH = 0.233, far above 2 × 5 %: detection.
    let b = motor_b();
    let (s, mode) = resolved(b.ld_h, b.lq_h);
    assert!((s - 0.233).abs() < 0.001, "{s}");
    assert_eq!(mode, StartupMode::Ipd);
    // A surface motor: alignment.
    assert_eq!(resolved(0.03, 0.03), (0.0, StartupMode::Align));
    // Either side of the threshold 2 × 5 % = 10 %: 8 % aligns, 12 % detects.
    let (s, mode) = resolved(0.0230, 0.0270);
    assert!((s - 0.08).abs() < 1e-9 && mode == StartupMode::Align, "{s}");
    let (s, mode) = resolved(0.0220, 0.0280);
    assert!((s - 0.12).abs() < 1e-9 && mode == StartupMode::Ipd, "{s}");
    // L_d > L_q counts by its magnitude.
    assert_eq!(resolved(b.lq_h, b.ld_h).1, StartupMode::Ipd);
    // A mode given explicitly is kept.
    let base = PerUnit::new(&b, &inverter_b(), 14e3).unwrap();
    let ipd = IpdDesign::default();
    assert_eq!(
        StartupMode::Align.resolve(&b, &base, &ipd),
        StartupMode::Align
    );
    assert_eq!(
        StartupMode::Known(Angle::ZERO).resolve(&b, &base, &ipd),
        StartupMode::Known(Angle::ZERO)
    );
}

/// Without the feature `ipd` motor B (23 % saliency) starts by the alignment, and a design
/// that asks for the detection is refused by the key's name.
#[cfg(not(feature = "ipd"))]
#[test]
fn a_build_without_the_detection_aligns_and_refuses_it() {
    let b = motor_b();
    assert_eq!(resolved(b.ld_h, b.lq_h).1, StartupMode::Align);
    let base = PerUnit::new(&b, &inverter_b(), 14e3).unwrap();
    let mut design = DriveDesign::default_for(&b, &inverter_b(), &base, EstimatorKind::MrasCurrent);
    design.startup = StartupMode::Ipd;
    let e = DriveConfig::new(&b, &inverter_b(), 14e3, design).unwrap_err();
    assert!(std::format!("{e}").contains("startup"), "{e}");
}

/// The speed loop's default bandwidth: the sample rate's on motor B (a heavy rotor; with the
/// current-model MRAS the resistance's bound, below it), raised to `4/τ_b` on a light one and
/// capped at `0.005/T_s`; the dip under a step of base torque
/// (`ω_b/(e ω_n τ_b)`, a fraction of base speed) is at most a tenth wherever the cap allows.
#[test]
fn a_light_rotor_gets_a_stiffer_speed_loop() {
    let bandwidth = |m: &MotorParams, inv: &InverterParams, kind| {
        let base = PerUnit::new(m, inv, inv.pwm_hz).unwrap();
        let d = DriveDesign::default_for(m, inv, &base, kind);
        let tau_b = m.j_kg_m2 * base.omega_e_rad_s / m.p() / (m.kt_nm_per_a * base.current_a);
        (d.speed.bandwidth_rad_s, tau_b, base.sample_s)
    };
    let (b, inv_b) = (motor_b(), inverter_b());
    let (w, tau_b, ts) = bandwidth(&b, &inv_b, EstimatorKind::Nlo);
    assert!(4.0 / tau_b < w, "{tau_b}");
    assert!((w - 0.4 * 0.005 / ts).abs() < 1e-9, "{w}");
    // The current-model MRAS's: the resistance's bound, below the sample rate's.
    let (w, tau_b, ts) = bandwidth(&b, &inv_b, EstimatorKind::MrasCurrent);
    assert!(4.0 / tau_b < w && w < 0.005 / ts, "{w} {tau_b}");
    assert!(
        (w - resistance_bandwidth_rad_s(&b, 1.0)).abs() < 1e-9,
        "{w}"
    );
    // A gimbal motor at 25 kHz with a camera of six times its rotor's inertia: 4/τ_b (the
    // dip a tenth of base speed).
    let mut gimbal = MotorParams::new(11, 5.55, 1.4e-3, 1.4e-3, 0.01856, 1e-4, 1e-6);
    gimbal.rated_current_a = Some(0.35);
    let inv = gimbal_inverter();
    let (w, tau_b, ts) = bandwidth(&gimbal, &inv, EstimatorKind::Nlo);
    assert!(
        (w * tau_b - SPEED_STIFFNESS).abs() < 1e-9 && w < SPEED_BANDWIDTH_MAX_TS / ts,
        "{w} {tau_b}"
    );
    assert!(1.0 / (core::f64::consts::E * w * tau_b) < 0.1);
    // Its bare rotor: the cap.
    gimbal.j_kg_m2 = 1.5e-5;
    let (w, _, ts) = bandwidth(&gimbal, &inv, EstimatorKind::Nlo);
    assert!((w - SPEED_BANDWIDTH_MAX_TS / ts).abs() < 1e-9, "{w}");
    // The MRAS on the EMF keeps its own (its speed is its adaptation's).
    let (w, _, ts) = bandwidth(&gimbal, &inv, EstimatorKind::MrasEmf);
    assert!((w - 0.4 * 0.005 / ts).abs() < 1e-9, "{w}");
}

/// With the speed-adaptive estimators the designed speed loop keeps `K_pΩ ε R/ψ`, the gain of
/// the path from its current through the resistance's error `ε R` to the estimated speed,
/// below one for `ε` up to `SPEED_LOOP_R_ERROR`, on motors light and heavy; the sample rate's
/// bandwidth on motor B would not (1.2).
#[test]
fn the_speed_loop_survives_the_resistance_s_error() {
    let gain = |m: &MotorParams, inv: &InverterParams, kind, bandwidth: Option<f64>| {
        let base = PerUnit::new(m, inv, inv.pwm_hz).unwrap();
        let mut d = DriveDesign::default_for(m, inv, &base, kind);
        if let Some(w) = bandwidth {
            d.speed.bandwidth_rad_s = w;
        }
        let config = DriveConfig::new(m, inv, inv.pwm_hz, d).unwrap();
        // K_pΩ in A per electrical rad/s; the speed error ΔR i_q/ψ in electrical rad/s.
        config.speed.gains_si.1 * SPEED_LOOP_R_ERROR * m.rs_ohm / m.flux_wb
    };
    let (b, inv) = (motor_b(), inverter_b());
    // The current-model MRAS at the bound; the MRAS on the EMF below it (its own, slower).
    let g = gain(&b, &inv, EstimatorKind::MrasCurrent, None);
    assert!(g < 1.0 && g > 0.9, "{g}");
    let g = gain(&b, &inv, EstimatorKind::MrasEmf, None);
    assert!(g < 0.7, "{g}");
    let mut heavy = b;
    heavy.j_kg_m2 *= 10.0;
    let g = gain(&heavy, &inv, EstimatorKind::MrasCurrent, None);
    assert!(g < 1.0 && g > 0.9, "{g}");
    let mut light = b;
    light.j_kg_m2 /= 10.0;
    assert!(gain(&light, &inv, EstimatorKind::MrasCurrent, None) < 0.5);
    let g = gain(
        &b,
        &inv,
        EstimatorKind::MrasCurrent,
        Some(0.005 * inv.pwm_hz),
    );
    assert!(g > 1.1, "{g}");
}

/// The MRAS on the EMF hands over where its adaptation's loop `s² + (|ω|/c3) s + ψ² c2 |ω|`
/// (the constants `MrasEmfConfig::default_for` designs) is damped at least ½: at a tenth of
/// rated speed where that is fast enough (motor B at 14 kHz: ζ = 0.82), at the damped
/// speed on a slow motor (two pole pairs, 1055 r/min: ζ = 0.40 at a tenth); the other
/// estimators hand over at a tenth.
#[test]
fn the_mras_on_the_emf_hands_over_where_its_adaptation_is_damped() {
    let handover = |m: &MotorParams, inv: &InverterParams, kind| {
        let base = PerUnit::new(m, inv, inv.pwm_hz).unwrap();
        let d = DriveDesign::default_for(m, inv, &base, kind);
        let w = d.open_loop.handover_speed_rad_s;
        let c = MrasEmfConfig::default_for(m, &base, default_observer_gain(m, &base)).unwrap();
        let [_, c2, c3] = c.constants;
        let zeta = (w / c3) / (2.0 * (m.flux_wb * m.flux_wb * c2 * w).sqrt());
        (w / rated_e_rad_s(m, &base), zeta)
    };
    let (b, inv_b) = (motor_b(), inverter_b());
    let (share, zeta) = handover(&b, &inv_b, EstimatorKind::MrasEmf);
    assert!(
        (share - 0.1).abs() < 1e-12 && (zeta - 0.82).abs() < 0.01,
        "{share} {zeta}"
    );
    let mut slow = MotorParams::new(2, 0.5822, 0.016699, 0.016699, 0.51839, 0.0076614, 0.0034);
    slow.rated_speed_rpm = Some(1055.0);
    slow.rated_current_a = Some(8.24);
    let inv = InverterParams {
        vdc_v: 320.0,
        pwm_hz: 14e3,
        dead_time_s: 1.06e-6,
        current_full_scale_a: 30.0,
    };
    let (share, zeta) = handover(&slow, &inv, EstimatorKind::MrasEmf);
    assert!(
        (zeta - crate::tuning::MRAS_EMF_MIN_DAMPING).abs() < 1e-9,
        "{zeta}"
    );
    assert!(share > 0.15 && share < 0.17, "{share}");
    for kind in [EstimatorKind::Ao, EstimatorKind::Nlo] {
        let (share, zeta) = handover(&slow, &inv, kind);
        assert!(
            (share - 0.1).abs() < 1e-12 && zeta < 0.41,
            "{kind:?}: {share} {zeta}"
        );
    }
}

/// The open loop's default acceleration takes a fifth of the torque of its current, but
/// reaches the handover speed in no less than `MIN_OPEN_LOOP_RAMP_S`: motor B ramps at
/// 0.2 p K_T I/J (115 ms); the GM4108H gimbal motor (11 pole pairs, 1.5·10⁻⁵ kg·m², whose
/// rotor a fifth of its torque takes to a tenth of rated speed in 1.6 ms) over the floor.
#[test]
fn the_open_loop_ramp_lasts_at_least_its_floor() {
    let ramp = |m: &MotorParams, inv: &InverterParams| {
        let base = PerUnit::new(m, inv, inv.pwm_hz).unwrap();
        let d = OpenLoopDesign::default_for(m, &base);
        let torque = 0.2 * m.p() * m.kt_nm_per_a * base.current_a / m.j_kg_m2;
        (
            d.handover_speed_rad_s / d.accel_rad_s2,
            d.accel_rad_s2 / torque,
        )
    };
    let (b, inv_b) = (motor_b(), inverter_b());
    let (t, share) = ramp(&b, &inv_b);
    assert!(
        t > MIN_OPEN_LOOP_RAMP_S && (share - 1.0).abs() < 1e-12,
        "{t} {share}"
    );
    let mut gimbal = MotorParams::new(11, 5.55, 0.0014, 0.0014, 0.01856, 1.5e-5, 4.8e-5);
    gimbal.rated_speed_rpm = Some(300.0);
    gimbal.rated_current_a = Some(0.35);
    let (t, share) = ramp(&gimbal, &gimbal_inverter());
    assert!(
        (t - MIN_OPEN_LOOP_RAMP_S).abs() < 1e-12 && share < 0.2,
        "{t} {share}"
    );
}
