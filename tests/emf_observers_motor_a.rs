//! Solsona, Valla, Muravchik (2000): the NLO, the AO and Tomita's MRAS on motor A,
//! the paper's experiments (Fig. 1–4 and its text on parameter errors), each a test with numeric bounds. All in fixed point at 20 kHz, on
//! the torque-consistent prescribed trajectories of `pmsm_tests::trajectory`.

use pmsm_core::MotorParams;
use pmsm_core::{Ao, AoConfig, Estimator, MrasEmf, MrasEmfConfig, Nlo, NloConfig};
use pmsm_tests::observers::*;
use pmsm_tests::trajectory::{Profile, Sample, Trajectory, motor_a};

const FS: f64 = 20e3;
const TS: f64 = 1.0 / FS;
const VDC: f64 = 300.0;

#[derive(Clone, Copy, Debug, PartialEq)]
enum Kind {
    Nlo,
    Ao,
    Mras,
}

/// Runs one estimator of `kind` (configured with `est_motor`, gain `g`) on `tr` for `seconds`.
fn run(
    kind: Kind,
    est_motor: &MotorParams,
    g: f64,
    tr: &Trajectory,
    seconds: f64,
) -> (Vec<Sample>, Vec<Est>) {
    let b = base(est_motor, VDC, FS);
    let s = tr.samples(TS, (seconds * FS) as usize);
    let est = match kind {
        Kind::Nlo => run_fixed(
            &mut Nlo::new(NloConfig::new(est_motor, &b, g).unwrap()),
            &b,
            &s,
        ),
        Kind::Ao => run_fixed(
            &mut Ao::new(AoConfig::new(est_motor, &b, g).unwrap()),
            &b,
            &s,
        ),
        Kind::Mras => run_fixed(
            &mut MrasEmf::new(MrasEmfConfig::paper(est_motor, &b, g).unwrap()),
            &b,
            &s,
        ),
    };
    (s, est)
}

/// Mean angle error (rad) and mean relative speed error over the last `tail_s` seconds.
fn steady(
    kind: Kind,
    est_motor: &MotorParams,
    g: f64,
    tr: &Trajectory,
    seconds: f64,
    tail_s: f64,
) -> (f64, f64) {
    let (s, est) = run(kind, est_motor, g, tr, seconds);
    let e = errors(&est, &s);
    let from = e.len() - (tail_s * FS) as usize;
    let w = s[s.len() - 1].omega_e_rad_s;
    (mean(&e, from, |x| x.0), mean(&e, from, |x| x.1) / w.abs())
}

/// Fig. 1: constant speed, several initial conditions. The AO converges to eq. 13–14
/// (within 3 % and 8 %), the NLO to zero, the MRAS to zero speed error.
#[test]
fn constant_speed_convergence() {
    let m = motor_a();
    for w_m in [120.0, 60.0, 12.0] {
        for theta0 in [0.3, 2.0, -2.9] {
            let mut tr = Trajectory::new(m, Profile::constant(w_m));
            tr.theta0_rad = theta0;
            let omega = 3.0 * w_m;
            let (ew, et) = ao_steady_errors(omega, 1000.0);
            let (ao_t, ao_w) = steady(Kind::Ao, &m, 1000.0, &tr, 0.5, 0.1);
            assert!(
                (ao_t - et).abs() <= 0.03 * et.abs(),
                "AO angle {ao_t} vs eq. 14 {et} at {w_m}"
            );
            assert!(
                (ao_w * omega - ew).abs() <= 0.08 * ew.abs(),
                "AO speed {} vs eq. 13 {ew}",
                ao_w * omega
            );
            let (nlo_t, nlo_w) = steady(Kind::Nlo, &m, 1000.0, &tr, 0.5, 0.1);
            assert!(
                deg(nlo_t).abs() < 0.01,
                "NLO angle {}° at {w_m}",
                deg(nlo_t)
            );
            assert!(nlo_w.abs() < 1e-4, "NLO speed {nlo_w} at {w_m}");
        }
        // The MRAS converges to zero speed error, more slowly than both.
        let tr = Trajectory::new(m, Profile::constant(w_m));
        let (_, mras_w) = steady(Kind::Mras, &m, 1000.0, &tr, 1.5, 0.2);
        assert!(mras_w.abs() < 0.005, "MRAS speed {mras_w} at {w_m}");
        // Time after which the speed error stays within 2 % of the speed of its final value.
        let settle = |kind| {
            let (s, est) = run(kind, &m, 1000.0, &tr, 1.0);
            let e = errors(&est, &s);
            let last = e[e.len() - 1].1;
            e.iter()
                .rposition(|x| (x.1 - last).abs() > 0.02 * 3.0 * w_m)
                .unwrap_or(0) as f64
                * TS
        };
        let (t_mras, t_nlo, t_ao) = (settle(Kind::Mras), settle(Kind::Nlo), settle(Kind::Ao));
        println!("{w_m} rad/s: 2 % settling NLO {t_nlo:.4} s, AO {t_ao:.4} s, MRAS {t_mras:.4} s");
        assert!(
            t_mras > t_nlo && t_mras > 2.0 * t_ao.min(t_nlo),
            "MRAS {t_mras} NLO {t_nlo} AO {t_ao}"
        );
    }
}

