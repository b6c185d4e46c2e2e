//! Unit tests of the current-model MRAS.

use super::*;
use crate::angle::Angle;
use crate::error::ConfigError;
use crate::frames::AlphaBeta;
use crate::num::Pu;
use crate::observer::{Estimator, ObserverInput};
use crate::params::{InverterParams, MotorParams};
use crate::units::PerUnit;

fn motor_b() -> (MotorParams, PerUnit) {
    (crate::fixtures::motor_b(), crate::fixtures::base_b())
}

#[test]
fn gains_out_of_range_are_named() {
    let (m, b) = motor_b();
    let mut g = MrasCurrentGains::default_for(&m, &b);
    g.kp = -1.0;
    assert!(matches!(
        MrasCurrentConfig::new(&m, &b, g),
        Err(ConfigError::Gain {
            key: "mras_current.kp",
            ..
        })
    ));
    let mut g = MrasCurrentGains::default_for(&m, &b);
    g.ki = 1e12;
    assert!(matches!(
        MrasCurrentConfig::new(&m, &b, g),
        Err(ConfigError::Gain {
            key: "mras_current.ki",
            ..
        })
    ));
}

/// The d-axis error's weight scales `ρ²` in ξ̃ (0 and 1 accepted); outside `[0, 1]`, or not a
/// number, it is a named error.
#[test]
fn the_d_weight_scales_the_d_error_and_is_checked() {
    let (m, b) = motor_b();
    let rho = m.lq_h / m.ld_h;
    for w in [0.0f32, DEFAULT_D_WEIGHT, 1.0] {
        let g = MrasCurrentGains {
            d_weight: w,
            ..MrasCurrentGains::default_for(&m, &b)
        };
        let c = MrasCurrentConfig::new(&m, &b, g).unwrap();
        let want = f64::from(w) * rho * rho;
        assert!(
            (c.rho2.to_f64() - want).abs() <= 2e-8,
            "{w}: {}",
            c.rho2.to_f64()
        );
    }
    for w in [-0.01f32, 1.01, f32::NAN] {
        let g = MrasCurrentGains {
            d_weight: w,
            ..MrasCurrentGains::default_for(&m, &b)
        };
        assert!(
            matches!(
                MrasCurrentConfig::new(&m, &b, g),
                Err(ConfigError::Gain {
                    key: "mras_current.d_weight",
                    ..
                })
            ),
            "{w}"
        );
    }
}

fn inverter(vdc_v: f64, full_scale_a: f64) -> InverterParams {
    InverterParams {
        vdc_v,
        pwm_hz: 20e3,
        dead_time_s: 0.5e-6,
        current_full_scale_a: full_scale_a,
    }
}

/// The corners of the motor family of `units` (a drone and an industrial motor, 8–20 kHz)
/// fit every format with the default gains; a motor whose `ψ/L_d` exceeds the offsets'
/// range (32 pu) is a named error, not a wrapped coefficient.
#[test]
fn family_corners_fit_and_too_small_an_inductance_is_named() {
    let mut drone = MotorParams::new(7, 0.02, 0.5e-3, 0.5e-3, 0.002, 2e-5, 1e-6);
    drone.rated_current_a = Some(60.0);
    let mut industrial = MotorParams::new(2, 4.0, 0.040, 0.048, 1.2, 0.01, 0.001);
    industrial.rated_current_a = Some(3.0);
    for hz in [8e3, 10e3, 20e3] {
        for (m, inv) in [
            (drone, inverter(24.0, 150.0)),
            (industrial, inverter(540.0, 10.0)),
        ] {
            let b = PerUnit::new(&m, &inv, hz).unwrap();
            let g = MrasCurrentGains::default_for(&m, &b);
            assert!(MrasCurrentConfig::new(&m, &b, g).is_ok(), "{m:?} {hz}");
        }
    }
    let (mut m, _) = motor_b();
    m.ld_h = 2.5e-3;
    m.lq_h = 4e-3;
    let inv = InverterParams {
        vdc_v: 540.0,
        pwm_hz: 40e3,
        dead_time_s: 2e-6,
        current_full_scale_a: 10.0,
    };
    let b = PerUnit::new(&m, &inv, 40e3).unwrap();
    let g = MrasCurrentGains::default_for(&m, &b);
    assert!(matches!(
        MrasCurrentConfig::new(&m, &b, g),
        Err(ConfigError::Gain { key: "ld_h", .. })
    ));
}

