//! Fault detection beyond the per-sample trips: a broken current sensor, an open phase, a
//! stalled rotor, an estimator that lost its lock. Each check is a counter or a first-order
//! filter on signals the drive has anyway, with thresholds from the motor's ratings, and each
//! is guarded so that a healthy run never trips it (tests: every shipped scenario and a sweep
//! of random healthy ones).
//!
//! The checks run in the task, once per task period ([`super::TASK_PERIOD`] samples), on
//! what the interrupt side reports of the period ([`Signals`]): the last sample, and each
//! phase's mean squared current. The filters are first-order with the pole a power of two (a
//! shift, no product): their time constants below are rounded to a power of two of task
//! periods (at 14 kHz a period is 8 samples, 0.57 ms: 2 ms is 4 periods, 10 ms 16). The sum of
//! the three currents is checked on every sample by the interrupt side.
//!
//! | fault | evidence | time to trip |
//! |---|---|---|
//! | current sensor (sum) | `|i_a + i_b + i_c|` filtered over 1 ms above 0.15 `I_b` | 1–3 ms |
//! | current sensor (stuck) | a phase reading the same bits for 50 ms while the rotor turns in the closed loop and another phase changes | 50 ms |
//! | phase loss (open or unbalanced phase) | one phase's filtered `i²` (5 ms) below 3/64 (4.7 %) of the three's sum (a third when balanced) through half a turn, with the sum above that of a balanced 1 % `I_b` and the rotor turning faster than `0.5/τ` (`τ` the filter's time constant; 110 rad/s electrical at 5 ms) for `2τ`, at any load | 10–30 ms at 800 r/min on motor B, no load (under load the loss-of-lock check is often first) |
//! | stall | the speed loop's current reference above 90 % of its limit and the estimated speed, along the reference's direction, below half the reference and not gaining speed (under a floor that starts at its value and rises at 1/64 of the motor's largest acceleration) for 50 ms, from 100 ms after entering the closed loop | 50–70 ms |
//! | loss of lock | the estimated speed changing faster than 20 × the motor's largest acceleration, over 2 ms, from 100 ms after entering the closed loop | 2–5 ms |
//! | driven backwards | the speed loop at 90 % of its limit in the reference's direction, the estimated speed the other way beyond 0.1 pu and above a ceiling that starts at its value and falls at 1/16 of the motor's largest deceleration, for 20 ms | 20–40 ms |
//! | loss of lock (estimator's figure) | [`Estimator::health`] filtered over 10 ms above `Protection::health_limit_pu` (default 1.0 pu), from 100 ms after entering the closed loop, in steady state (40 ms at a constant reference with the estimate within 0.02 pu of it throughout, until the reference changes) | 10–20 ms |
//! | loss of lock (angle against speed) | the estimated angle turning one way over a task period and the estimated speed the other, both beyond 0.03 pu and the speed below a quarter turn a period, in the closed loop, until the angle has turned a quarter turn (electrical) away from the speed's integral: the mirror solution of a back-EMF estimator (a rotor turning backwards at `θ` has the EMF of one turning forwards at `θ + π`), which a load that stops and reverses a light rotor leaves it in, half a turn off the rotor, or any estimate that turns away from the rotor while its speed does not | a quarter turn at twice the speed: 3 ms at 600 r/min on four pole pairs |
//! | loss of lock (against the torque) | the speed loop at 90 % of its limit, the estimated speed falling against the limit's torque faster than the motor's largest acceleration (over 5 ms), and the estimator's filtered figure above its limit, from 100 ms after entering the closed loop: an estimate that has left the rotor (a rotor slows so only under a load of more than twice the drive's torque, and a healthy estimate that swings about the limit explains the currents) | 3–5 ms |
//! | loss of lock (current tracking) | `|i_d − i_d*| + |i_q − i_q*|` in the estimated frame, filtered over 10 ms (held while the modulator limits the voltage) above a third of the current limit, from 100 ms after entering the closed loop | 10–50 ms |

use super::Fault;
#[cfg(doc)]
use crate::Estimator;
use crate::angle::Angle;
use crate::frames::{Abc, Dq};
use crate::num::{Pu, follow, follow_shift, pu_from_f64};

