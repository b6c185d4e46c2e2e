//! The identification's state machine: its state, the integer per-sample step and the
//! current loop shared by every stage. Each stage's excitation is in its own file
//! (`resistance`, `inductance`, `spin`), the background `f64` work in `poll` and `finish`.

use super::inductance::BurstSums;
use super::resistance::LevelSums;
use super::spin::{Seg, WindowSums};
use super::{Identified, IdentifyConfig, IdentifyError, Stage};
use crate::angle::Angle;
use crate::frames::{AlphaBeta, Dq, inverse_clarke, inverse_park};
use crate::num::{Pu, pu_from_f64, sat_i32};
use crate::svpwm::{Duties, SvpwmConfig, SvpwmOutput};

/// Output of one [`Identify::step`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct IdentifyOutput {
    /// Duties for the next control period.
    pub duties: Duties,
    /// The voltage those duties command, αβ per unit of `V_b`.
    pub v: AlphaBeta,
    /// Keep the inverter switching.
    pub pwm_on: bool,
    /// The stage running (or that ran last).
    pub stage: Stage,
    /// The commanded electrical speed of the spin, angle counts (2³² a turn) per sample
    /// × 2¹⁶ (0 outside it); [`Identify::speed_rad_s`] converts.
    pub speed_q16: u64,
    /// The sequence has ended; [`Identify::poll`] gives the result.
    pub finished: bool,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Phase {
    Align,
    Level(u8),
    /// Burst 0 = d coarse, 1 = d fine, 2 = q coarse, 3 = q fine.
    Burst(u8),
    /// Waiting for [`Identify::poll`] to choose the next burst's half period.
    AwaitPoll(u8),
    Spin(Seg),
    Finished,
    Done,
}

/// The identification; step it once per control sample from standstill, and call
/// [`Identify::poll`] in the background (after each step on the host).
#[derive(Clone, Debug)]
pub struct Identify {
    pub(super) config: IdentifyConfig,
    pub(super) svpwm: SvpwmConfig,
    pub(super) phase: Phase,
    pub(super) k: u32,
    pub(super) level_bits: [i32; 4],
    pub(super) ramp_step_bits: i32,
    pub(super) i_ref: i32,
    pub(super) trip_bits: i32,
    pub(super) sq_bits: i32,
    pub(super) spin_bits: i32,
    pub(super) spin_v2_bits: i64,
    pub(super) integ: [i64; 2],
    pub(super) saturated: bool,
    pub(super) v_hold: AlphaBeta,
    /// Σ of the resistance loop's α output over a level's settle, `Pu` bits.
    pub(super) v_settle: i64,
    pub(super) levels: [LevelSums; 4],
    pub(super) bursts: [BurstSums; 4],
    pub(super) sign: i32,
    pub(super) in_half: u32,
    pub(super) half_ended: bool,
    pub(super) windows: [WindowSums; 3],
    pub(super) phase_q16: u64,
    pub(super) speed_q16: u64,
    pub(super) omega1_q16: u64,
    pub(super) omega2_q16: u64,
    pub(super) energy: i64,
    /// Running Σ of the squared field step (angle counts per sample)² over the spin.
    pub(super) f_energy: i128,
    pub(super) spin_n: i64,
    pub(super) retries: u32,
    /// Slow mean of the spin's x voltage (`Pu` bits × 2¹²), for the hunting damper.
    pub(super) vx_mean: i64,
    // Background results (f32, off the per-sample path).
    pub(super) r_ohm: f32,
    pub(super) v0_v: f32,
    pub(super) r_rms_v: f32,
    pub(super) inductance_h: [f32; 2],
    pub(super) result: Option<Result<Identified, IdentifyError>>,
    pub(super) reported: bool,
}

pub(super) const Q24: i64 = 1 << 24;

impl Identify {
    /// Ready to start.
    pub fn new(config: IdentifyConfig) -> Self {
        let d = config.design;
        let bits = |x: f64| pu_from_f64(x).to_bits();
        let level_bits = d.levels.map(bits);
        let spin_v = bits(d.spin_voltage_pu) as i64;
        Self {
            config,
            svpwm: SvpwmConfig::default(),
            phase: Phase::Align,
            k: 0,
            // Unsigned, by a non-zero divisor: no division panic path (the levels are
            // positive, validated).
            ramp_step_bits: ((level_bits[0].max(0) as u32 / config.n_ramp.max(1)) as i32).max(1),
            level_bits,
            i_ref: 0,
            trip_bits: bits(d.trip_pu),
            sq_bits: bits(d.square_v_pu),
            spin_bits: bits(d.spin_current_pu),
            spin_v2_bits: spin_v * spin_v,
            integ: [0; 2],
            saturated: false,
            v_hold: AlphaBeta::default(),
            v_settle: 0,
            levels: [LevelSums::default(); 4],
            bursts: [BurstSums::default(); 4],
            sign: 1,
            in_half: 0,
            half_ended: false,
            windows: [WindowSums::default(); 3],
            phase_q16: 0,
            speed_q16: 0,
            omega1_q16: 0,
            omega2_q16: 0,
            energy: 0,
            f_energy: 0,
            spin_n: 0,
            retries: 0,
            vx_mean: 0,
            r_ohm: 0.0,
            v0_v: 0.0,
            r_rms_v: 0.0,
            inductance_h: [0.0; 2],
            result: None,
            reported: false,
        }
    }

