//! The low-speed d-axis current (docs/drive.md, "low-speed current").
//!
//! Every estimator of the crate reads the rotor through its EMF, directly (the back-EMF
//! observers) or through the currents it drives (the current-model MRAS, whose sensitivity to
//! the position error falls as `ω²/(ω² + ω_c²)`). Near standstill the estimate therefore
//! runs on its model alone, and a load that changes while the rotor passes through zero (a
//! reversal under load, a load step at low speed) turns the estimated frame away from the
//! rotor: the speed loop then pushes its current into a frame that is turning away, and the
//! lock is lost.
//!
//! A positive current along the estimated d axis makes the rotor follow the estimated frame
//! instead: with the frame `δ` behind the magnet, the magnet's torque on that current is
//! `1.5 p ψ i_d sin δ`, a spring that pulls the rotor back towards the frame (an alignment,
//! or the current vector of an open-loop "I–f" start, held while the closed loop runs). So
//! the drive adds, in the closed loop,
//!
//! ```text
//! i_d,LS = min(I_LS (1 − |ω̂|/ω_LS), I_max − x²/I_max),   x = max(|i_q*|, |i_q*|_f),   not below 0
//! ```
//!
//! - `I_LS`: the rated current (the per-unit base), at most `ψ/(2 (L_q − L_d))` on a salient
//!   motor, where the reluctance torque `1.5 p (L_d − L_q) i_d i_q` would take more than half
//!   of the spring's stiffness `1.5 p (ψ − (L_q − L_d) i_d) i_d` (it turns `q`, not `d`,
//!   towards the current) and of the torque per ampere of `i_q`.
//! - `ω_LS`: twice the back-EMF estimators' handover speed, a fifth of the rated speed, where
//!   every estimator sees the rotor again; the current fades linearly to it.
//! - `I_max − x²/I_max`: the current vector stays within the speed loop's circle
//!   (`(I − x²/I)² + x² = I² − x² + x⁴/I² ≤ I²` for `|x| ≤ I`), so a loaded motor crossing
//!   zero keeps all its torque current (without a room, strongly salient motors of the random
//!   family stalled under load at low speed). It is the circle's room `√(I² − x²)` to within
//!   `x⁴/(8I³)` at small `x` and half of it at `x = 0.87 I`, without its root: the exact room
//!   cost 150 instructions on the Cortex-M4, beyond the step's budget; the linear room
//!   `I − |x|`, cheaper still, held 7 runs fewer of the family. `x` is `|i_q*|` as it rises
//!   and its 16 ms filter `|i_q*|_f` (the light-load current's, `super::light_load`) as it
//!   falls: from `|i_q*|` alone, whose room falls steeply near the limit, the d current moved
//!   with every ripple of the speed loop, and on a salient motor, where it takes torque, it
//!   closed a second loop (motor B at 300 r/min and rated load swung between 239 and
//!   291 r/min); from the filter alone, an acceleration from rest carried the vector beyond
//!   the circle for the filter's time (1.3 `I_max` on motor B).
//!
//! It costs copper: at standstill the rated current's loss. On the random family (`cargo xtask
//! family`, seeds 1–8) it lifts the current-model MRAS from 248 to 278 runs of 320 with the IP
//! speed loop and from 256 to 290 with the drive's half-weighted reference; measured figures in
//! docs/drive.md.
//!
//! # Handover
//!
//! The back-EMF estimators' open-loop start runs the whole current along its imposed frame,
//! nearly the rotor's d axis at no load. Stepping that current to the closed loop's `i_d* = 0`
//! at the handover left the dead-time compensation, which takes its signs from the current
//! reference, without the distortion of a current that still flowed for the current loop's
//! response: the estimator's voltage was then wrong by up to `(4/3) V_dead` for a few
//! milliseconds, as much as the EMF at the handover speed, and the NLO turned to the mirror
//! angle (the start-up faults of the NLO in `cargo xtask family`, three of seed 2's four
//! lost runs). So the handover after the start sets the faded level to the open loop's
//! current and the drive lets it decay ([`LowSpeedConfig::decayed`]): by a sixteenth of itself
//! every eighth sample, a time constant of 128 samples (6.4 ms at 20 kHz), within the same
//! room. Only with `I_LS = 0`, the back-EMF estimators' default (with the low-speed current
//! on, its fade from `I_LS` is the law; decaying it too slowed the current-model MRAS's fade
//! in a fast start and motor B's averaged-inverter run at no load ended in its limit cycle,
//! estimated speed σ 13.1 r/min against 8.8). Not after an open-loop reversal: under load its
//! current is mostly torque, and the fade there changed which marginal reversals of the family
//! held, not how many.
//!
//! Formats: currents [`Pu`] (Q8.24) of `I_b`; speeds in units of 2⁻¹² pu, as
//! [`super::light_load`].