/// NLO at rated speed in steady state: ≤ 0.05° and ≤ 0.1 % (the required bound; the float
/// reference reaches 0.004° and 0.02 %).
#[test]
fn nlo_rated_speed_steady_state() {
    let m = motor_a();
    let tr = Trajectory::new(m, Profile::constant(120.0));
    let (s, est) = run(Kind::Nlo, &m, 1000.0, &tr, 0.5);
    let e = errors(&est, &s);
    let from = e.len() - 2000;
    let angle = deg(max_abs(&e, from, |x| x.0));
    let speed = max_abs(&e, from, |x| x.1) / 360.0;
    println!(
        "NLO at 120 rad/s: max {angle:.5}°, max {:.5} %",
        100.0 * speed
    );
    assert!(angle <= 0.05 && speed <= 1e-3);
}

/// Fig. 2: 3 → 120 → 3 rad/s. The NLO is indistinguishable from the motor (≤ 0.25°
/// everywhere after convergence); the MRAS lags while accelerating; the AO's error grows with
/// speed.
#[test]
fn speed_profile_3_to_120_rad_s() {
    let m = motor_a();
    let profile = Profile::new(&[(0.3, 3.0), (2.3, 120.0), (3.3, 120.0), (5.3, 3.0)]);
    let tr = Trajectory::new(m, profile.clone());
    let (s, nlo) = run(Kind::Nlo, &m, 1000.0, &tr, 6.0);
    let e = errors(&nlo, &s);
    let after = (0.05 * FS) as usize;
    let nlo_max = deg(max_abs(&e, after, |x| x.0));
    println!("NLO max angle error after 50 ms: {nlo_max:.4}°");
    assert!(nlo_max <= 0.25, "NLO {nlo_max}°");
    // Mid-ramp (t = 1.3 s, about 60 rad/s, 58 rad/s² peak acceleration).
    let k = (1.3 * FS) as usize;
    let w = s[k].omega_e_rad_s;
    let (_, mras) = run(Kind::Mras, &m, 1000.0, &tr, 1.4);
    let mras_rel = (mras[k].omega_rad_s - w) / w;
    let nlo_rel = (nlo[k].omega_rad_s - w) / w;
    println!(
        "mid-ramp speed error: MRAS {:.2} %, NLO {:.4} %",
        100.0 * mras_rel,
        100.0 * nlo_rel
    );
    assert!(
        mras_rel < -0.02,
        "MRAS should lag while accelerating: {mras_rel}"
    );
    assert!(nlo_rel.abs() < 1e-3);
    // The AO's speed error grows with speed: larger at 120 than at 60 rad/s.
    let (_, ao) = run(Kind::Ao, &m, 1000.0, &tr, 3.3);
    let ao_err = |t: f64| {
        let k = (t * FS) as usize;
        ao[k].omega_rad_s - s[k].omega_e_rad_s
    };
    assert!(
        ao_err(3.2).abs() > 2.0 * ao_err(1.3).abs(),
        "AO {} vs {}",
        ao_err(3.2),
        ao_err(1.3)
    );
}