/// Thresholds and filter poles, per unit and in task periods.
#[derive(Clone, Copy, Debug, crate::image::Words)]
pub(crate) struct MonitorConfig {
    /// Filters of 2 and 10 ms as shifts: `y += (x − y) >> k`, the pole `2^−k` with the
    /// time constant rounded to a power of two of task periods (no product).
    pub ms2: u32,
    pub ms10: u32,
    /// The phase-loss filter (5 ms), as the others.
    pub ms5: u32,
    pub stuck_samples: u32,
    pub turning: Pu,
    /// Least filtered `Σ i_x²` (in the Q8.12 squares of [`phase_power`]) for the phase-loss
    /// test: (1 % of `I_b`)² times 3/2, the sum of a balanced 1 % current.
    pub min_power: u32,
    /// Least speed for the phase-loss test, per unit: `0.5/τ` of its filter (`τ` the 5 ms
    /// filter), where the ripple of a balanced phase's filtered square is 71 % of its mean
    /// (its share still above 3/32, twice the threshold).
    pub phase_loss_speed: Pu,
    /// Rotation a phase must stay below 3/64 of the power through before it trips: half a
    /// turn (electrical), as the sum of the speed's bits over the steps. A healthy current
    /// vector that was just built in one direction (a load step) turns through every phase
    /// within it; an open phase stays dark. (A quarter turn tripped a healthy 540 V motor of
    /// the random family at load off, whose small current vector turned back in the rotor
    /// frame as fast as the rotor turned, so that it stood still on the stator for 6 ms.)
    pub phase_loss_turn: u64,
    /// Steps the test's conditions must hold before it counts: two time constants of its
    /// filter.
    pub phase_loss_arm_samples: u32,
    /// Steps (50 ms) at the limit without gaining speed before a stall trips.
    pub stall_samples: u32,
    /// 90 % of the speed loop's current limit, per unit.
    pub stall_current: Pu,
    /// Largest plausible change of the estimated speed per step (eight samples), per unit.
    pub accel_limit: Pu,
    /// Samples after entering the closed loop before the lock is judged (the estimate settles
    /// after a detection or a handover).
    pub settle_samples: u32,
    /// Limit of the estimator's filtered health figure ([`Estimator::health`], filter
    /// `ms10`), per unit of its own quantity; `Pu::MAX` never trips.
    pub health_limit: Pu,
    /// Consecutive steps in steady state (the reference unchanged and the estimated speed
    /// within [`MonitorConfig::steady_error`] of it) before the health figure is judged: four time
    /// constants of its 10 ms filter (40 ms), so that what an acceleration left in the filter
    /// has decayed below 2 %. Judged from then until the reference changes.
    pub health_arm_samples: u32,
    /// Speed error of the steady state, per unit (0.02).
    pub steady_error: Pu,
    /// Least wrong-way speed that counts towards [`Fault::DrivenBackwards`]: 0.1 pu of the
    /// base speed (above the estimators' speed ripple at standstill).
    pub backwards_speed: Pu,
    /// How much the wrong-way speed must fall per step while the loop pushes at its limit:
    /// 1/16 of the motor's largest deceleration `p K_T I_max/J`. A healthy reversal falls at
    /// that deceleration less what an overhauling load takes (at most 80 % on the sweep's
    /// loads); a rotor the load drives backwards does not fall.
    pub backwards_fall: Pu,
    /// How much a rotor at the limit must gain per step not to count as stalled: 1/64 of
    /// `p K_T I_max/J` (a rotor of the random family reversing against 0.6 of its rated
    /// torque with its estimate 0.85 rad behind gained at 1/36 of it, and made it).
    pub stall_rise: Pu,
    /// Steps (20 ms) the rotor must keep being driven backwards before the drive trips.
    pub backwards_samples: u32,
    /// The motor's largest acceleration `p K_T I_max/J` per step: the estimate slowing
    /// against the limit's torque faster than this (filter `ms5`) is a lost lock.
    pub against_torque: Pu,
    /// Limit of the current loops' filtered tracking error `|e_d| + |e_q|` (filter `ms10`):
    /// a third of the speed loop's current limit. A healthy loop tracks within a few percent
    /// of the limit, but while the modulator limits the voltage (when the check holds); in a
    /// lost lock the motor's EMF turns in the estimated frame at the slip frequency, beyond
    /// the loops' reach. On the random family's lost reversals the filtered error reached
    /// 0.38–0.81 of the limit within 30 ms of the loss, while the worst healthy run seen (a
    /// 48 V start whose estimated speed lagged at the limit, the angle within 0.21 rad)
    /// peaked at 0.25. In quarters of [`Pu`]'s bits, as the filter.
    pub tracking_limit: i32,
    /// The estimated angle's turn over a task period (in [`Angle`] bits) as a speed in [`Pu`]
    /// bits: `(turn · k) >> 16`, `k = 2π 2²⁴ / (2³² ω_b T)` in Q16.16 (`T` the task period).
    pub turn_to_pu_q16: i64,
    /// Least speed, by the angle and by the estimate, of an angle turning against the speed.
    pub against_speed: Pu,
    /// How far the angle must turn away from the speed's integral, against it, before the
    /// drive trips: a quarter turn, as `Σ |ω_angle − ω̂|` in [`Pu`] bits over task periods.
    /// The same bits are the largest estimated speed at which the check is made, a quarter
    /// turn a task period, so that the angle's turn over the period, a difference of two
    /// angles, cannot alias (the mirror solution comes about through zero speed, far below).
    pub against_turn: u64,
}