use crate::error::ConfigError;
use crate::num::{Pu, pu_from_f64};
use crate::params::{MotorParams, in_range, positive};
use crate::units::PerUnit;

/// [`LowSpeedConfig::default_fade_rad_s`]: the fade's end as a fraction of the rated
/// electrical speed.
pub const LOW_SPEED_FADE_PER_RATED: f64 = 0.2;

/// The handover current's decay per eight-sample update, as a shift (module docs, "handover").
const HANDOVER_DECAY_SHIFT: u32 = 4;

/// The low-speed current's configuration.
#[derive(Clone, Copy, Debug, PartialEq, crate::image::Words)]
pub struct LowSpeedConfig {
    /// `I_LS`, [`Pu`] bits (0: off).
    current: i32,
    /// `ω_LS`, [`Pu`] bits, at least 2¹² (2⁻¹² pu).
    fade: i32,
    /// `I_LS/ω_LS` in [`Pu`] bits of current per 2⁻¹² pu of speed: `k (min(|ω|, ω_LS) ≫ 12)`
    /// is at most `I_LS` (< 2²⁸ bits), a 32-bit product.
    per_speed: i32,
    /// The speed loop's current limit `I_max`, [`Pu`] bits.
    limit: i32,
    /// `s`: the least shift that takes `I_max/2ˢ` below 2¹⁵ (zero for `I_max` < 2¹⁵ bits), the
    /// scale of the room's 32-bit products.
    shift: u32,
    /// `2³⁰·2ˢ/I_max` rounded up (at most 2¹⁶ for `s` > 0, 2²⁰ with `I_max` ≥ 2¹⁰ bits):
    /// `x/I_max` in Q14 from `x/2ˢ`, erring up (the room then errs inside the circle).
    inv_limit: u32,
}

impl LowSpeedConfig {
    /// Off, and without a limit: no handover current either (the drive's configuration keeps
    /// the limit with `I_LS = 0`, [`LowSpeedConfig::new`]).
    pub const OFF: Self = Self {
        current: 0,
        fade: 1 << 12,
        per_speed: 0,
        limit: 0,
        shift: 0,
        inv_limit: 0,
    };

    /// `I_LS = current_a` (A peak; 0 turns it off), faded out at the electrical speed
    /// `fade_rad_s`, within the speed loop's current limit `limit` (per unit, as the speed
    /// loop holds it: taken within [2⁻¹⁴, 64] pu), in the bases `base`.
    ///
    /// Errors: [`ConfigError::Param`] for `low_speed_id_a` outside `[0, 10 I_b]` or a
    /// `low_speed_fade_rad_s` that is not positive. (Beyond the limit the current is the room
    /// the limit leaves, as for any `i_q*`.)
    pub fn new(
        current_a: f64,
        fade_rad_s: f64,
        limit: Pu,
        base: &PerUnit,
    ) -> Result<Self, ConfigError> {
        let i = in_range("low_speed_id_a", current_a, 0.0, 10.0 * base.current_a)?;
        let fade = positive("low_speed_fade_rad_s", fade_rad_s)?;
        // Off (`I_LS = 0`) keeps the limit: the handover's current fades within it.
        let current = pu_from_f64(i / base.current_a).to_bits();
        // ω_LS in units of 2⁻¹² pu, at least one; I_LS/ω_LS rounded down (the current then
        // reaches zero a fraction of a unit beyond ω_LS, within `max(0)`).
        let fade_units = ((fade / base.omega_e_rad_s * 4096.0) as i32).max(1);
        // I_max in [2⁻¹⁴, 64] pu (2¹⁰ to 2³⁰ bits; the room's products stay within 32 bits
        // up to there): I_max/2ˢ below 2¹⁵, at least 2¹⁴ when s > 0.
        let limit = limit.to_bits().clamp(1 << 10, 1 << 30);
        let shift = (32 - limit.leading_zeros()).saturating_sub(15);
        Ok(Self {
            current,
            fade: fade_units.saturating_mul(1 << 12),
            per_speed: current / fade_units,
            limit,
            shift,
            inv_limit: libm::ceil(
                f64::from(1u32 << 30) * f64::from(1u32 << shift) / f64::from(limit),
            ) as u32,
        })
    }

