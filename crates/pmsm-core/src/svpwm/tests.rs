extern crate std;
use super::*;
use proptest::prelude::*;
use std::println;

#[test]
fn low_bus_gives_half_duties() {
    let c = SvpwmConfig::default();
    let v = AlphaBeta {
        alpha: Pu::from_num(1),
        beta: Pu::ZERO,
    };
    for vdc in [Pu::ZERO, Pu::MIN, Pu::from_bits(1), pu_from_f64(0.01)] {
        let o = c.modulate(v, vdc);
        assert_eq!(o.duties, Duties::HALF);
        assert!(o.bus_low && o.saturated);
        assert_eq!(o.v, AlphaBeta::default());
    }
    assert!(SvpwmConfig::new(1.1, 0.01).is_err());
    assert_eq!(Duties::HALF.to_compare(1000), [500; 3]);
}

/// The request `r` (fraction of the bus) at angle `th` on the bus `vdc` (per unit),
/// through the fixed-point modulator: duties and the applied vector in fractions of the bus.
fn over(c: &SvpwmConfig, r: f64, th: f64, vdc: f64) -> ([f64; 3], [f64; 2]) {
    let v = AlphaBeta {
        alpha: pu_from_f64(r * th.cos() * vdc),
        beta: pu_from_f64(r * th.sin() * vdc),
    };
    let o = c.modulate(v, pu_from_f64(vdc));
    (
        o.duties.to_f64(),
        [
            o.v.alpha.to_num::<f64>() / vdc,
            o.v.beta.to_num::<f64>() / vdc,
        ],
    )
}

/// Fixed point against the f64 reference over the whole range (linear, hexagon, toward
/// six-step, beyond) on three buses: duties within 2e−8 of the period, the applied vector's
/// length within 1e−7 of the bus and its angle within 2e−7 rad (measured 9.5e−9, 3.5e−8,
/// 5.7e−8).
#[test]
fn overmodulation_matches_reference() {
    let (mut dmax, mut amax, mut thmax) = (0.0f64, 0.0f64, 0.0f64);
    let mut ambiguous = 0;
    for (delta, vdc) in [(0.0, 1.732_050_8), (0.028, 1.2), (0.01, 2.1)] {
        let c = SvpwmConfig::overmodulating().with_min_pulse(delta).unwrap();
        // The bus as the fixed point holds it.
        let vdc = pu_from_f64(vdc).to_num::<f64>();
        for i in 0..60 {
            let r = 0.2 + 0.6 * i as f64 / 59.0;
            for k in 0..997 {
                let th = core::f64::consts::TAU * k as f64 / 997.0;
                let (d, v) = over(&c, r, th, vdc);
                // The reference sees the request as the fixed point rounded it.
                let ua = pu_from_f64(r * th.cos() * vdc).to_num::<f64>() / vdc;
                let ub = pu_from_f64(r * th.sin() * vdc).to_num::<f64>() / vdc;
                let (dr, vr) = overmodulate_f64(ua, ub, delta);
                // A leg on the rail's threshold to the rounding: either side is right.
                let (dn, _) = overmodulate_f64(ua, ub, delta + 1e-8);
                let (dw, _) = overmodulate_f64(ua, ub, (delta - 1e-8).max(0.0));
                if dn.iter().zip(dw).any(|(x, y)| (x - y).abs() > 1e-3) {
                    ambiguous += 1;
                    continue;
                }
                for j in 0..3 {
                    dmax = dmax.max((d[j] - dr[j]).abs());
                }
                amax = amax.max((v[0].hypot(v[1]) - vr[0].hypot(vr[1])).abs());
                let dth = (v[1].atan2(v[0]) - vr[1].atan2(vr[0]) + 3.0 * core::f64::consts::PI)
                    % core::f64::consts::TAU
                    - core::f64::consts::PI;
                thmax = thmax.max(dth.abs());
                assert!(d.iter().all(|x| (0.0..=1.0).contains(x)), "{d:?}");
            }
        }
    }
    println!(
        "duties {dmax:.2e}, length {amax:.2e}, angle {thmax:.2e} rad, {ambiguous} samples on a threshold"
    );
    assert!(ambiguous < 10, "{ambiguous}");
    assert!(
        dmax < 2e-8 && amax < 2e-7 && thmax < 4e-7,
        "{dmax} {amax} {thmax}"
    );
}

