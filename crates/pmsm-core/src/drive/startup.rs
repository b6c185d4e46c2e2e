//! Start-up of the drive without the estimator: the alignment, and the open-loop current-vector
//! ("I–f") start that the back-EMF estimators of Solsona, Valla, Muravchik (2000) need, since they see nothing at
//! standstill.
//!
//! # Open-loop start
//!
//! The current loops regulate `(I, 0)` in an imposed frame `θ_ol` that starts at the detected
//! rotor angle (the current along the rotor's d axis: no torque, no jerk) and accelerates at a
//! constant rate. The rotor lags the current vector by the angle where the torque
//! `K_T I sin(θ_ol − θ)` equals what the acceleration and the load need:
//! `δ = θ − θ_ol ∈ [−90°, 0]` turning forwards (mirrored backwards). Nothing but friction damps
//! the rotor's swing about that angle; the closed loop does, once it has taken over.
//!
//! # Handover
//!
//! At the handover speed the estimator has seen the EMF for a while. The rotor swings about its
//! lag angle, so the check is what physics allows whatever the swing: the estimated angle
//! within a quarter turn (plus [`HANDOVER_MARGIN`]) of the current vector, which rules out the
//! dangerous false lock half a turn away, and the estimated speed in the commanded direction
//! and at least [`HANDOVER_SPEED_TOLERANCE`] of the imposed one. Otherwise the drive trips
//! with a named fault rather than closing the loop on a wrong angle. The speed loop starts
//! from the torque current the rotor was getting, `I sin(−δ̂)`, so the handover is bumpless.
//!
//! # Reversal
//!
//! A back-EMF estimator sees nothing near standstill, and driven through zero speed in the
//! closed loop (slowly under load) it can come out locked on the mirror solution: the estimate
//! turning the way the reference asks, the rotor the other way, no fault (`cargo xtask family`
//! found it on most surface motors). So when the closed loop's reference is in one direction
//! and the estimated speed, in the other, has come down to the handover speed, the drive goes
//! back to the open-loop current vector from the estimated state ([`OpenLoop::reverse`]): the
//! imposed frame starts at the estimated speed (the speed loop's filtered one: the MRAS on the
//! EMF of a 48 V motor near a tenth of its rated speed under load swung ±150 r/min about the
//! rotor's, and a reversal entered on a low sample started the frame 240 r/min slower than the
//! rotor, which slipped out of it: family seed 2 #31; seeds 1…14 hold 299 of 301 runs with
//! the filtered speed, 293 with the sample), turned from the estimated rotor angle so that
//! the current keeps the torque's sign, decelerates through zero at the start's acceleration
//! (where the estimator restarts at the frame's angle less that turn, [`OpenLoop::restart_angle`],
//! and holds the new direction as at the start) and hands over in the new direction with the
//! same check as at the start. Without the hold, an estimator restarted off the rotor's angle
//! (the frame runs ahead of a rotor whose estimate lagged it into the reversal) could see its
//! EMF turn the old way while it converged and take that direction: on the random family
//! (`cargo xtask family 40 --seed S`, S = 1…14) the hold takes the AO from 295 to 300 of 301
//! runs and the MRAS on the EMF from 276 to 293, the NLO (301) and the current-model MRAS
//! unchanged.
//!
//! A load strong enough to turn the rotor against the open loop's current leaves the frame
//! and the rotor turning opposite ways, and the estimate handed over lies about the rotor's
//! mirror: in the closed loop it soon turns against the reference again. That return to the
//! open loop within the checks' settling time of a handover for a reference of the same sign
//! is no reversal but a lost lock, and the task names it (`Fault::LossOfLock`): passed back
//! through the open loop each time, the drive handed over every few milliseconds, each
//! handover resetting the checks, and never tripped.
//!
//! The turn carries the speed loop's `i_q` alone, not what the frame's own deceleration
//! takes besides. That sum is the rotor's balance only where the rotor held its speed before
//! the reversal; a rotor still decelerating (the MRAS on the EMF, whose higher handover speed
//! it enters from) already carries it in `i_q`, and counting it twice lost more reversals
//! than it saved. The estimated speed's change over a task period, which would tell the two
//! apart, is dominated by the estimate's noise near the handover speed. The swing the step in
//! torque starts is the damping's to take out (below).
//!
//! # Damping
//!
//! Nothing in the open loop damps the rotor's swing about its lag: the torque
//! `K_T I sin δ` is a spring in the lag `δ` of natural frequency `ω_n = √(p K_T I/J)`
//! (electrical), and a load step, the change from the closed loop's torque to the one the
//! frame's acceleration takes, or a load that changes sign through a reversal sets it
//! swinging; past a quarter turn the rotor slips out of the frame. So while the estimate
//! sees the rotor (its speed and the frame's both beyond half the handover speed, the same
//! way) the task leads the frame by `k_d (ω_f − ω̂)`, at most an eighth of a turn, with
//! `k_d = 2ζ/ω_n` and `ζ = ½` ([`damping`], [`frame_shift`]): a rotor falling behind the
//! frame gets more torque, one running ahead less, and about its lag the swing is that of
//! `δ̈ + k_d ω_n² δ̇ + ω_n² δ = 0`, damped by half. Below half the handover speed the frame
//! runs as ramped: there the estimate knows nothing, and the swing a load excites there is
//! what the damping took out before. Sent with each command, the lead is a step at the task's
//! rate: `ω_n` is far below it.
//!
//! # Alignment
//!
//! The d current first along a quarter turn ahead of `θ = 0`, ramped up over the first eighth
//! of the alignment time, then along `θ = 0`, ramped up again until the half and held over the
//! second half. The first step is short: it only has to move a rotor off the second's dead
//! point; a longer one (a quarter) swung motor C's rotor, standing at `θ = 0`, out and back, and
//! the estimator started on a rotor not yet at rest (at zero speed under rated load it then
//! let the load turn the rotor backwards at 280 r/min). A single step along `θ = 0` leaves a rotor that stands half a turn away where it
//! is: the current along its negative d axis has no torque (an unstable rest, which the
//! plant's exact motor keeps; a real one leaves it slowly), and the estimator then starts half
//! a turn off: motor A from 180° tripped at the handover (docs/PERFORMANCE.md, operating map).
//! The first step's own dead point, a quarter turn behind `θ = 0`, is a quarter turn from the
//! second's. Nothing in a current loop damps the rotor's swing about `θ = 0` (a heavy
//! rotor released at 120° still swings by ±90° after 0.5 s, and the estimator then starts on a
//! rotor that is neither there nor at rest), so the q axis is not regulated: its reference is
//! the measured `i_β`, the q error is zero, its PI (reset, without speed feed-forward at
//! `ω = 0`) puts out zero volts, and the β winding is shorted through the inverter. The swing's
//! EMF `ω ψ cos θ` then drives `i_β = −ω ψ cos θ / R`, whose torque brakes the rotor with the
//! electrical damping `1.5 p² ψ²/R` (docs/identification.md, the same held-voltage argument).
//!
//! ## Where the rotor stops
//!
//! With the β winding shorted, any voltage the inverter adds to zero (the dead-time
//! compensation's residual: an inverter's distortion is never quite the one the drive was
//! told, 14 % more in the case below by the calibration's measurement) drives
//! `i_β = ΔV_β/R`, and the rotor comes to rest along the current vector, not along α: a
//! rotor at rest carries no torque, so the current lies on its d axis. On a low-resistance
//! motor that is far from zero (0.40 Ω on 540 V with 2.87 µs of dead time: 13 A of β current
//! beside 28 A on α, the rotor 0.5 rad off). The alignment therefore ends at the current's
//! angle, `atan2(i_β, I)`, from the last sample's `i_β` (the swing is damped out by then, and
//! the last sample needs no state); exact at rest without load (a load holding the rotor would
//! leave it off by the load angle, as `θ = 0` did).