    /// `I_LS`, per unit (zero: off).
    pub fn current(&self) -> Pu {
        Pu::from_bits(self.current)
    }

    /// The default `I_LS`, A: the current limit `limit_a`, at most `ψ/(2 (L_q − L_d))` on a
    /// salient motor (module docs).
    pub fn default_current_a(motor: &MotorParams, limit_a: f64) -> f64 {
        let saliency = motor.lq_h - motor.ld_h;
        if saliency > 0.0 {
            limit_a.min(0.5 * motor.flux_wb / saliency)
        } else {
            limit_a
        }
    }

    /// The default `ω_LS`, electrical rad/s: [`LOW_SPEED_FADE_PER_RATED`] of `rated_e_rad_s`.
    pub fn default_fade_rad_s(rated_e_rad_s: f64) -> f64 {
        LOW_SPEED_FADE_PER_RATED * rated_e_rad_s
    }

    /// The d-axis reference `i_d,LS ≥ 0` for the q reference `iq` and the speed `omega`
    /// (module docs): [`LowSpeedConfig::within_limit`] of [`LowSpeedConfig::faded`].
    #[inline(always)]
    pub fn id_ref(&self, iq: Pu, omega: Pu) -> Pu {
        self.within_limit(self.faded(omega), iq, Pu::ZERO)
    }

    /// [`LowSpeedConfig::faded`]; with the low-speed current off, the level `previous` decayed
    /// by a sixteenth and one LSB, not below 0: a d current set at the back-EMF estimators'
    /// handover (the open loop's, [`crate::Drive`]) fades out over about 16 of the drive's
    /// eight-sample updates instead of stepping to zero (module docs, "handover"). (With the
    /// low-speed current on, its fade is the law, as it always was.)
    #[inline(always)]
    pub fn decayed(&self, omega: Pu, previous: Pu) -> Pu {
        if self.current != 0 {
            return self.faded(omega);
        }
        let p = previous.to_bits();
        Pu::from_bits((p - (p >> HANDOVER_DECAY_SHIFT) - 1).max(0))
    }

    /// `I_LS (1 − |ω|/ω_LS)`, not below 0 (the drive takes it on one slot, the limit on
    /// another: each fits beside that slot's other work). A shift, a comparison and a 32-bit
    /// product.
    #[inline(always)]
    pub fn faded(&self, omega: Pu) -> Pu {
        // min(|ω|, ω_LS) in units of 2⁻¹² pu times I_LS/ω_LS: at most I_LS (< 2²⁸ bits).
        let w = (omega.to_bits().unsigned_abs().min(self.fade as u32) >> 12) as i32;
        Pu::from_bits((self.current - w * self.per_speed).max(0))
    }