/// Without a proportional gain the integrator stops at the limit (conditional
/// integration) instead of back-calculating; wild inputs still saturate, never panic.
#[test]
fn conditional_integration_without_kp() {
    let (m, b) = motor_b();
    let mut g = MrasCurrentGains::default_for(&m, &b);
    g.kp = 0.0;
    let cfg = MrasCurrentConfig::new(&m, &b, g).unwrap();
    let mut e = MrasCurrent::new(cfg);
    e.reset(Angle::ZERO, cfg.omega_max);
    let wild = ObserverInput {
        i: AlphaBeta {
            alpha: Pu::MIN,
            beta: Pu::MAX,
        },
        v: AlphaBeta {
            alpha: Pu::MAX,
            beta: Pu::MAX,
        },
    };
    for _ in 0..100 {
        let out = e.update(&wild);
        assert!(out.omega.abs() <= cfg.omega_max);
    }
}

#[test]
fn model_at_rest_stays_at_rest_and_reset_seeds() {
    let (m, b) = motor_b();
    let cfg = MrasCurrentConfig::new(&m, &b, MrasCurrentGains::default_for(&m, &b)).unwrap();
    let mut e = MrasCurrent::new(cfg);
    e.reset(Angle::from_deg(30.0), Pu::ZERO);
    for _ in 0..1000 {
        let out = e.update(&ObserverInput::default());
        assert_eq!(out.theta, Angle::from_deg(30.0));
        assert_eq!(out.omega, Pu::ZERO);
    }
    // Wild inputs saturate, never panic.
    let wild = ObserverInput {
        i: AlphaBeta {
            alpha: Pu::MAX,
            beta: Pu::MIN,
        },
        v: AlphaBeta {
            alpha: Pu::MIN,
            beta: Pu::MAX,
        },
    };
    for _ in 0..100 {
        let out = e.update(&wild);
        assert!(out.omega.abs() <= cfg.omega_max);
    }
}

/// The schedule's thresholds are the definition's (level `j` above
/// `ω_c/√(√(b_j b_{j+1}) − 1)`, `b = (1, 3/2, 2, 3, 4)`); on motor B each level gives the
/// design gains times `b_j` from `c_j ω_c` up and the next level's just below, and the gains
/// stay fixed with the schedule off.
#[test]
fn low_speed_schedule_follows_its_definition() {
    let b = [1.0, 1.5, 2.0, 3.0, 4.0];
    for (j, (c, pair)) in BOOST_ABOVE.iter().zip(b.windows(2)).enumerate() {
        let [lo, hi] = [pair[0], pair[1]];
        let want = 1.0 / libm::sqrt(libm::sqrt(lo * hi) - 1.0);
        assert!((c - want).abs() < 1e-12, "c_{j}: {c} against {want}");
    }
    let (m, base) = motor_b();
    let g = MrasCurrentGains {
        low_speed_schedule: true,
        ..MrasCurrentGains::default_for(&m, &base)
    };
    let cfg = MrasCurrentConfig::new(&m, &base, g).unwrap();
    assert_eq!(cfg.top as usize, BOOST_LEVELS - 1);
    let corner = m.rs_ohm / libm::sqrt(m.ld_h * m.lq_h) / base.omega_e_rad_s;
    let fixed = cfg.design;
    for (j, factor) in b.iter().enumerate() {
        // Just above the level's threshold (the last level: at standstill).
        let speed = BOOST_ABOVE.get(j).map_or(0.0, |c| c * corner * 1.001);
        let level = cfg.gains_at(crate::num::pu_from_f64(speed));
        for (name, got, design) in [
            ("K_p", level.kp.to_f64(), fixed.kp.to_f64()),
            ("K_i", level.ki_ts.to_f64(), fixed.ki_ts.to_f64()),
            ("K_L", level.load_gain.to_f64(), fixed.load_gain.to_f64()),
        ] {
            let ratio = got / design;
            assert!((ratio - factor).abs() < 1e-6, "level {j}: {name} × {ratio}");
        }
        // And just below it, the next level's (more) gain.
        if j + 1 < BOOST_LEVELS {
            let below = cfg.gains_at(crate::num::pu_from_f64(speed / 1.002));
            assert!(below.kp.bits() > level.kp.bits(), "below level {j}");
        }
    }
    let off = MrasCurrentConfig::new(
        &m,
        &base,
        MrasCurrentGains {
            low_speed_schedule: false,
            ..g
        },
    )
    .unwrap();
    assert_eq!(off.gains_at(Pu::ZERO), off.design);
    assert_eq!(off.design, fixed);
}