use super::Fault;
use super::config::OpenLoopConfig;
use crate::angle::Angle;
use crate::frames::{AlphaBeta, Dq};
use crate::num::{Pu, mul_unit};
use crate::observer::Estimate;
use crate::params::MotorParams;
use crate::units::PerUnit;

/// The alignment's first frame, a quarter turn ahead of the second (`θ = 0`): a rotor half a
/// turn from `θ = 0`, where a current along α has no torque, is pulled from there first.
const ALIGN_FIRST: Angle = Angle(1 << 30);

/// Tolerance of the handover angle check beyond the physical range [0, 90°].
pub const HANDOVER_MARGIN: Angle = Angle(1 << 28); // 22.5°
/// Smallest estimated speed at the handover, as a fraction of the imposed one.
pub const HANDOVER_SPEED_TOLERANCE: f64 = 0.25;

/// State of the alignment and of the open-loop start.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct OpenLoop {
    theta: Angle,
    omega: Pu,
    reverse: bool,
    count: u32,
    /// A reversal: the rotor's angle behind the imposed frame when it began, kept until the
    /// frame passes through zero speed (then the estimator restarts there).
    reversal_lag: Option<Angle>,
    /// The open loop is a reversal from the closed loop.
    reversal: bool,
    /// The alignment's current ramp, [`Pu`] bits with 16 more fractional bits.
    ramp: i64,
    /// The frame's lead over its ramp, the task's damping (module docs, "Damping").
    pub shift: Angle,
}