/// The fundamental of the applied vector over one turn of a request of constant length:
/// equal to the request in the linear range, nondecreasing with it, and the six-step
/// `2/π · V_DC` at and beyond [`OVERMOD_SIX_STEP_REQUEST`]; the reference agrees. With
/// no minimum pulse and with 2.8 % of the period (motor B's dead time at 14 kHz), where
/// the linear range ends at `(1 − 2δ)/√3`.
#[test]
fn overmodulation_fundamental_grows_to_six_step() {
    for delta in [0.0, 0.028] {
        fundamental_grows(delta);
    }
}

fn fundamental_grows(delta: f64) {
    const N: usize = 3600;
    let c = SvpwmConfig::overmodulating().with_min_pulse(delta).unwrap();
    let vdc = 1.732_050_8;
    let fundamental = |r: f64, fixed: bool| {
        let (mut x, mut y) = (0.0, 0.0);
        for k in 0..N {
            // Mid-sample angles: none falls exactly on a sector boundary.
            let th = core::f64::consts::TAU * (k as f64 + 0.5) / N as f64;
            let v = if fixed {
                over(&c, r, th, vdc).1
            } else {
                overmodulate_f64(r * th.cos(), r * th.sin(), delta).1
            };
            // Projection on the request's direction (e^{−jθ}).
            x += v[0] * th.cos() + v[1] * th.sin();
            y += v[1] * th.cos() - v[0] * th.sin();
        }
        (x / N as f64).hypot(y / N as f64)
    };
    let six_step = 2.0 / core::f64::consts::PI;
    let mut last = 0.0;
    for i in 0..=80 {
        let r = 0.4 + 0.45 * i as f64 / 80.0;
        let f = fundamental(r, true);
        let f_ref = fundamental(r, false);
        assert!((f - f_ref).abs() < 1e-6, "r {r}: {f} vs {f_ref}");
        assert!(f >= last - 1e-7, "r {r}: {f} after {last}");
        if r <= (1.0 - 2.0 * delta) / 3f64.sqrt() {
            assert!((f - r).abs() < 1e-6, "linear: {r} → {f}");
        } else {
            assert!(f >= r.min(0.577) && f <= six_step + 1e-4, "{r} → {f}");
        }
        if r >= OVERMOD_SIX_STEP_REQUEST {
            assert!((f - six_step).abs() < 2e-4, "six-step: {f} vs {six_step}");
        }
        last = f;
    }
    // The hexagon with its angle kept (λ = 0 at the vertex length 2/3) gives less: the
    // second region is what reaches six-step.
    let hexagon = fundamental(2.0 / 3.0, true);
    println!("δ {delta}: fundamental at |u| = 2/3: {hexagon:.4}, six-step {six_step:.4}");
    assert!(hexagon < 0.97 * six_step && hexagon > 0.6, "{hexagon}");
}

/// `c` on the input bits: duties in [0, 1] and the commanded vector within the
/// modulator's reach (2 LSB and 1e−8 relative): the hexagon's span `V_DC` for the linear
/// modulator, the vertex `c.v_max` overmodulating.
fn check_modulated(
    c: &SvpwmConfig,
    al: i32,
    be: i32,
    vdc: i32,
) -> Result<(), proptest::test_runner::TestCaseError> {
    let v = AlphaBeta {
        alpha: Pu::from_bits(al),
        beta: Pu::from_bits(be),
    };
    let vdc = Pu::from_bits(vdc);
    let o = c.modulate(v, vdc);
    for d in [o.duties.a, o.duties.b, o.duties.c] {
        prop_assert!(d >= Unit::ZERO && d <= Unit::from_num(1));
    }
    let (x, y) = (o.v.alpha.to_bits() as f64, o.v.beta.to_bits() as f64);
    if c.overmodulation() {
        let vmax = c.v_max(vdc).to_bits() as f64;
        prop_assert!((x * x + y * y).sqrt() <= vmax * (1.0 + 1e-8) + 2.0);
    } else {
        let s3 = 3f64.sqrt();
        let ph = [x, -0.5 * x + 0.5 * s3 * y, -0.5 * x - 0.5 * s3 * y];
        let span = ph[0].max(ph[1]).max(ph[2]) - ph[0].min(ph[1]).min(ph[2]);
        let vdc = (vdc.to_bits() as f64).max(0.0);
        prop_assert!(span <= vdc * (1.0 + 1e-8) + 3.0, "{} {}", span, vdc);
    }
    if o.saturated && !o.bus_low && v.alpha.to_bits() != 0 {
        // The angle kept: the cross product of request and command is within rounding.
        let (ra, rb) = (v.alpha.to_bits() as f64, v.beta.to_bits() as f64);
        let cross = (ra * y - rb * x) / ra.hypot(rb);
        prop_assert!(cross.abs() <= 3.0, "{}", cross);
    }
    Ok(())
}