impl MonitorConfig {
    /// For task period `tt`, base speed `omega_b` (rad/s) and the largest electrical
    /// acceleration the motor can make, `p K_T I_max/J` (rad/s²).
    pub fn new(
        tt: f64,
        omega_b: f64,
        max_accel_rad_s2: f64,
        current_limit_pu: f64,
        health_limit: Pu,
    ) -> Option<Self> {
        // τ/T to the nearest power of two, 1 to 2²⁰ task periods.
        let pole = |tau: f64| follow_shift(tau / tt);
        // Half a turn (electrical) as Σ ω_pu over task periods, in bits of Pu.
        let half_turn =
            libm::ceil(core::f64::consts::PI / (omega_b * tt) * (1u64 << 24) as f64) as u64;
        Some(Self {
            ms2: pole(2e-3)?,
            ms10: pole(10e-3)?,
            stuck_samples: libm::ceil(0.05 / tt) as u32,
            turning: pu_from_f64(0.02),
            min_power: {
                let m = 0.01 * 4096.0;
                (1.5 * m * m) as u32
            },
            phase_loss_speed: pu_from_f64(
                0.5 / (tt * libm::ldexp(1.0, pole(5e-3)? as i32)) / omega_b,
            ),
            // Σ ω_pu ω_b T = π, in bits of Pu.
            phase_loss_turn: half_turn,
            phase_loss_arm_samples: 2 << pole(5e-3)?,
            ms5: pole(5e-3)?,
            stall_samples: libm::ceil(0.05 / tt) as u32,
            stall_current: pu_from_f64(0.9 * current_limit_pu),
            accel_limit: pu_from_f64(20.0 * max_accel_rad_s2 * tt / omega_b),
            settle_samples: libm::ceil(0.1 / tt) as u32,
            health_limit,
            health_arm_samples: libm::ceil(0.04 / tt) as u32,
            steady_error: pu_from_f64(0.02),
            backwards_speed: pu_from_f64(0.1),
            backwards_fall: pu_from_f64(max_accel_rad_s2 / 16.0 * tt / omega_b),
            stall_rise: pu_from_f64(max_accel_rad_s2 / 64.0 * tt / omega_b),
            backwards_samples: libm::ceil(0.02 / tt) as u32,
            against_torque: pu_from_f64(max_accel_rad_s2 * tt / omega_b),
            tracking_limit: pu_from_f64(current_limit_pu / 3.0).to_bits() >> 2,
            // Half a turn, a quarter, and a task period's turn per unit of speed, all from
            // one figure (π/(ω_b T) in Pu bits, as `phase_loss_turn`).
            turn_to_pu_q16: (half_turn >> 15) as i64,
            // 0.03 pu.
            against_speed: Pu::from_bits(503_316),
            against_turn: half_turn >> 1,
        })
    }
}