impl OpenLoop {
    /// Alignment from its first sample.
    pub fn align() -> Self {
        Self::default()
    }

    /// The alignment's end at the angle `theta` already known (the dead-time calibration
    /// after an initial position detection: no pull, the rotor is there).
    pub fn aligned_at(theta: Angle, c: &OpenLoopConfig) -> Self {
        Self {
            theta,
            count: c.align_samples,
            ..Self::default()
        }
    }

    /// The angle the alignment holds: zero, or the one detected.
    pub fn align_angle(&self) -> Angle {
        self.theta
    }

    /// The alignment's frame and current reference (module docs, "Alignment"): the first
    /// eighth of the samples a quarter turn ahead of `θ = 0`, `(I_r, −i_α)` with `I_r` ramped
    /// to `I`; then `θ = 0`, `(I_r, i_β)` ramped again up to the half and held at `I` over the
    /// second half (the q reference is the measured q current of the frame: zero q voltage). Counts the
    /// sample. At the last sample the rotor's angle is taken as the current's,
    /// `atan2(i_β, I)` (module docs, "where the rotor stops").
    pub fn align_frame(&mut self, c: &OpenLoopConfig, i: AlphaBeta) -> (Angle, Dq) {
        self.count = self.count.saturating_add(1);
        let n = c.align_samples;
        let first = (n / 8).max(1);
        // I · k/len by steps of I/len (16 more fractional bits): within an LSB of the
        // exact ramp up to 2¹⁶ samples, without a division per sample.
        let [step_first, step_second] = c.align_steps;
        let step = if self.count < first {
            step_first
        } else if self.count == first {
            self.ramp = 0;
            0
        } else {
            step_second
        };
        self.ramp = self.ramp.saturating_add(step);
        let top = i64::from(c.current.to_bits());
        let d = Pu::from_bits(((self.ramp + (1 << 15)) >> 16).min(top) as i32);
        if self.count < first {
            return (
                ALIGN_FIRST,
                Dq {
                    d,
                    q: i.alpha.saturating_neg(),
                },
            );
        }
        if self.count == n {
            self.theta = crate::cordic::polar(c.current, i.beta).angle;
        }
        (Angle::ZERO, Dq { d, q: i.beta })
    }

    /// The alignment has lasted its time.
    pub fn align_done(&self, c: &OpenLoopConfig) -> bool {
        self.count >= c.align_samples
    }

    /// Open-loop start from the rotor angle `theta`, backwards if `reverse`.
    pub fn start(theta: Angle, reverse: bool) -> Self {
        Self {
            theta,
            omega: Pu::ZERO,
            reverse,
            count: 0,
            reversal_lag: None,
            reversal: false,
            ramp: 0,
            shift: Angle::ZERO,
        }
    }

    /// The open-loop reversal from the closed loop (module docs): the imposed frame at the
    /// estimated speed `omega`, turned from the estimated angle `theta` by
    /// `atan2(i_q, I)` so that the vector `(I, 0)` pulls the way the speed loop's `i_q` did, and
    /// accelerating towards `reverse`.
    pub fn reverse(theta: Angle, omega: Pu, iq: Pu, reverse: bool, c: &OpenLoopConfig) -> Self {
        let turn = crate::cordic::polar(c.current, iq).angle;
        Self {
            theta: theta + turn,
            omega,
            reverse,
            count: 0,
            reversal_lag: Some(turn),
            reversal: true,
            ramp: 0,
            shift: Angle::ZERO,
        }
    }

    /// The open loop is a reversal from the closed loop (not the start).
    pub fn is_reversal(&self) -> bool {
        self.reversal
    }