/// Fraction of the samples with |ω_m| > 1 rad/s where the estimated speed has the wrong sign.
fn wrong_sign(s: &[Sample], est: &[Est], p: f64) -> (usize, usize) {
    let mut n = 0;
    let mut wrong = 0;
    for (x, e) in s.iter().zip(est) {
        if x.omega_e_rad_s.abs() / p > 1.0 {
            n += 1;
            if e.omega_rad_s.signum() != x.omega_e_rad_s.signum() {
                wrong += 1;
            }
        }
    }
    (wrong, n)
}

/// Fig. 3: 5 → −5 rad/s in 5 s. The AO and the NLO keep the right speed sign wherever
/// |ω_m| > 1 rad/s; continued to −120 rad/s, they follow while the MRAS fails.
#[test]
fn slow_reversal_keeps_the_speed_sign() {
    let m = motor_a();
    let tr = Trajectory::new(m, Profile::new(&[(0.5, 5.0), (5.5, -5.0)]));
    for kind in [Kind::Nlo, Kind::Ao] {
        let (s, est) = run(kind, &m, 1000.0, &tr, 6.5);
        let (wrong, n) = wrong_sign(&s[1000..], &est[1000..], 3.0);
        println!("{kind:?}: wrong sign at {wrong} of {n} samples with |ω_m| > 1 rad/s");
        assert_eq!(wrong, 0, "{kind:?}");
        if kind == Kind::Nlo {
            let e = errors(&est, &s);
            let worst = s[1000..]
                .iter()
                .zip(&e[1000..])
                .filter(|(x, _)| x.omega_e_rad_s.abs() > 3.0)
                .map(|(_, e)| e.0.abs())
                .fold(0.0, f64::max);
            println!(
                "NLO max angle error where |ω_m| > 1 rad/s: {:.3}°",
                deg(worst)
            );
            assert!(deg(worst) < 1.0);
        }
    }
    // The MRAS struggles through the reversal: its speed estimate spikes where ω̂_AO → 0
    // (Solsona, Valla, Muravchik (2000): "any difference between both EMF estimates when ω̂_AO tends to zero will
    // result in a very high value of the estimated speed").
    let rms = |kind| {
        let (s, est) = run(kind, &m, 1000.0, &tr, 6.5);
        let e = errors(&est, &s);
        let window = &e[(2.5 * FS) as usize..(3.5 * FS) as usize];
        (window.iter().map(|x| x.1 * x.1).sum::<f64>() / window.len() as f64).sqrt()
    };
    let (mras, nlo) = (rms(Kind::Mras), rms(Kind::Nlo));
    println!(
        "5 → −5 rad/s, 2.5–3.5 s: rms speed error MRAS {mras:.2} rad/s, NLO {nlo:.3} rad/s (electrical)"
    );
    assert!(mras > 3.0 * nlo && mras > 1.0, "MRAS {mras} NLO {nlo}");
    // To −120 rad/s (the 3 → 120 profile continued): NLO and AO keep the sign and their
    // steady errors; the MRAS's error through the zero crossing is far larger.
    let tr = Trajectory::new(
        m,
        Profile::new(&[(0.3, 3.0), (2.3, 120.0), (3.3, 120.0), (6.3, -120.0)]),
    );
    let mut peak = [0.0f64; 3];
    for (j, kind) in [Kind::Nlo, Kind::Ao, Kind::Mras].into_iter().enumerate() {
        let (s, est) = run(kind, &m, 1000.0, &tr, 7.5);
        let (wrong, n) = wrong_sign(&s[2000..], &est[2000..], 3.0);
        let e = errors(&est, &s);
        peak[j] = max_abs(&e, (3.3 * FS) as usize, |x| x.1);
        println!(
            "{kind:?} to −120: wrong sign at {wrong} of {n}; peak speed error after 3.3 s {:.1} rad/s",
            peak[j]
        );
        if kind != Kind::Mras {
            assert!(wrong < n / 500, "{kind:?}: {wrong} of {n}");
        }
        if kind == Kind::Nlo {
            assert!(
                max_abs(&e, (7.0 * FS) as usize, |x| x.1) < 0.36,
                "NLO at −120 rad/s"
            );
        }
    }
    assert!(peak[2] > 5.0 * peak[0], "MRAS {} NLO {}", peak[2], peak[0]);
}