/// The default design against its definition in f64 (`libm::sqrt`): motor B's rotor keeps
/// `ω_n = 0.02/T_s`; lighter rotors raise it towards `√(a I_b/0.15)` within `0.06/T_s` and the
/// formats' room, and the configuration takes the gains.
#[test]
fn default_design_follows_its_definition() {
    let (m, b) = motor_b();
    let ts = b.sample_s;
    let floor = 0.02 / ts;
    let reference = |m: &MotorParams| {
        let (k, rho) = ((m.flux_wb / m.lq_h).powi(2), m.lq_h / m.ld_h);
        let a = m.p() * m.kt_nm_per_a / m.j_kg_m2;
        let c = b.current_a * b.current_a / (rho * b.omega_e_rad_s * k);
        let wn = libm::sqrt(a * b.current_a / 0.15)
            .min(libm::sqrt(0.75 / (1.5 * ts * c)))
            .min(0.06 / ts);
        let kl_pu = wn * wn * wn * ts * b.current_a / (4.0 * a * k * rho);
        if kl_pu > 8.0 { floor } else { wn.max(floor) }
    };
    let got = MrasCurrentGains::default_bandwidth_rad_s(&m, &b);
    assert!((got - floor).abs() < 1e-9 * floor, "{got}");
    assert_eq!(
        MrasCurrentGains::default_for(&m, &b),
        MrasCurrentGains::design(&m, got)
    );
    let mut raised = 0;
    for j in [0.3, 0.1, 0.03, 0.01] {
        let mut light = m;
        light.j_kg_m2 *= j;
        let (got, want) = (
            MrasCurrentGains::default_bandwidth_rad_s(&light, &b),
            reference(&light),
        );
        assert!((got - want).abs() < 1e-9 * want, "J × {j}: {got} {want}");
        raised += (got > 1.01 * floor) as u32;
        let g = MrasCurrentGains::default_for(&light, &b);
        assert!(!g.low_speed_schedule);
        assert!(MrasCurrentConfig::new(&light, &b, g).is_ok());
    }
    assert!(raised >= 2, "{raised}");
}

/// Held, the MRAS keeps `ξ = 0` and its model on the measured current, and its speed moves by
/// the mechanical model alone: against the f64 recursion
/// `ω ← ω + T_s a (i_q − i_L) − T_s (B/J) ω` (the load estimate stays at zero) within 1e−6 pu
/// over the hold, on a current the model does not explain; the update after it starts afresh
/// (`ξ = 0`, the speed kept, as after a reset), and the next adapts again.
#[test]
fn a_held_update_follows_the_mechanical_model_alone() {
    let (m, b) = motor_b();
    let cfg = MrasCurrentConfig::new(&m, &b, MrasCurrentGains::default_for(&m, &b)).unwrap();
    let mut e = MrasCurrent::new(cfg);
    e.reset(Angle::from_deg(10.0), Pu::from_num(0.02));
    // A stationary current of 0.4 pu and no voltage: the model cannot explain it.
    let input = ObserverInput {
        i: AlphaBeta {
            alpha: Pu::from_num(0.1),
            beta: Pu::from_num(0.4),
        },
        v: AlphaBeta::default(),
    };
    e.update(&input);
    let a = m.p() * m.kt_nm_per_a * b.current_a * b.sample_s / (m.j_kg_m2 * b.omega_e_rad_s);
    let f = b.sample_s * m.b_nm_s / m.j_kg_m2;
    let mut omega = e.estimate().omega.to_num::<f64>();
    let n = 8;
    e.hold(n);
    for k in 0..n {
        let out = e.update(&input);
        let (_, i_dq) = e.frame();
        omega += a * i_dq.q.to_num::<f64>() - f * omega;
        assert_eq!(e.xi(), Pu::ZERO, "update {k}");
        assert_eq!(e.health(), Pu::ZERO, "update {k}");
        let got = out.omega.to_num::<f64>();
        assert!(
            (got - omega).abs() < 1e-6,
            "update {k}: {got} against {omega}"
        );
    }
    // The held speed has moved: the comparison above is not of constants.
    assert!((omega - 0.02).abs() > 1e-4, "{omega}");
    let kept = e.estimate().omega;
    let out = e.update(&input);
    assert_eq!((e.xi(), out.omega), (Pu::ZERO, kept));
    e.update(&input);
    let xi = e.xi().to_num::<f64>();
    assert!(xi.abs() > 1e-3, "released: ξ' {xi}");
}