    /// The frame turns backwards.
    pub fn is_reverse(&self) -> bool {
        self.reverse
    }

    /// In a reversal, once the imposed frame has come through zero speed to half the handover
    /// speed in the new direction: the angle the estimator restarts from (at zero speed), the rotor behind the
    /// frame by the lag it had when the reversal began. Near zero speed a back-EMF estimator
    /// knows nothing, and restarted there it takes up the new direction as at the start
    /// instead of keeping what it drifted to (the mirror solution). With it the speed to
    /// restart from: the frame's, at least one LSB in the new direction (the estimators take
    /// their direction from its sign). Once per reversal.
    pub fn restart_angle(&mut self, c: &OpenLoopConfig) -> Option<(Angle, Pu)> {
        // Half the handover speed into the new direction: the rotor, which lags the frame's
        // deceleration, has come through zero too.
        let half = Pu::from_bits(c.handover_speed.to_bits() >> 1);
        let through = if self.reverse {
            self.omega <= half.saturating_neg()
        } else {
            self.omega >= half
        };
        match self.reversal_lag {
            Some(lag) if through => {
                self.reversal_lag = None;
                let lsb = Pu::from_bits(1);
                let omega = if self.reverse {
                    self.omega.min(lsb.saturating_neg())
                } else {
                    self.omega.max(lsb)
                };
                Some((self.theta + self.shift - lag, omega))
            }
            _ => None,
        }
    }

    /// Advances the imposed frame by one sample: its angle, speed and current reference
    /// `(I, 0)` (the current vector is the imposed d axis).
    pub fn advance(&mut self, c: &OpenLoopConfig) -> (Angle, Pu, Dq) {
        let ol = c;
        let step = if self.reverse {
            ol.accel.saturating_neg()
        } else {
            ol.accel
        };
        // Past the handover speed too while the handover waits (at most as long again as the
        // ramp took: twice the handover speed).
        self.omega = self.omega.saturating_add(step);
        self.theta = self.theta + Angle(ol.turn_per_speed.apply_bits(self.omega.to_bits()));
        (
            self.theta + self.shift,
            self.omega,
            Dq {
                d: ol.current,
                q: Pu::ZERO,
            },
        )
    }

    /// The imposed frame has reached the handover speed in its direction.
    pub fn at_handover(&self, c: &OpenLoopConfig) -> bool {
        let h = c.handover_speed;
        if self.reverse {
            self.omega <= h.saturating_neg()
        } else {
            self.omega >= h
        }
    }
}

/// The open loop's damping (module docs, "Damping"): `k_d = 2ζ/ω_n` with `ζ = ½` and
/// `ω_n = √(p K_T I/J)`, the rotor's swing about its lag at the open loop's current `I`
/// (electrical, rad/s), as the frame's lead per unit of speed, angle LSB per 2¹⁶ [`Pu`] LSB
/// (`k_d ω_b 2²⁴/(2π)`, saturated).
pub(crate) fn damping(motor: &MotorParams, base: &PerUnit, current_a: f64) -> i32 {
    let w_n = libm::sqrt(motor.p() * motor.kt_nm_per_a * current_a / motor.j_kg_m2);
    let k_d = 1.0 / w_n;
    // Angle LSB per 2¹⁶ Pu LSB (2⁻⁸ per unit of speed).
    let d = k_d * base.omega_e_rad_s / (Angle::RAD_PER_LSB * 256.0);
    if d.is_finite() {
        d.clamp(0.0, f64::from(i32::MAX)) as i32
    } else {
        0
    }
}

/// The frame's lead for a task period of the open loop whose frame turned at `omega_frame`
/// and the estimate at `omega_est` (module docs, "Damping"): `k_d (ω_f − ω̂)`, within an
/// eighth of a turn, while the estimate sees the rotor (both beyond half the handover speed
/// `handover`, the same way); zero otherwise.
pub(crate) fn frame_shift(omega_frame: Pu, omega_est: Pu, handover: Pu, damping: i32) -> Angle {
    let (f, e) = (omega_frame.to_bits(), omega_est.to_bits());
    let half = (handover.to_bits() >> 1).unsigned_abs();
    if (f ^ e) < 0 || f.unsigned_abs() < half || e.unsigned_abs() < half {
        return Angle::ZERO;
    }
    // The same sign: the difference cannot wrap.
    let lead = (i64::from(f - e) * i64::from(damping)) >> 16;
    Angle(lead.clamp(-(1 << 29), 1 << 29) as i32)
}