/// The shrink onto the hexagon for every span up to ⅛ beyond it (a stride through all of
/// them, both margins): `(1 − c) s ≤ S` always, and short of `S` by at most 1.2e−5 of it
/// (`e⁶` and the roundings; measured 9.6e−6).
#[test]
fn shrink_is_inside_and_near() {
    for m in [1.0, 0.9, 0.5] {
        let cfg = SvpwmConfig::new(m, 0.01).unwrap();
        let big = u64::from(cfg.span_max);
        let mut worst = 0.0f64;
        let mut n = 0;
        let mut s = cfg.span_max + 1;
        while let Some(c) = cfg.shrink(s) {
            let shrunk = ((1u64 << 19) - u64::from(c)) * u64::from(s);
            assert!(shrunk <= big << 19, "m {m}: span {s}, c {c}");
            worst = worst.max(1.0 - shrunk as f64 / (big << 19) as f64);
            n += 1;
            s += 997;
        }
        println!("m {m}: {n} spans, shortfall at most {worst:.2e}");
        assert!(n > 16_000 && worst < 1.2e-5, "{n} {worst}");
        // The series ends at an eighth beyond; the division takes over. At its last
        // excess the products still fit (a debug build would panic otherwise).
        let end = u64::from(s) * 8 / big;
        assert!((8..=9).contains(&end), "{end}");
        let last = cfg.span_max + cfg.excess_max;
        let c = cfg.shrink(last).unwrap();
        assert!(((1u64 << 19) - u64::from(c)) * u64::from(last) <= big << 19);
        assert!(cfg.shrink(last + 1).is_none());
    }
}

proptest! {
    /// Overmodulating, any input: duties in [0, 1], the vector within the vertex `2 v_dc/3`.
    #[test]
    fn overmodulated_duties_always_valid(al in any::<i32>(), be in any::<i32>(), vdc in any::<i32>()) {
        check_modulated(&SvpwmConfig::overmodulating(), al, be, vdc)?;
    }

    /// Any input: duties in [0, 1] and the commanded vector inside the hexagon, its angle kept.
    #[test]
    fn duties_always_valid(al in any::<i32>(), be in any::<i32>(), vdc in any::<i32>()) {
        check_modulated(&SvpwmConfig::default(), al, be, vdc)?;
    }
}

/// The bus terms are kept while the reading stays within 2⁻⁹ of theirs, and the modulator on
/// them is the modulator on their reading, bit for bit; a reading beyond takes new terms.
#[test]
fn the_bus_terms_are_kept_within_their_tolerance() {
    let c = SvpwmConfig::default();
    let v = AlphaBeta {
        alpha: pu_from_f64(0.41),
        beta: pu_from_f64(-0.23),
    };
    let vdc = pu_from_f64(1.7);
    let tol = vdc.to_bits() >> BUS_TOLERANCE_SHIFT;
    let mut cache = BusReciprocal::default();
    let first = *cache.get(vdc);
    assert_eq!(first.reading(), vdc);
    let on = |bus: &BusReciprocal| c.modulate_on(v, bus.reading(), bus.recip());
    for d in [-tol, -tol / 2, -1, 0, 1, tol / 3, tol] {
        let bus = *cache.get(Pu::from_bits(vdc.to_bits() + d));
        assert_eq!(bus, first, "a reading {d} LSB off");
        assert_eq!(on(&bus), c.modulate(v, vdc));
    }
    // 0.2 % is 0.0033 pu of this bus: a reading beyond takes its own terms.
    for d in [tol + 1, -tol - 1] {
        let reading = Pu::from_bits(vdc.to_bits() + d);
        let mut cache = first;
        let bus = *cache.get(reading);
        assert_eq!(bus.reading(), reading);
        assert_eq!(on(&bus), c.modulate(v, reading));
    }
    // The empty cache keeps nothing but the reading 0; a low bus is the low bus's output.
    let mut empty = BusReciprocal::default();
    assert_eq!(empty.get(Pu::ZERO).reading(), Pu::ZERO);
    assert!(on(empty.get(Pu::from_bits(1))).bus_low);
}