/// State of the checks.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Monitor {
    last_bits: [i32; 3],
    same: [u32; 3],
    /// Filtered `i_x²` of each phase (Q8.12 squares, see [`phase_power`]).
    power: [u32; 3],
    /// Rotation (Σ of the speed's bits) through which each phase has been below 3/64 of the
    /// total power.
    weak: [u64; 3],
    /// Samples the phase-loss test's conditions have held.
    armed: u32,
    /// The estimator's health figure, filtered.
    health: Pu,
    /// Stall: the steps in the condition without gaining speed, and the floor the speed
    /// along the reference must pass to start them again.
    stall: u32,
    stall_floor: Pu,
    /// The reference of the steady state and the steps spent in it (the health check's arming).
    steady_ref: Pu,
    steady: u32,
    /// Driven backwards: in the condition, the ceiling the wrong-way speed must stay under
    /// (its value on entry, falling by `backwards_fall` a step), and the steps above it.
    backwards_in: bool,
    backwards_ceiling: Pu,
    backwards: u32,
    last_omega: Option<Pu>,
    jerk: Pu,
    /// The estimate's deceleration against the limit's torque per step, filtered.
    against_torque: Pu,
    /// The current loops' tracking error, filtered, in quarters of [`Pu`]'s bits.
    tracking: i32,
    /// How far the estimated angle has turned away from the estimated speed's integral while
    /// turning against it (Σ of speed differences in [`Pu`] bits), and the last period's
    /// angle (in the closed loop).
    against: u64,
    last_theta: Option<Angle>,
    running_for: u32,
}

/// What the checks look at, once per task period.
pub(crate) struct Signals {
    /// The last sample's phase currents.
    pub i_abc: Abc,
    /// Each phase's mean squared current over the period (Q8.12 squares, [`phase_power`]).
    pub power: [u32; 3],
    /// The estimated speed at the last sample, and its mean over the period.
    pub omega: Pu,
    pub omega_mean: Pu,
    /// The estimated angle at the last sample.
    pub theta_est: Angle,
    pub omega_ref: Pu,
    /// The speed loop's current reference.
    pub iq_ref: Pu,
    pub running: bool,
    /// The estimator's health figure at the last sample.
    pub health: Pu,
    /// The last sample's current loops: reference, measurement, a limit held the voltage.
    pub i_ref: Dq,
    pub i_dq: Dq,
    pub saturated: bool,
}

impl Monitor {
    /// Restart (a new start).
    pub fn reset(&mut self) {
        *self = Self::default();
    }

    /// Whether the closed loop has run no longer than the checks' settling time
    /// ([`MonitorConfig::settle_samples`], 100 ms), in which the checks of the closed loop
    /// stay quiet.
    pub fn settling(&self, c: &MonitorConfig) -> bool {
        self.running_for <= c.settle_samples
    }

    /// One task period of every check; the first fault found.
    pub fn check(&mut self, c: &MonitorConfig, s: &Signals) -> Option<Fault> {
        let ph = [s.i_abc.a, s.i_abc.b, s.i_abc.c];
        let speed = s.omega.saturating_abs();
        self.running_for = if s.running {
            self.running_for.saturating_add(1)
        } else {
            0
        };
        if s.running
            && let Some(f) = self.check_stuck(c, &ph, speed)
        {
            return Some(f);
        }
        self.check_phase_loss(c, &s.power, speed, s.running)
            .or_else(|| self.check_health(c, s))
            .or_else(|| self.check_motion(c, s, speed))
            .or_else(|| self.check_tracking(c, s))
            .or_else(|| self.check_against(c, s))
    }