/// The task's `f32` model against the `f64` reference for the same scaled motor: on motor B,
/// the family's drone and industrial corners and a slow motor (`R T_s/(2L)` of 10⁻⁶), over
/// `R/R₀` from 0.5 to 2 and `ψ/ψ₀` from 0.7 to 1.3, every coefficient within 2⁻²¹ of itself
/// plus 4 LSB, and the pole `1 − a²` within 10⁻⁵ of itself.
#[test]
fn the_task_s_scaled_model_is_the_reference_s() {
    let (b, bb) = motor_b();
    let mut drone = MotorParams::new(7, 0.02, 0.5e-3, 0.5e-3, 0.002, 2e-5, 1e-6);
    drone.rated_current_a = Some(60.0);
    let mut industrial = MotorParams::new(2, 4.0, 0.040, 0.048, 1.2, 0.01, 0.001);
    industrial.rated_current_a = Some(3.0);
    let mut slow = b;
    slow.rs_ohm = 0.02;
    let cases = [
        (b, bb),
        (
            drone,
            PerUnit::new(&drone, &inverter(24.0, 150.0), 8e3).unwrap(),
        ),
        (
            industrial,
            PerUnit::new(&industrial, &inverter(540.0, 10.0), 20e3).unwrap(),
        ),
        (slow, bb),
    ];
    let (mut worst, mut worst_pole) = (0.0f64, 0.0f64);
    for (m, base) in cases {
        let scaling = MrasModelScaling::new(&m, &base);
        for s_r in [0.5f32, 0.8, 1.0, 1.3, 2.0] {
            for s_psi in [0.7f32, 1.0, 1.3] {
                let mut scaled = m;
                scaled.rs_ohm *= f64::from(s_r);
                scaled.flux_wb *= f64::from(s_psi);
                let want = MrasModel::new(&scaled, &base).unwrap().bits();
                let got = scaling.model(s_r, s_psi).unwrap().bits();
                for (k, (g, w)) in got.iter().zip(want).enumerate() {
                    let err = (g - w).abs() as f64;
                    worst = worst.max(err / (4.0 + w.abs() as f64 * 2f64.powi(-21)));
                    if k == 0 || k == 4 {
                        let pole = (1i64 << MODEL_FRAC) - w;
                        worst_pole = worst_pole.max(err / pole as f64);
                    }
                }
            }
        }
    }
    assert!(worst <= 1.0, "{worst}");
    assert!(worst_pole <= 1e-5, "{worst_pole}");
    // A scaling that takes an offset out of its format is named, as the reference names it.
    let scaling = MrasModelScaling::new(&b, &bb);
    assert!(matches!(
        scaling.model(1.0, 1e3),
        Err(ConfigError::Gain { key: "ld_h", .. })
    ));
}

/// The high words' test of the speed integrator's limits answers only when the exact 64-bit
/// comparison agrees, and answers for every value more than 2³³ inside the limits.
#[test]
fn the_high_words_tell_the_integrator_inside_only_when_it_is() {
    use super::update::within_high_word;
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    let mut answered = 0;
    for k in 0..200_000 {
        // Limits of ±4 pu in Q9.55 and a few others, some not a whole number of high words.
        let hi = match k % 3 {
            0 => 4i64 << 55,
            1 => (next() >> 6) as i64,
            _ => ((next() >> 6) as i64) & !0xffff_ffff,
        };
        let x = match k % 4 {
            0 => next() as i64,
            1 => (next() as i64) >> 5,
            2 => hi - 2 + (next() % 5) as i64,
            _ => -hi - 2 + (next() % 5) as i64,
        };
        let exact = -hi < x && x < hi;
        if within_high_word(x, hi) {
            assert!(exact, "{x} within ±{hi}?");
            answered += 1;
        } else if exact {
            // Unanswered inside: only within 2³³ of a limit.
            assert!(x > hi - (1 << 33) || x < -hi + (1 << 33), "{x} ±{hi}");
        }
    }
    assert!(answered > 10_000, "{answered}");
}
