//! SVPWM (docs/khlaief2012.md §5) against its f64 reference: the average voltages rebuilt from the
//! fixed-point duties, the hexagon's limit, and the 15.5 % more voltage than sine PWM.

use pmsm_core::AlphaBeta;
use pmsm_core::pu_from_f64;
use pmsm_core::to_f64;
use pmsm_core::{Duties, SvpwmConfig};
use pmsm_tests::drive_ref::{SQRT3, duties_to_alpha_beta, hexagon_radius, svpwm_ref};
use pmsm_tests::signals::SplitMix;

const LSB: f64 = 1.0 / (1u64 << 24) as f64;

fn ab(v: [f64; 2]) -> AlphaBeta {
    AlphaBeta {
        alpha: pu_from_f64(v[0]),
        beta: pu_from_f64(v[1]),
    }
}

/// Random vectors up to 1.5× the circle, random angles, buses from 0.2 to 2× nominal: the
/// voltage rebuilt from the duties is within 1 LSB of the f64 reference in the linear range
/// (the whole hexagon; measured 0.08 LSB); beyond it, never longer than the reference's (by
/// more than 2 LSB) and short of it by at most 1.2e−5 of its length and 4 LSB (measured
/// 9e−6); the saturation flags agree except within 1e−6 of the hexagon; the duties of the
/// fixed and f64 modulators differ by less than 1e−5 of the period (measured 4.6e−6).
#[test]
fn rebuilt_voltage_matches_f64() {
    let cfg = SvpwmConfig::default();
    let mut rng = SplitMix(7);
    let (mut worst_lin, mut worst_sat, mut worst_duty) = (0.0f64, 0.0f64, 0.0f64);
    let (mut n_lin, mut n_sat) = (0, 0);
    for _ in 0..200_000 {
        let vdc = pu_from_f64(SQRT3 * rng.uniform(0.2, 2.0));
        let vdc_f = to_f64(vdc);
        let mag = rng.uniform(0.0, 1.5) * vdc_f / SQRT3;
        let phi = rng.uniform(-std::f64::consts::PI, std::f64::consts::PI);
        let v = ab([mag * phi.cos(), mag * phi.sin()]);
        let vf = [to_f64(v.alpha), to_f64(v.beta)];
        let out = cfg.modulate(v, vdc);
        let (d_ref, v_ref, sat_ref) = svpwm_ref(vf, vdc_f, 1.0);
        let rebuilt = duties_to_alpha_beta(out.duties.to_f64(), vdc_f);
        let err = (rebuilt[0] - v_ref[0]).hypot(rebuilt[1] - v_ref[1]) / LSB;
        // Flags may differ only within a few LSB of the hexagon.
        if out.saturated != sat_ref {
            let r = hexagon_radius(vf[1].atan2(vf[0]), vdc_f, 1.0);
            assert!((vf[0].hypot(vf[1]) / r - 1.0).abs() < 1e-6);
            continue;
        }
        if sat_ref {
            let len = v_ref[0].hypot(v_ref[1]);
            assert!(rebuilt[0].hypot(rebuilt[1]) <= len + 2.0 * LSB);
            worst_sat = worst_sat.max((err - 4.0).max(0.0) * LSB / len);
            n_sat += 1;
        } else {
            worst_lin = worst_lin.max(err);
            n_lin += 1;
        }
        let dd = out.duties.to_f64();
        for k in 0..3 {
            worst_duty = worst_duty.max((dd[k] - d_ref[k]).abs());
        }
        // The returned vector is the one the duties make.
        let ret = [to_f64(out.v.alpha), to_f64(out.v.beta)];
        assert!((ret[0] - rebuilt[0]).hypot(ret[1] - rebuilt[1]) / LSB <= 4.0);
    }
    println!(
        "linear ({n_lin}): {worst_lin:.2} LSB; hexagon ({n_sat}): {worst_sat:.2e} of the length \
         beyond 4 LSB; duty {worst_duty:.2e}"
    );
    assert!(n_lin > 50_000 && n_sat > 50_000);
    assert!(worst_lin <= 1.0, "linear {worst_lin} LSB");
    assert!(worst_sat <= 1.2e-5, "hexagon {worst_sat}");
    assert!(worst_duty < 1e-5, "duty {worst_duty}");
}