/// Peak-to-peak of the speed error over the last `tail_s` seconds, relative.
fn ripple(kind: Kind, g: f64, tr: &Trajectory, seconds: f64, tail_s: f64) -> f64 {
    let (s, est) = run(kind, &tr.motor, g, tr, seconds);
    let e = errors(&est, &s);
    let from = e.len() - (tail_s * FS) as usize;
    let (lo, hi) = e[from..]
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
            (a.min(x.1), b.max(x.1))
        });
    (hi - lo) / 360.0
}

/// Fig. 4: 4.2 % 5th and 2.5 % 7th EMF harmonics at nominal speed: ripple in all
/// three; with g = 200 the ripple shrinks, the NLO converges more slowly, the AO's
/// steady-state error grows and the MRAS transient is violent.
#[test]
fn emf_harmonics_ripple_falls_with_the_gain() {
    let mut tr = Trajectory::new(motor_a(), Profile::constant(120.0));
    tr.h5 = 0.042;
    tr.h7 = 0.025;
    for kind in [Kind::Nlo, Kind::Ao, Kind::Mras] {
        let r1000 = ripple(kind, 1000.0, &tr, 2.0, 0.2);
        let r200 = ripple(kind, 200.0, &tr, 2.0, 0.2);
        println!(
            "{kind:?}: speed ripple {:.2} % at g = 1000, {:.2} % at g = 200",
            100.0 * r1000,
            100.0 * r200
        );
        assert!(r1000 > 0.01, "{kind:?} shows ripple at g = 1000");
        assert!(r200 < 0.6 * r1000, "{kind:?}: ripple shrinks with g = 200");
    }
    let m = motor_a();
    // NLO converges more slowly with g = 200.
    let settle = |g| {
        let (s, est) = run(Kind::Nlo, &m, g, &tr, 1.0);
        let e = errors(&est, &s);
        // The last sample whose speed error exceeds 10 % (the harmonics ripple is 5.6 %).
        e.iter().rposition(|x| x.1.abs() > 0.1 * 360.0).unwrap_or(0)
    };
    println!(
        "NLO settling to 10 %: {} samples at g = 200, {} at g = 1000",
        settle(200.0),
        settle(1000.0)
    );
    assert!(
        settle(200.0) > 3 * settle(1000.0),
        "{} vs {}",
        settle(200.0),
        settle(1000.0)
    );
    // AO steady-state angle error grows (eq. 14: −19.8° → −60.9°).
    let (a1000, _) = steady(Kind::Ao, &m, 1000.0, &tr, 1.0, 0.2);
    let (a200, _) = steady(Kind::Ao, &m, 200.0, &tr, 1.0, 0.2);
    assert!(a200 < 2.5 * a1000, "AO {}° vs {}°", deg(a200), deg(a1000));
    // MRAS transient: the largest speed error in the first 0.5 s dwarfs the NLO's.
    let peak = |kind, g| {
        let (s, est) = run(kind, &m, g, &tr, 0.5);
        max_abs(&errors(&est, &s), 200, |x| x.1)
    };
    let (mras, nlo) = (peak(Kind::Mras, 200.0), peak(Kind::Nlo, 200.0));
    println!("transient peak speed error with g = 200: MRAS {mras:.0} rad/s, NLO {nlo:.0} rad/s");
    assert!(mras > 1.5 * nlo);
}