    /// Loss of lock: the estimated angle turns against the estimated speed. The estimators
    /// whose angle is the integral of their speed (the MRAS on the currents) never trip it;
    /// those that read the angle off the EMF and the speed off its size (the NLO, the AO, the
    /// MRAS on the EMF) can settle on the mirror solution, `θ + π` turning forwards for a
    /// rotor at `θ` turning backwards, and there the two disagree in sign.
    fn check_against(&mut self, c: &MonitorConfig, s: &Signals) -> Option<Fault> {
        let last = core::mem::replace(&mut self.last_theta, s.running.then_some(s.theta_est));
        // The angle's turn over the period (a wrapping difference), as a speed in Pu bits:
        // |turn| < 2³¹ and k < 2²³ (ω_b T ≥ 2⁻¹¹), the product fits an i64.
        let turn = last.map_or(0, |l| s.theta_est.0.wrapping_sub(l.0));
        let by_angle = (i64::from(turn) * c.turn_to_pu_q16) >> 16;
        let (floor, omega) = (
            i64::from(c.against_speed.to_bits()),
            i64::from(s.omega_mean.to_bits()),
        );
        let against = (by_angle > floor && omega < -floor) || (by_angle < -floor && omega > floor);
        self.against = if last.is_some() && against && omega.unsigned_abs() <= c.against_turn {
            self.against.saturating_add(by_angle.abs_diff(omega))
        } else {
            0
        };
        (self.against > c.against_turn).then_some(Fault::LossOfLock)
    }

    /// Phase loss.
    #[inline(always)]
    fn check_phase_loss(
        &mut self,
        c: &MonitorConfig,
        power: &[u32; 3],
        speed: Pu,
        running: bool,
    ) -> Option<Fault> {
        // Phase loss: one phase carries under 3/64 (4.7 %) of the current's power (a third
        // when balanced) while the rotor turns fast enough for the filter to average a period's
        // ripple away. An open phase keeps its current at zero (noise only), whatever the load:
        // the other two then carry ±the same current, and its share falls with the filter.
        let mut total = 0u32;
        for (p, &sq) in self.power.iter_mut().zip(power) {
            // Both ≤ 2³⁰: the difference fits an i32, the filtered value stays in [0, 2³⁰].
            *p = p.wrapping_add_signed((sq.wrapping_sub(*p) as i32) >> c.ms5);
            total += *p; // ≤ 3·2³⁰
        }
        // Armed once the conditions have held for two time constants: a current vector just
        // built from nothing (a load step at no load) or a filter that has just come up to
        // speed has not turned through every phase yet.
        self.armed = if running && speed > c.phase_loss_speed && total > c.min_power {
            self.armed.saturating_add(1)
        } else {
            0
        };
        let armed = self.armed > c.phase_loss_arm_samples;
        let low = (total >> 5) + (total >> 6);
        let turn = speed.to_bits().unsigned_abs() as u64;
        for (k, (p, weak)) in self.power.iter().zip(self.weak.iter_mut()).enumerate() {
            *weak = if armed && *p < low {
                weak.saturating_add(turn)
            } else {
                0
            };
            if *weak > c.phase_loss_turn {
                return Some(Fault::PhaseLoss(k as u8));
            }
        }
        None
    }

    /// Stuck channel (in the closed loop only): the same bits for 50 ms while the rotor turns
    /// and other phases change (the last sample's reading compared with the last period's). Only the closed loop's estimate says that the rotor turns: during an alignment
    /// the estimator runs on a rotor held still, and the MRAS on the EMF drifted to 90 r/min
    /// there while the aligned phase's current, steady, kept its bits (540 V motors of the
    /// random family tripped before they started). Outside the closed loop the check is
    /// skipped whole, counts held: gating `turning` instead cost the Cortex-M0's step 18
    /// instructions against 12.
    #[inline(always)]
    fn check_stuck(&mut self, c: &MonitorConfig, ph: &[Pu; 3], speed: Pu) -> Option<Fault> {
        let turning = speed > c.turning;
        let bits = [ph[0].to_bits(), ph[1].to_bits(), ph[2].to_bits()];
        let changed = [
            bits[0] != self.last_bits[0],
            bits[1] != self.last_bits[1],
            bits[2] != self.last_bits[2],
        ];
        self.last_bits = bits;
        let any = changed[0] | changed[1] | changed[2];
        for (k, (count, mine)) in self.same.iter_mut().zip(changed).enumerate() {
            // Another phase moved when any did and this one did not. A sample where nothing
            // else moved says nothing: hold the count.
            *count = if mine || !turning {
                0
            } else if any {
                count.saturating_add(1)
            } else {
                *count
            };
            if *count > c.stuck_samples {
                return Some(Fault::CurrentSensor(Some(k as u8)));
            }
        }
        None
    }