    /// `faded` within the room `I_max − x²/I_max` that `x = max(|iq|, level)` leaves: the q
    /// reference `iq` as it rises, its filtered magnitude `level` (`≥ 0`) as it falls. Two
    /// 32-bit products at 2⁻¹⁴ of `I_max`, each rounded up so that the room errs inside the
    /// circle, by at most `4·2⁻¹⁴ I_max` and a few LSB (in 64 bits they made the slot that
    /// takes them the Cortex-M0's dearest, by about 120 instructions).
    #[inline(always)]
    pub fn within_limit(&self, faded: Pu, iq: Pu, level: Pu) -> Pu {
        let x = iq
            .to_bits()
            .unsigned_abs()
            .max(level.to_bits() as u32)
            .min(self.limit as u32);
        // x ≤ I_max < 2¹⁵·2ˢ: x/2ˢ rounded up ≤ 2¹⁵, times 2³⁰·2ˢ/I_max at most 2³¹ (with
        // s = 0, I_max (2³⁰/I_max + 1) ≤ 2³⁰ + 2¹⁵), and +2¹⁶ − 1 to round up: r = x/I_max in
        // Q14, at most one. Then x²/(I_max 2ˢ) ≤ 2¹⁵ + 1 from a product ≤ 2²⁹, and back in
        // bits at most I_max + 2ˢ⁺¹ < 2³¹.
        let s = self.shift;
        let xn = (x + (1 << s) - 1) >> s;
        let r = ((xn * self.inv_limit + 0xFFFF) >> 16).min(1 << 14);
        let sq = (xn * r + 0x3FFF) >> 14;
        let room = self.limit - (sq << s) as i32;
        Pu::from_bits(faded.to_bits().min(room).max(0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixtures::{inverter_b, motor_b};
    use crate::num::PU_FRAC;

    /// The room `I_max − x²/I_max` in 32-bit products against f64, over limits from the
    /// least taken (2⁻¹⁴ pu) to 64 pu and `x` across `[0, I_max]`: never outside the f64
    /// room (so never outside the circle), and within `4·2⁻¹⁴ I_max` + 3 LSB of it (the
    /// LSB: the roundings up of `x/2ˢ` and of the square, and `x` itself to its bits).
    #[test]
    fn the_room_errs_inside_and_within_its_bound() {
        let base = PerUnit::new(&motor_b(), &inverter_b(), 14e3).unwrap();
        let lsb = 1.0 / f64::from(1u32 << PU_FRAC);
        for lim_pu in [1.0 / 16384.0, 0.0123, 0.37, 1.0, 5.3, 63.9, 64.0] {
            let c = LowSpeedConfig::new(1.0, 100.0, pu_from_f64(lim_pu), &base).unwrap();
            let lim = f64::from(c.limit) * lsb;
            let mut worst: f64 = 0.0;
            for k in 0..=1000 {
                let x = lim * f64::from(k) / 1000.0;
                let want = lim - x * x / lim;
                let big = Pu::from_bits(i32::MAX);
                let got = c
                    .within_limit(big, pu_from_f64(x), Pu::ZERO)
                    .to_num::<f64>();
                assert!(got <= want + lsb, "{lim_pu} pu, x {x}: {got} > {want}");
                worst = worst.max(want - got);
                // The filtered level counts as the reference does.
                let by_level = c.within_limit(big, Pu::ZERO, pu_from_f64(x));
                assert_eq!(by_level, c.within_limit(big, pu_from_f64(-x), Pu::ZERO));
            }
            assert!(
                worst <= 4.0 * lim / 16384.0 + 3.0 * lsb,
                "{lim_pu} pu: {worst}"
            );
        }
    }

    /// The fixed-point law against the f64 one over speeds through the fade and q
    /// references up to the limit, and within the current circle: within one step of the speed's 2⁻¹² pu (`I_LS` over the
    /// fade's speed in those steps: 1.4e−3 pu on motor B) and a few LSB.
    #[test]
    fn low_speed_current_against_reference() {
        let m = motor_b();
        let base = PerUnit::new(&m, &inverter_b(), 14e3).unwrap();
        let limit = base.current_a;
        let i_ls = LowSpeedConfig::default_current_a(&m, limit);
        // Motor B: ψ/(2 (L_q − L_d)) = 10.1 A, beyond the rated 3.58 A.
        assert!((i_ls - limit).abs() < 1e-12, "{i_ls}");
        let rated_e = 3000.0 * core::f64::consts::TAU / 60.0 * 3.0;
        let fade = LowSpeedConfig::default_fade_rad_s(rated_e);
        let lim = pu_from_f64(limit / base.current_a);
        let c = LowSpeedConfig::new(i_ls, fade, lim, &base).unwrap();
        let (i_pu, fade_pu, lim_pu) = (
            i_ls / base.current_a,
            fade / base.omega_e_rad_s,
            limit / base.current_a,
        );
        let mut worst: f64 = 0.0;
        for k in 0..=40 {
            let omega = (k as f64 / 20.0 - 1.0) * 1.5 * fade_pu;
            for j in 0..=20 {
                let iq = (j as f64 / 10.0 - 1.0) * lim_pu;
                let want = (i_pu * (1.0 - omega.abs() / fade_pu))
                    .min(lim_pu - iq * iq / lim_pu)
                    .max(0.0);
                let got = c
                    .id_ref(pu_from_f64(iq), pu_from_f64(omega))
                    .to_num::<f64>();
                worst = worst.max((got - want).abs());
                // Within the current circle.
                assert!(got * got + iq * iq <= lim_pu * lim_pu * (1.0 + 1e-6));
            }
        }
        let step = i_pu / (fade_pu * 4096.0);
        assert!(worst < step + 1e-6, "{worst} pu, step {step}");
        assert!(step < 2e-3, "{step}");
        // Off: nothing; out of range: named.
        assert_eq!(LowSpeedConfig::OFF.id_ref(Pu::ZERO, Pu::ZERO), Pu::ZERO);
        assert!(LowSpeedConfig::new(-1.0, fade, lim, &base).is_err());
        assert!(LowSpeedConfig::new(20.0 * limit, fade, lim, &base).is_err());
        assert!(LowSpeedConfig::new(1.0, 0.0, lim, &base).is_err());
    }

    /// The handover's fade against its f64 recurrence `x ← x (1 − 2⁻ᵏ) − LSB`: within `2ᵏ`
    /// LSB at every update (the shift's floor adds at most one LSB per update, and the decay
    /// shrinks what came before by `1 − 2⁻ᵏ`), a time constant of about `2ᵏ` updates and zero
    /// within a finite number of them with the low-speed current off; with it on, its fade.
    #[test]
    fn the_handover_current_decays_with_the_low_speed_current_off() {
        let m = motor_b();
        let base = PerUnit::new(&m, &inverter_b(), 14e3).unwrap();
        let lim = pu_from_f64(1.0);
        let rated_e = 3000.0 * core::f64::consts::TAU / 60.0 * 3.0;
        let fade = LowSpeedConfig::default_fade_rad_s(rated_e);
        let off = LowSpeedConfig::new(0.0, fade, lim, &base).unwrap();
        let lsb = 1.0 / f64::from(1u32 << PU_FRAC);
        let k = 1.0 / f64::from(1u32 << HANDOVER_DECAY_SHIFT);
        let (mut x, mut want) = (pu_from_f64(1.0), 1.0);
        let mut updates = 0;
        while x > Pu::ZERO {
            x = off.decayed(Pu::ZERO, x);
            want = (want * (1.0 - k) - lsb).max(0.0);
            updates += 1;
            let err = (x.to_num::<f64>() - want).abs();
            assert!(err <= (1.0 / k) * lsb, "{updates}: {x:?} {want}");
            if updates == 1 << HANDOVER_DECAY_SHIFT {
                // `2ᵏ` updates: `(1 − 2⁻ᵏ)^(2ᵏ)` of the start (0.356 at k = 4), e⁻¹ to 3 %:
                // a time constant of `2ᵏ` updates.
                let e = x.to_num::<f64>();
                assert!((e - (1.0 - k).powf(1.0 / k)).abs() < 1e-4, "{e}");
                assert!((e - (-1.0f64).exp()).abs() < 0.015, "{e}");
            }
            assert!(updates < 1000, "no end");
        }
        // Within the room the limit leaves: off, the limit is kept.
        assert_eq!(off.within_limit(pu_from_f64(2.0), Pu::ZERO, Pu::ZERO), lim);
        // On: the fade is the law, whatever came before.
        let on = LowSpeedConfig::new(0.5 * base.current_a, fade, lim, &base).unwrap();
        let omega = pu_from_f64(0.5 * fade / base.omega_e_rad_s);
        let x = on.decayed(omega, pu_from_f64(1.0));
        assert_eq!(x, on.faded(omega));
        assert!((x.to_num::<f64>() - 0.25).abs() < 2e-3, "{x:?}");
    }

    /// A strongly salient motor: the current stops where the reluctance torque would take
    /// half the magnet's.
    #[test]
    fn salient_motors_get_less() {
        let mut m = motor_b();
        m.lq_h = 4.0 * m.ld_h;
        let cap = 0.5 * m.flux_wb / (m.lq_h - m.ld_h);
        assert!((LowSpeedConfig::default_current_a(&m, 100.0) - cap).abs() < 1e-12);
        assert!((LowSpeedConfig::default_current_a(&m, 0.5 * cap) - 0.5 * cap).abs() < 1e-12);
    }
}