/// The imposed frame at the handover, as the task sees it in the interrupt's window.
#[derive(Clone, Copy, Debug)]
pub(crate) struct HandoverFrame {
    pub theta: Angle,
    pub omega: Pu,
    /// Turning backwards.
    pub reverse: bool,
    /// A reversal from the closed loop (not the start).
    pub reversal: bool,
}

/// Checks the estimate `est` against the imposed frame (module docs, "Handover"); on success
/// the torque current the rotor gets in the estimated frame, per unit, from the open loop's
/// current `current`.
pub(crate) fn handover(f: &HandoverFrame, est: &Estimate, current: Pu) -> Result<Pu, Fault> {
    // δ̂ = θ̂ − θ_ol, measured in the sense of rotation.
    let delta = if f.reverse {
        f.theta - est.theta
    } else {
        est.theta - f.theta
    };
    let angle_ok = delta.0.unsigned_abs() <= (Angle::HALF_PI.0 + HANDOVER_MARGIN.0) as u32;
    let tolerance = crate::num::pu_from_f64(HANDOVER_SPEED_TOLERANCE);
    let forward_speed = if f.reverse {
        est.omega.saturating_neg()
    } else {
        est.omega
    };
    let speed_ok = forward_speed >= crate::num::mul(tolerance, f.omega.saturating_abs());
    if !(angle_ok && speed_ok) {
        // A reversal whose rotor still turns the old way at the handover was held there by
        // its load: named as such, as the closed loop's check would.
        if f.reversal && forward_speed < Pu::ZERO {
            return Err(Fault::DrivenBackwards);
        }
        return Err(Fault::Handover(delta, est.omega));
    }
    // The current (I, 0) at θ_ol seen from the rotor at θ_ol + δ: q component I sin(−δ),
    // signed with the direction.
    let iq = mul_unit(current, (-delta).sin_cos().sin);
    Ok(if f.reverse { iq.saturating_neg() } else { iq })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::drive::DriveDesign;
    use crate::drive::TASK_PERIOD;
    use crate::fixtures::{inverter_b, motor_b};
    use crate::num::pu_from_f64;
    use crate::observer::EstimatorKind;
    use crate::units::PerUnit;
    use core::f64::consts::{PI, TAU};

    /// The alignment ends at the angle of the last sample's current `(I, i_β)`, against the
    /// `f64` `atan2` within 10⁻⁵ rad (`polar`'s rounding), for β currents up to ±I; the
    /// frame is a quarter turn ahead over the first eighth of the samples, then zero; the d
    /// current ramps from zero to `I` over that eighth, and again from zero until the half (the
    /// q reference the frame's measured q current).
    #[test]
    fn the_alignment_ends_at_the_currents_angle() {
        let (m, inv) = (motor_b(), inverter_b());
        let base = PerUnit::new(&m, &inv, 14e3).unwrap();
        let design = DriveDesign::default_for(&m, &inv, &base, EstimatorKind::MrasCurrent);
        let c = crate::drive::DriveConfig::new(&m, &inv, 14e3, design)
            .unwrap()
            .isr
            .open_loop;
        let i = c.current.to_bits() as f64;
        let n = c.align_samples;
        let first = n / 8;
        assert!(first > 10);
        for ratio in [-1.0, -0.47, -0.01, 0.0, 0.2, 0.9] {
            let i_ab = AlphaBeta {
                alpha: pu_from_f64(0.3),
                beta: pu_from_f64(ratio * i / (1u64 << 24) as f64),
            };
            let mut ol = OpenLoop::align();
            let mut k = 0;
            while !ol.align_done(&c) {
                k += 1;
                let (frame, i_ref) = ol.align_frame(&c, i_ab);
                let (want_frame, ramp, q) = if k < first {
                    (
                        ALIGN_FIRST,
                        k as f64 / first as f64,
                        i_ab.alpha.saturating_neg(),
                    )
                } else {
                    let len = (n / 2 - first) as f64;
                    (Angle::ZERO, ((k - first) as f64 / len).min(1.0), i_ab.beta)
                };
                assert_eq!(frame, want_frame, "sample {k}");
                assert_eq!(i_ref.q, q, "sample {k}");
                assert!(
                    (i_ref.d.to_bits() as f64 - i * ramp).abs() <= 1.0,
                    "sample {k}"
                );
            }
            let want = libm::atan2(i_ab.beta.to_bits() as f64, i);
            let got = ol.align_angle().to_rad();
            assert!(
                (got - want).abs() < 1e-5,
                "i_β/I {ratio}: {got} against {want}"
            );
        }
    }

    /// Motor B's bases, the open loop's damping at its rated current, `ω_n` and a handover
    /// speed of 0.1 pu.
    fn damping_b() -> (PerUnit, i32, f64, Pu) {
        let (m, inv) = (motor_b(), inverter_b());
        let base = PerUnit::new(&m, &inv, 14e3).unwrap();
        let d = damping(&m, &base, base.current_a);
        let w_n = libm::sqrt(m.p() * m.kt_nm_per_a * base.current_a / m.j_kg_m2);
        (base, d, w_n, pu_from_f64(0.1))
    }

    /// The lead is `k_d (ω_f − ω̂)` with `k_d = 1/ω_n`, within 10⁻⁶ rad of the `f64` product
    /// over speeds beyond half the handover speed, an eighth of a turn at most; zero below
    /// half the handover speed or with the estimate turning the other way.
    #[test]
    fn the_frame_leads_by_the_speed_it_gains_on_the_estimate() {
        let (base, d, w_n, h) = damping_b();
        let mut worst = 0.0f64;
        for k in -40..=40 {
            let (f, e) = (
                0.06 + 0.01 * f64::from(k.max(0)),
                0.06 + 0.0005 * f64::from(k + 40),
            );
            for sign in [1.0, -1.0] {
                let lead = frame_shift(pu_from_f64(sign * f), pu_from_f64(sign * e), h, d);
                let want = (sign * (f - e) * base.omega_e_rad_s / w_n).clamp(-0.25 * PI, 0.25 * PI);
                worst = worst.max((lead.to_rad() - want).abs());
            }
        }
        assert!(worst < 1e-6, "{worst}");
        let at = |f: f64, e: f64| frame_shift(pu_from_f64(f), pu_from_f64(e), h, d);
        assert_eq!(at(0.04, 0.2), Angle::ZERO);
        assert_eq!(at(0.2, 0.04), Angle::ZERO);
        assert_eq!(at(0.2, -0.2), Angle::ZERO);
        assert_eq!(at(-0.06, 3.0), Angle::ZERO);
        assert_eq!(at(3.0, 0.06), Angle(1 << 29));
        assert_eq!(at(-3.0, -0.06), Angle(-(1 << 29)));
    }

    /// The rotor released a sixth of a turn off its lag at the open loop's current, on motor B
    /// with the frame at constant speed: undamped it swings back as far; with the lead the
    /// task sends (taken every task period from the rotor's speed, as the estimate would give
    /// it) its swing is down to a tenth within two periods of `ω_n`.
    #[test]
    fn the_lead_damps_the_rotors_swing_about_its_lag() {
        let (base, d, w_n, h) = damping_b();
        let w_f = 0.3 * base.omega_e_rad_s;
        let swing = |damped: bool| {
            // δ: the rotor's angle behind the ramp, electrical; the frame leads the ramp by the
            // shift; the torque's spring acts on the frame's lead over the rotor.
            let (mut delta, mut w_r) = (PI / 3.0, w_f);
            let (ts, mut shift, mut late) = (base.sample_s, 0.0, 0.0f64);
            let samples = (2.0 * TAU / w_n / ts) as usize;
            for k in 0..2 * samples {
                if damped && k % TASK_PERIOD as usize == 0 {
                    let (f, e) = (w_f / base.omega_e_rad_s, w_r / base.omega_e_rad_s);
                    shift = frame_shift(pu_from_f64(f), pu_from_f64(e), h, d).to_rad();
                }
                let accel = w_n * w_n * libm::sin(delta + shift);
                w_r += accel * ts;
                delta += (w_f - w_r) * ts;
                if k >= samples {
                    late = late.max(delta.abs());
                }
            }
            late
        };
        let (free, damped) = (swing(false), swing(true));
        assert!(free > 0.9 * PI / 3.0, "undamped {free}");
        assert!(damped < 0.1 * PI / 3.0, "damped {damped}");
    }
}