/// The hexagon's limit keeps the angle: for requests 1.0001× to 10× the hexagon in their
/// direction, the commanded vector is never beyond it (2 LSB), short of it by at most 1.2e−5
/// of its length (measured 8.4e−6), and at the request's angle within 1e−7 rad (measured
/// 8.2e−8; 1 LSB of a 1 pu vector is 6e−8 rad).
#[test]
fn hexagon_limit_keeps_the_angle() {
    let cfg = SvpwmConfig::default();
    let vdc_f = SQRT3;
    let vdc = pu_from_f64(vdc_f);
    let mut rng = SplitMix(11);
    let (mut worst_len, mut worst_ang) = (0.0f64, 0.0f64);
    for i in 0..40_000 {
        // Half just beyond (the series), half far beyond (the division).
        let k = if i % 2 == 0 {
            rng.uniform(1.0001, 1.12)
        } else {
            rng.uniform(1.13, 10.0)
        };
        let phi = rng.uniform(-std::f64::consts::PI, std::f64::consts::PI);
        let r = hexagon_radius(phi, vdc_f, 1.0);
        let v = ab([k * r * phi.cos(), k * r * phi.sin()]);
        let out = cfg.modulate(v, vdc);
        assert!(out.saturated && !out.bus_low);
        let (x, y) = (to_f64(out.v.alpha), to_f64(out.v.beta));
        let want = to_f64(v.beta).atan2(to_f64(v.alpha));
        let r = hexagon_radius(want, vdc_f, 1.0);
        assert!(x.hypot(y) <= r + 2.0 * LSB, "{} > {r}", x.hypot(y));
        worst_len = worst_len.max(1.0 - x.hypot(y) / r);
        let d = (y.atan2(x) - want + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
            - std::f64::consts::PI;
        worst_ang = worst_ang.max(d.abs());
    }
    println!("hexagon: length short by {worst_len:.2e}, angle {worst_ang:.2e} rad");
    assert!(
        worst_len <= 1.2e-5 && worst_ang <= 1e-7,
        "{worst_len} {worst_ang}"
    );
}

/// SVPWM reaches `V_DC/√3` in every direction without distortion, sine PWM only `V_DC/2`:
/// 2/√3 − 1 = 15.47 % more; toward the vertices the hexagon reaches `2 V_DC/3`. At every
/// whole degree, 0.999999 of the hexagon is linear (not saturated, duties in [0, 1], the legs
/// spanning 0.999999 of the period) and 1.000001 of it is limited; the same amplitude by sine
/// PWM would need a duty of ½ + (1/√3)·... > 1.
#[test]
fn linear_range_is_15_5_percent_above_sine_pwm() {
    let cfg = SvpwmConfig::default();
    let vdc_f = SQRT3; // nominal bus, per unit of V_b
    let vdc = pu_from_f64(vdc_f);
    let (mut widest, mut narrowest) = (0.0f64, 1.0f64);
    let (mut shortest, mut longest) = (f64::MAX, 0.0f64);
    for deg in 0..360 {
        let phi = (deg as f64).to_radians();
        let r = hexagon_radius(phi, vdc_f, 1.0);
        shortest = shortest.min(r);
        longest = longest.max(r);
        let k = 0.999_999 * r;
        let inside = cfg.modulate(ab([k * phi.cos(), k * phi.sin()]), vdc);
        assert!(!inside.saturated, "{deg}°");
        let d = inside.duties.to_f64();
        assert!(d.iter().all(|&x| (0.0..=1.0).contains(&x)));
        let span =
            d.iter().cloned().fold(f64::MIN, f64::max) - d.iter().cloned().fold(f64::MAX, f64::min);
        widest = widest.max(span);
        narrowest = narrowest.min(span);
        let k = 1.000_001 * r;
        let outside = cfg.modulate(ab([k * phi.cos(), k * phi.sin()]), vdc);
        assert!(outside.saturated, "{deg}°");
    }
    // Largest linear amplitude in every direction over the sine-PWM limit V_DC/2.
    let gain = (shortest / (vdc_f / 2.0) - 1.0) * 100.0;
    // Sine PWM at the SVPWM limit: d_a = ½ + v_a/V_DC peaks at ½ + 1/√3, above 1.
    let sine_peak = 0.5 + 1.0 / vdc_f;
    println!(
        "spans {narrowest:.7}..{widest:.7}, gain over sine PWM {gain:.2} %, vertex {longest:.4} \
         pu, sine duty peak {sine_peak:.4}"
    );
    assert!((widest - 0.999_999).abs() < 1e-6 && (narrowest - 0.999_999).abs() < 1e-6);
    assert!((shortest - 1.0).abs() < 1e-9 && (longest - 2.0 / SQRT3).abs() < 1e-9);
    assert!((gain - 15.47).abs() < 0.01);
    assert!(sine_peak > 1.07);
}

/// No bus, a tiny bus or a negative reading: duties ½, zero vector, both flags; compare
/// values round to the timer period.
#[test]
fn low_or_absent_bus_is_safe() {
    let cfg = SvpwmConfig::default();
    let v = ab([0.5, -0.3]);
    for vdc in [0.0, -1.0, 1e-6, 0.017] {
        let out = cfg.modulate(v, pu_from_f64(vdc));
        assert_eq!(out.duties, Duties::HALF);
        assert!(out.bus_low && out.saturated);
    }
    // 2 % of nominal is usable: the vector is limited to the small hexagon, not dropped.
    let vdc = pu_from_f64(0.02 * SQRT3);
    let out = cfg.modulate(v, vdc);
    assert!(!out.bus_low && out.saturated);
    let r = hexagon_radius((-0.3f64).atan2(0.5), to_f64(vdc), 1.0);
    let len = to_f64(out.v.alpha).hypot(to_f64(out.v.beta));
    assert!(
        len <= r + 2.0 * LSB && len > r * (1.0 - 1.2e-5) - 4.0 * LSB,
        "{len} {r}"
    );
    let d = cfg.modulate(ab([0.0, 0.0]), pu_from_f64(SQRT3)).duties;
    assert_eq!(d.to_compare(4250), [2125; 3]);
}