    /// The configuration.
    pub fn config(&self) -> &IdentifyConfig {
        &self.config
    }

    /// A commanded speed of [`IdentifyOutput::speed_q16`] in electrical rad/s.
    pub fn speed_rad_s(&self, speed_q16: u64) -> f64 {
        self.config.omega_e(speed_q16)
    }

    fn stage(&self) -> Stage {
        match self.phase {
            Phase::Align | Phase::Level(_) => Stage::Resistance,
            Phase::Burst(b) | Phase::AwaitPoll(b) if b < 2 => Stage::InductanceD,
            Phase::Burst(_) | Phase::AwaitPoll(_) => Stage::InductanceQ,
            Phase::Spin(Seg::Down | Seg::Up) => Stage::Inertia,
            Phase::Spin(_) => Stage::Flux,
            Phase::Finished | Phase::Done => match self.result {
                Some(Err(e)) => e.stage(),
                _ => Stage::Inertia,
            },
        }
    }

    fn idle(&self) -> IdentifyOutput {
        IdentifyOutput {
            duties: Duties::HALF,
            v: AlphaBeta::default(),
            pwm_on: false,
            stage: self.stage(),
            speed_q16: 0,
            finished: true,
        }
    }

    fn fail(&mut self, e: IdentifyError) -> IdentifyOutput {
        self.result = Some(Err(e));
        self.phase = Phase::Done;
        self.idle()
    }

    /// The current loop: PI on the error (frame of the caller), integrator frozen while the
    /// modulator saturates. `Pu` bits in, `Pu` out.
    pub(super) fn pi(&mut self, err: [i32; 2]) -> Dq {
        let c = &self.config;
        let mut out = [0i32; 2];
        for (k, e) in err.iter().enumerate() {
            let e = *e as i64;
            let integ = self.integ.get(k).copied().unwrap_or(0);
            let integ = if self.saturated {
                integ
            } else {
                (integ + c.ki_q24 * e).clamp(-2 * Q24 * Q24, 2 * Q24 * Q24)
            };
            if let Some(x) = self.integ.get_mut(k) {
                *x = integ;
            }
            if let Some(o) = out.get_mut(k) {
                *o = sat_i32((c.kp_q24 * e + integ) >> 24);
            }
        }
        Dq {
            d: Pu::from_bits(out[0]),
            q: Pu::from_bits(out[1]),
        }
    }

    pub(super) fn hold_integrators(&mut self, v: AlphaBeta) {
        self.integ = [
            (v.alpha.to_bits() as i64) << 24,
            (v.beta.to_bits() as i64) << 24,
        ];
    }

    /// One control sample: `i` the phase currents measured now (αβ, per unit of the current
    /// limit), `vdc` the bus (per unit of `V_b`). Integer only; never panics.
    pub fn step(&mut self, i: AlphaBeta, vdc: Pu) -> IdentifyOutput {
        if matches!(self.phase, Phase::Finished | Phase::Done) {
            return self.idle();
        }
        let ph = inverse_clarke(i);
        let worst =
            ph.a.saturating_abs()
                .max(ph.b.saturating_abs())
                .max(ph.c.saturating_abs());
        if worst.to_bits() > self.trip_bits {
            return self.fail(IdentifyError::OverCurrent(self.stage()));
        }
        let (ia, ib) = (i.alpha.to_bits(), i.beta.to_bits());
        let mut out_angle = Angle::ZERO;
        let v: AlphaBeta = match self.phase {
            Phase::Align => self.align_step(ia),
            Phase::Level(l) => match self.level_step(l, ia, ib) {
                Ok(v) => v,
                Err(e) => return self.fail(e),
            },
            Phase::Burst(b) => self.burst_step(b, ia, ib),
            Phase::AwaitPoll(_) => self.v_hold,
            Phase::Spin(seg) => match self.spin_step(seg, i) {
                Ok((v, angle)) => {
                    out_angle = angle;
                    v
                }
                Err(e) => return self.fail(e),
            },
            Phase::Finished | Phase::Done => return self.idle(),
        };
        let out = self.modulate(v, out_angle, vdc);
        if out.bus_low {
            return self.fail(IdentifyError::BusLow(self.stage()));
        }
        self.saturated = out.saturated;
        let finished = self.phase == Phase::Finished;
        IdentifyOutput {
            duties: out.duties,
            v: out.v,
            pwm_on: !finished,
            stage: self.stage(),
            speed_q16: self.speed_q16,
            finished,
        }
    }

    /// The stage's voltage to duties: the spin's is in the field's frame (x, y at `angle`),
    /// the others' already αβ.
    fn modulate(&self, v: AlphaBeta, angle: Angle, vdc: Pu) -> SvpwmOutput {
        let v_ab = if matches!(self.phase, Phase::Spin(_)) {
            inverse_park(
                Dq {
                    d: v.alpha,
                    q: v.beta,
                },
                angle.sin_cos(),
            )
        } else {
            v
        };
        self.svpwm.modulate(v_ab, vdc)
    }
}