/// text, from their ref. 10: parameter errors. Similar sensitivity to R; the AO more
/// sensitive to L; the NLO slightly sensitive to K_E (ψ), B and J, the AO insensitive to those;
/// NLO errors below the AO's in every case. Angle errors in steady state at 120 rad/s and over
/// the 3 → 120 profile.
#[test]
fn parameter_error_sensitivity() {
    let m = motor_a();
    let tr = Trajectory::new(m, Profile::new(&[(0.2, 3.0), (1.2, 120.0)]));
    type Spoil = fn(&mut MotorParams);
    let cases: [(&str, Spoil); 8] = [
        ("R +30 %", |p| p.rs_ohm *= 1.3),
        ("R −30 %", |p| p.rs_ohm *= 0.7),
        ("L +30 %", |p| {
            p.ld_h *= 1.3;
            p.lq_h *= 1.3
        }),
        ("L −30 %", |p| {
            p.ld_h *= 0.7;
            p.lq_h *= 0.7
        }),
        ("K_E +10 %", |p| p.flux_wb *= 1.1),
        ("K_E −10 %", |p| p.flux_wb *= 0.9),
        ("B ×2", |p| p.b_nm_s *= 2.0),
        ("J ×2", |p| p.j_kg_m2 *= 2.0),
    ];
    let nominal_ao = steady(Kind::Ao, &m, 1000.0, &tr, 2.0, 0.3);
    let nominal_nlo = steady(Kind::Nlo, &m, 1000.0, &tr, 2.0, 0.3);
    let mut shift = Vec::new();
    for (name, spoil) in cases {
        let mut p = m;
        spoil(&mut p);
        let ao = steady(Kind::Ao, &p, 1000.0, &tr, 2.0, 0.3);
        let nlo = steady(Kind::Nlo, &p, 1000.0, &tr, 2.0, 0.3);
        println!(
            "{name:>10}: AO {:7.3}° {:6.2} %   NLO {:7.3}° {:6.2} %",
            deg(ao.0),
            100.0 * ao.1,
            deg(nlo.0),
            100.0 * nlo.1
        );
        // Angle: the NLO's error is below the AO's in every case. Speed: also, except where the
        // AO's own −5.9 % bias at 120 rad/s happens to cancel an underestimated ψ.
        assert!(nlo.0.abs() < ao.0.abs(), "{name}");
        if name != "K_E −10 %" {
            assert!(nlo.1.abs() <= ao.1.abs() + 1e-3, "{name}");
        }
        shift.push((
            (ao.0 - nominal_ao.0).abs(),
            (nlo.0 - nominal_nlo.0).abs(),
            (ao.1 - nominal_ao.1).abs(),
            (nlo.1 - nominal_nlo.1).abs(),
        ));
    }
    // R: similar sensitivity of the speed estimates (within a factor 3).
    for s in &shift[0..2] {
        assert!(
            s.2 < 3.0 * s.3 && s.3 < 3.0 * s.2,
            "R: AO {} NLO {}",
            s.2,
            s.3
        );
    }
    // L: the error enters both through the same measured EMF (`L di/dt`), and both angle
    // estimates move by the same amount here: the paper's "AO more sensitive to L" is not
    // reproduced by the observers of docs/solsona2000.md (see docs/PERFORMANCE.md). The NLO's error
    // stays far below the AO's (asserted above).
    for s in &shift[2..4] {
        assert!((s.0 - s.1).abs() < 0.1 * s.0, "L: AO {} NLO {}", s.0, s.1);
    }
    // K_E: the NLO's speed moves with it; the AO's too (|ω̂| = |ê|/ψ) — both "sensitive".
    for s in &shift[4..6] {
        assert!(s.3 > 0.05, "K_E moves the NLO speed: {}", s.3);
    }
    // B, J: the AO does not use them at all; the NLO only slightly.
    for s in &shift[6..8] {
        assert!(s.0 == 0.0 && s.2 == 0.0, "AO insensitive to B, J");
        assert!(
            s.1 < 0.001 && s.3 < 1e-3,
            "NLO slightly sensitive: {}° {}",
            deg(s.1),
            s.3
        );
    }
}

/// The estimators restart from a known state: after `reset`, the NLO is converged at once.
#[test]
fn reset_starts_converged() {
    let m = motor_a();
    let b = base(&m, VDC, FS);
    let tr = Trajectory::new(m, Profile::constant(100.0));
    let s = tr.samples(TS, 400);
    let mut nlo = Nlo::new(NloConfig::new(&m, &b, 1000.0).unwrap());
    // The state one sample before the first update.
    let before = tr.sample(-TS);
    nlo.reset(
        pmsm_core::Angle::from_rad(before.theta_e_rad),
        b.speed_pu(before.omega_e_rad_s),
    );
    let est = run_fixed(&mut nlo, &b, &s);
    let e = errors(&est, &s);
    assert!(
        deg(max_abs(&e, 0, |x| x.0)) < 0.05,
        "{}",
        deg(max_abs(&e, 0, |x| x.0))
    );
}