    /// Stall, driven backwards, and loss of lock from the estimate's acceleration.
    fn check_motion(&mut self, c: &MonitorConfig, s: &Signals, speed: Pu) -> Option<Fault> {
        // Stall: at the current limit, far below the reference and not gaining speed, for
        // 50 ms. "Below" along the reference's direction: an estimate turning the other way (a
        // lock lost through zero speed under load) is slow too, not fast. "Not gaining": under
        // a floor that starts at the speed on entry and rises at 1/64 of the motor's largest
        // acceleration; a rotor that passes it (one accelerating at the limit, a heavy one
        // after a step of the reference, even against a load of 63/64 of the limit's torque)
        // starts the count again from its speed.
        let speed_ref = s.omega_ref.saturating_abs();
        let along = if s.omega_ref < Pu::ZERO {
            s.omega.saturating_neg()
        } else {
            s.omega
        };
        let slow = along < speed_ref >> 1;
        let limited = s.iq_ref.saturating_abs() >= c.stall_current;
        // Judged from 100 ms after entering the closed loop, as the other checks of a lock: a
        // start whose estimate slipped a turn in its first milliseconds and caught up (motor
        // B's model off by R +50 % and L +30 %) is no stall.
        if s.running
            && limited
            && slow
            && speed_ref > c.turning
            && self.running_for > c.settle_samples
        {
            let floor = self.stall_floor.saturating_add(c.stall_rise);
            if self.stall == 0 || along > floor {
                self.stall_floor = along;
                self.stall = 1;
            } else {
                self.stall_floor = floor;
                self.stall = self.stall.saturating_add(1);
            }
            if self.stall > c.stall_samples {
                return Some(Fault::Stall);
            }
        } else {
            self.stall = 0;
        }
        // Driven backwards: the loop pushes at its limit in the reference's direction and the
        // estimate turns the other way, beyond 0.1 pu, without falling as the limit's torque
        // would make it (a ceiling from its value on entry, falling at 1/16 of the motor's
        // largest deceleration), for 20 ms. A healthy reversal falls faster than the ceiling.
        // The common case (off the limit) costs one branch.
        let sign = s.omega_ref.to_bits();
        if limited
            && (s.omega.to_bits() ^ sign) < 0
            && (s.iq_ref.to_bits() ^ sign) >= 0
            && s.running
            && speed_ref > c.turning
        {
            if !self.backwards_in {
                self.backwards_in = true;
                self.backwards_ceiling = speed;
            }
            self.backwards_ceiling = self.backwards_ceiling.saturating_sub(c.backwards_fall);
            self.backwards = if speed > self.backwards_ceiling.max(c.backwards_speed) {
                self.backwards.saturating_add(1)
            } else {
                0
            };
            if self.backwards > c.backwards_samples {
                return Some(Fault::DrivenBackwards);
            }
        } else if self.backwards_in {
            self.backwards_in = false;
            self.backwards = 0;
        }
        // Loss of lock: the estimate accelerating faster than the motor can, once settled.
        // No fault before there is a last speed to compare with.
        let last = self.last_omega.replace(s.omega)?;
        if self.running_for <= c.settle_samples {
            return None;
        }
        let step = s.omega.saturating_sub(last);
        self.jerk = follow(self.jerk, step.saturating_abs(), c.ms2);
        if self.jerk > c.accel_limit {
            return Some(Fault::LossOfLock);
        }
        // Loss of lock: at the limit, the estimate slowing against the loop's torque faster
        // than that torque accelerates the rotor, over 5 ms, while the estimator no longer
        // explains the currents. A rotor slows so only under a load of more than twice the
        // drive's torque; an estimate that has left the rotor does it as it slips. The health
        // condition spares a healthy estimate that a model's error makes swing about the
        // limit (docs/drive.md, "the estimate against the torque").
        if limited && s.running {
            let against = if s.iq_ref < Pu::ZERO {
                step
            } else {
                step.saturating_neg()
            };
            self.against_torque = follow(self.against_torque, against, c.ms5);
            if self.against_torque > c.against_torque && self.health > c.health_limit {
                return Some(Fault::LossOfLock);
            }
        } else {
            self.against_torque = Pu::ZERO;
        }
        None
    }

    /// Loss of lock from the estimator's health figure.
    fn check_health(&mut self, c: &MonitorConfig, s: &Signals) -> Option<Fault> {
        // Loss of lock: the estimator's own figure of how badly its model explains the
        // measurements, filtered, once settled.
        self.health = if s.running {
            follow(self.health, s.health, c.ms10)
        } else {
            Pu::ZERO
        };
        // Judged in steady state only: an acceleration raises a healthy estimator's figure (the
        // current-model MRAS up to 1.3 pu on the sweep, its load steps 0.2 pu). Armed after
        // 40 ms at a constant reference with the estimate within 0.02 pu of it throughout,
        // until the reference changes.
        if s.omega_ref != self.steady_ref {
            self.steady_ref = s.omega_ref;
            self.steady = 0;
        } else if self.steady <= c.health_arm_samples {
            self.steady = if s.omega_ref.saturating_sub(s.omega).saturating_abs() < c.steady_error {
                self.steady + 1
            } else {
                0
            };
        }
        if self.health > c.health_limit
            && self.steady > c.health_arm_samples
            && self.running_for > c.settle_samples
        {
            return Some(Fault::LossOfLock);
        }
        None
    }

    /// Loss of lock from the current loops' tracking: the last sample's error, filtered, held
    /// while the modulator limits the voltage (a loop that cannot follow then is not lost).
    fn check_tracking(&mut self, c: &MonitorConfig, s: &Signals) -> Option<Fault> {
        if !s.running {
            self.tracking = 0;
        } else if !s.saturated {
            // In quarters of Pu's bits: each difference within ±2³⁰, their magnitudes' sum
            // below 2³¹: no wrap, no saturating step.
            let d = (s.i_ref.d.to_bits() >> 2).wrapping_sub(s.i_dq.d.to_bits() >> 2);
            let q = (s.i_ref.q.to_bits() >> 2).wrapping_sub(s.i_dq.q.to_bits() >> 2);
            let e = d.unsigned_abs().wrapping_add(q.unsigned_abs()) as i32;
            self.tracking = follow_nonnegative(self.tracking, e, c.ms10);
        }
        if self.tracking > c.tracking_limit && self.running_for > c.settle_samples {
            return Some(Fault::LossOfLock);
        }
        None
    }

    /// The estimator's health figure, filtered over 10 ms (zero outside the closed loop).
    pub fn health(&self) -> Pu {
        self.health
    }
}

/// [`follow`] for a state and an input both in `[0, 2³¹)`: their difference fits an `i32` and
/// the result lies between them, so plain 32-bit arithmetic cannot wrap (saturating steps cost
/// the Cortex-M0 a branch each).
#[inline(always)]
pub(crate) fn follow_nonnegative(y: i32, x: i32, k: u32) -> i32 {
    y.wrapping_add(x.wrapping_sub(y) >> k)
}

/// `i²` of a phase current in Q8.12 squares (`(i·2¹²)²`, the current saturated to ±8 pu, far
/// beyond any overcurrent trip, by a signed 16-bit saturation: one instruction on the
/// Cortex-M4): a 32-bit product on every core, and three of them sum below 2³² (each
/// ≤ 2³⁰).
#[inline(always)]
pub(crate) fn phase_power(i: Pu) -> u32 {
    let a = (i.to_bits() >> 12).clamp(-(1 << 15), (1 << 15) - 1);
    a.wrapping_mul(a) as u32
}

#[cfg(test)]
mod tests;
