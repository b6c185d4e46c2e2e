//! The identification's state machine: integer per-sample step, `f64` poll.

use super::fit::{inductance_from_ripple, least_squares_3, line, magnet_flux};
use super::{Identified, IdentifyConfig, IdentifyError, Stage};
use crate::angle::Angle;
use crate::frames::{AlphaBeta, Dq, inverse_clarke, inverse_park, park};
use crate::num::{Pu, pu_from_f64, sat_i32};
use crate::params::MotorParams;
use crate::svpwm::{Duties, SvpwmConfig};

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

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct LevelSums {
    v: i64,
    i: i64,
    beta: i64,
    first: i64,
    second: i64,
    n: u32,
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct BurstSums {
    /// Σ over the ends of halves of `sign · i_axis`, `Pu` bits.
    d: i64,
    halves: u32,
    n_half: u32,
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct WindowSums {
    v: [i64; 2],
    i: [i64; 2],
    /// Σ of the energy `C` over the window.
    c_sum: i64,
    /// Σ of `C` over the first and the second half of the window (their difference over
    /// the half length squared is the mean power, with the hunting averaged out at both ends).
    c_first: i64,
    c_second: i64,
    n: u32,
    /// Σ of the field's actual step (commanded speed with the damper's correction).
    speed_sum: u64,
    speed_n: u32,
    /// Σ over the window of `F`, the running Σ of the squared field step, and of the spin's
    /// sample index.
    f_sum: i128,
    t_sum: i64,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Seg {
    First,
    Hold(u8),
    Down,
    Up,
    Stop,
    Rest,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Phase {
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
    config: IdentifyConfig,
    svpwm: SvpwmConfig,
    phase: Phase,
    k: u32,
    level_bits: [i32; 4],
    ramp_step_bits: i32,
    i_ref: i32,
    trip_bits: i32,
    sq_bits: i32,
    spin_bits: i32,
    spin_v2_bits: i64,
    integ: [i64; 2],
    saturated: bool,
    v_hold: AlphaBeta,
    levels: [LevelSums; 4],
    bursts: [BurstSums; 4],
    sign: i32,
    in_half: u32,
    half_ended: bool,
    windows: [WindowSums; 3],
    phase_q16: u64,
    speed_q16: u64,
    omega1_q16: u64,
    omega2_q16: u64,
    energy: i64,
    /// Running Σ of the squared field step (angle counts per sample)² over the spin.
    f_energy: i128,
    spin_n: i64,
    retries: u32,
    /// Slow mean of the spin's x voltage (`Pu` bits × 2¹²), for the hunting damper.
    vx_mean: i64,
    // Background results (f64, off the per-sample path).
    r_ohm: f64,
    v0_v: f64,
    r_rms_v: f64,
    inductance_h: [f64; 2],
    result: Option<Result<Identified, IdentifyError>>,
    reported: bool,
}

const Q24: i64 = 1 << 24;

/// Windows repeated in all while the rotor still moves at the resistance levels.
const MAX_RETRIES: u32 = 16;

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
            ramp_step_bits: (level_bits[0] / config.n_ramp as i32).max(1),
            level_bits,
            i_ref: 0,
            trip_bits: bits(d.trip_pu),
            sq_bits: bits(d.square_v_pu),
            spin_bits: bits(d.spin_current_pu),
            spin_v2_bits: spin_v * spin_v,
            integ: [0; 2],
            saturated: false,
            v_hold: AlphaBeta::default(),
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
    fn pi(&mut self, err: [i32; 2]) -> Dq {
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

    fn hold_integrators(&mut self, v: AlphaBeta) {
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
            Phase::Align => {
                self.i_ref = (self.i_ref + self.ramp_step_bits).min(self.level_bits[0]);
                self.k += 1;
                if self.k >= self.config.n_ramp {
                    self.k = 0;
                    self.phase = Phase::Level(0);
                }
                let v = self.pi([self.i_ref - ia, -ib]);
                AlphaBeta {
                    alpha: v.d,
                    beta: v.q,
                }
            }
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
        let v_ab = if matches!(self.phase, Phase::Spin(_)) {
            inverse_park(
                Dq {
                    d: v.alpha,
                    q: v.beta,
                },
                out_angle.sin_cos(),
            )
        } else {
            v
        };
        let out = self.svpwm.modulate(v_ab, vdc);
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

    fn level_step(&mut self, l: u8, ia: i32, ib: i32) -> Result<AlphaBeta, IdentifyError> {
        let c = self.config;
        let li = l as usize;
        let r = self.level_bits.get(li).copied().unwrap_or(0);
        let k = self.k;
        self.k += 1;
        if k < c.n_settle {
            // β is regulated to zero too: the rotor may still be turning onto α.
            let v = self.pi([r - ia, -ib]);
            let v = AlphaBeta {
                alpha: v.d,
                beta: v.q,
            };
            self.v_hold = v;
            return Ok(v);
        }
        if k == c.n_settle {
            if 2 * ia < r {
                return Err(IdentifyError::NoCurrent(Stage::Resistance));
            }
            if self.saturated {
                return Err(IdentifyError::Saturation(Stage::Resistance));
            }
            // At standstill the β voltage that keeps β current at zero is zero (the phase
            // currents' signs are symmetric about α); what the loop holds there now only
            // answers the rotor's motion, and holding it would pull the rotor off α.
            self.v_hold.beta = Pu::ZERO;
        }
        let w0 = c.n_settle + c.n_hold;
        if k >= w0 {
            let j = k - w0;
            if let Some(s) = self.levels.get_mut(li) {
                s.v += self.v_hold.alpha.to_bits() as i64;
                s.i += ia as i64;
                s.beta += ib as i64;
                if j < c.n_window / 2 {
                    s.first += ia as i64;
                } else if j < 2 * (c.n_window / 2) {
                    s.second += ia as i64;
                }
                s.n += 1;
            }
            if j + 1 >= c.n_window {
                let s = self.levels.get(li).copied().unwrap_or_default();
                let (n, r) = (s.n as i64, r as i64);
                if 2 * s.i < r * n {
                    return Err(IdentifyError::NoCurrent(Stage::Resistance));
                }
                if 100 * (s.first - s.second).abs() > 2 * r * (c.n_window / 2) as i64
                    || 50 * s.beta.abs() > r * n
                {
                    // Still swinging (the held voltage brakes it through R): measure again,
                    // a bounded number of times.
                    if self.retries >= MAX_RETRIES {
                        return Err(IdentifyError::RotorMoved(Stage::Resistance));
                    }
                    self.retries += 1;
                    if let Some(s) = self.levels.get_mut(li) {
                        *s = LevelSums::default();
                    }
                    self.k = w0;
                    return Ok(self.v_hold);
                }
                self.k = 0;
                self.hold_integrators(self.v_hold);
                self.phase = if l >= 3 {
                    self.start_burst(0, 1);
                    Phase::Burst(0)
                } else {
                    Phase::Level(l + 1)
                };
            }
        }
        Ok(self.v_hold)
    }

    fn start_burst(&mut self, b: u8, n_half: u32) {
        if let Some(s) = self.bursts.get_mut(b as usize) {
            *s = BurstSums {
                n_half: n_half.max(1),
                ..Default::default()
            };
        }
        self.k = 0;
        self.sign = 1;
        self.in_half = 0;
        self.half_ended = false;
    }

    fn burst_step(&mut self, b: u8, ia: i32, ib: i32) -> AlphaBeta {
        let c = self.config;
        let bi = b as usize;
        let along = if b < 2 { ia } else { ib };
        let fine = b % 2 == 1;
        let len = if fine { c.n_window } else { c.n_burst };
        let warm = c.n_hold;
        let Some(s) = self.bursts.get_mut(bi) else {
            return self.v_hold;
        };
        // The current now ends the period commanded last step.
        if self.half_ended {
            if self.k >= warm {
                s.d += -(self.sign as i64) * along as i64;
                s.halves += 1;
            }
            if self.k >= warm + len && s.halves % 2 == 0 && s.halves > 0 {
                self.k = 0;
                self.phase = match b {
                    0 | 2 => Phase::AwaitPoll(b),
                    1 => {
                        self.start_burst(2, 1);
                        Phase::Burst(2)
                    }
                    _ => {
                        self.start_spin();
                        Phase::Spin(Seg::First)
                    }
                };
                return self.v_hold;
            }
        }
        let n_half = s.n_half;
        let sign = self.sign;
        self.in_half += 1;
        self.half_ended = self.in_half >= n_half;
        if self.half_ended {
            self.in_half = 0;
            self.sign = -sign;
        }
        self.k += 1;
        let sq = Pu::from_bits(sign * self.sq_bits);
        let mut v = self.v_hold;
        if b < 2 {
            v.alpha = v.alpha.saturating_add(sq);
        } else {
            v.beta = v.beta.saturating_add(sq);
        }
        v
    }

    fn start_spin(&mut self) {
        self.k = 0;
        self.phase_q16 = 0;
        self.speed_q16 = 0;
        self.energy = 0;
        self.vx_mean = (self.v_hold.alpha.to_bits() as i64) << 12;
        self.hold_integrators(self.v_hold);
    }

    fn spin_step(&mut self, seg: Seg, i: AlphaBeta) -> Result<(AlphaBeta, Angle), IdentifyError> {
        let c = self.config;
        let angle = Angle((self.phase_q16 >> 16) as u32 as i32);
        let ic = park(i, angle.sin_cos());
        let v = self.pi([self.spin_bits - ic.d.to_bits(), -ic.q.to_bits()]);
        if self.saturated && !matches!(seg, Seg::Stop | Seg::Rest) {
            return Err(IdentifyError::Saturation(Stage::Flux));
        }
        let (vx, vy) = (v.d.to_bits() as i64, v.q.to_bits() as i64);
        let (ix, iy) = (ic.d.to_bits() as i64, ic.q.to_bits() as i64);
        // Saturating: a healthy spin is far from the limits (see the module's formats).
        let p = vx.saturating_mul(ix).saturating_add(vy.saturating_mul(iy)) >> 24;
        self.energy = self.energy.saturating_add(p);
        let accel = c.accel_q16;
        let mut w_open = false;
        match seg {
            Seg::First => {
                self.speed_q16 += accel;
                let v2 = vx.saturating_mul(vx).saturating_add(vy.saturating_mul(vy));
                if v2 >= self.spin_v2_bits || self.speed_q16 >= c.max_speed_q16 {
                    self.omega1_q16 = self.speed_q16 & !1;
                    self.omega2_q16 = self.omega1_q16 / 2;
                    self.speed_q16 = self.omega1_q16;
                    self.next_seg(Seg::Hold(0));
                }
            }
            Seg::Hold(h) => {
                let k = self.k;
                w_open = k >= c.n_settle;
                self.k += 1;
                if k >= c.n_settle {
                    let e = self.energy;
                    if let Some(w) = self.windows.get_mut(h as usize) {
                        w.v[0] += vx;
                        w.v[1] += vy;
                        w.i[0] += ix;
                        w.i[1] += iy;
                        w.c_sum = w.c_sum.saturating_add(e);
                        let (j, half) = (k - c.n_settle, c.n_window / 2);
                        if j < half {
                            w.c_first = w.c_first.saturating_add(e);
                        } else if j < 2 * half {
                            w.c_second = w.c_second.saturating_add(e);
                        }
                        w.n += 1;
                    }
                    if k + 1 >= c.n_settle + c.n_window {
                        let next = match h {
                            0 => Seg::Down,
                            1 => Seg::Up,
                            _ => Seg::Stop,
                        };
                        self.next_seg(next);
                    }
                }
            }
            Seg::Down => {
                self.speed_q16 = self.speed_q16.saturating_sub(accel);
                if self.speed_q16 <= self.omega2_q16 {
                    self.speed_q16 = self.omega2_q16;
                    self.next_seg(Seg::Hold(1));
                }
            }
            Seg::Up => {
                self.speed_q16 += accel;
                if self.speed_q16 >= self.omega1_q16 {
                    self.speed_q16 = self.omega1_q16;
                    self.next_seg(Seg::Hold(2));
                }
            }
            Seg::Stop => {
                self.speed_q16 = self.speed_q16.saturating_sub(accel);
                if self.speed_q16 == 0 {
                    self.next_seg(Seg::Rest);
                }
            }
            Seg::Rest => {
                self.k += 1;
                if self.k >= c.n_settle {
                    self.phase = Phase::Finished;
                }
            }
        }
        // Hunting damper: the x voltage carries `ω ψ sin δ`; slowing the field when it rises
        // above its slow mean (the rotor falling behind) damps the load angle's oscillation
        // (`δ'' + c cos δ δ' + (K/J) sin δ = 0`), which open-loop I–f otherwise lacks.
        self.vx_mean += vx - (self.vx_mean >> 12);
        let dv = vx - (self.vx_mean >> 12);
        let corr = c.damp_q24.saturating_mul(dv) >> 24;
        let step = (self.speed_q16 as i64).saturating_sub(corr).max(0) as u64;
        // Output at the middle of the coming period's angle (the vector turns during it).
        let out_angle = Angle((self.phase_q16.wrapping_add(step / 2) >> 16) as u32 as i32);
        self.phase_q16 = self.phase_q16.wrapping_add(step);
        let counts = (step >> 16) as i128;
        self.f_energy = self.f_energy.saturating_add(counts * counts);
        self.spin_n += 1;
        if let Seg::Hold(h) = seg
            && w_open
            && let Some(w) = self.windows.get_mut(h as usize)
        {
            w.speed_sum = w.speed_sum.saturating_add(step);
            w.speed_n += 1;
            w.f_sum = w.f_sum.saturating_add(self.f_energy);
            w.t_sum = w.t_sum.saturating_add(self.spin_n);
        }
        Ok((
            AlphaBeta {
                alpha: v.d,
                beta: v.q,
            },
            out_angle,
        ))
    }

    fn next_seg(&mut self, s: Seg) {
        self.k = 0;
        self.phase = Phase::Spin(s);
    }

    /// Background work: chooses the fine bursts' half periods and, once the sequence has
    /// ended, computes the result. Returns the result once (then `None`).
    pub fn poll(&mut self) -> Option<Result<Identified, IdentifyError>> {
        match self.phase {
            Phase::AwaitPoll(b) => {
                if let Err(e) = self.choose_burst(b) {
                    self.result = Some(Err(e));
                    self.phase = Phase::Done;
                }
                None
            }
            Phase::Finished => {
                self.result = Some(self.finish());
                self.phase = Phase::Done;
                self.report()
            }
            Phase::Done => self.report(),
            _ => None,
        }
    }

    /// What the resistance and inductance steps have measured so far (zero before):
    /// `(R Ω, distortion V, [L_d H, L_q H])`.
    pub fn measured(&self) -> (f64, f64, [f64; 2]) {
        (self.r_ohm, self.v0_v, self.inductance_h)
    }

    fn report(&mut self) -> Option<Result<Identified, IdentifyError>> {
        if self.reported {
            None
        } else {
            self.reported = true;
            self.result
        }
    }

    fn resistance(&mut self) -> Result<(), IdentifyError> {
        let c = self.config;
        let mut pts = [(0.0, 0.0); 4];
        for (p, s) in pts.iter_mut().zip(self.levels.iter()) {
            let n = s.n.max(1) as f64;
            *p = (c.amps(s.i as f64 / n), c.volts(s.v as f64 / n));
        }
        let (r, v0, rms) = line(&pts).ok_or(IdentifyError::Noise(Stage::Resistance))?;
        // The line must explain the points to a small fraction of the voltage span.
        let span = pts[3].1 - pts[0].1;
        if r.is_nan() || r <= 0.0 || rms > 0.05 * span.abs() {
            return Err(IdentifyError::Noise(Stage::Resistance));
        }
        self.r_ohm = r;
        self.v0_v = v0;
        self.r_rms_v = rms;
        Ok(())
    }

    fn burst_inductance(&self, b: u8) -> Result<f64, IdentifyError> {
        let c = self.config;
        let stage = if b < 2 {
            Stage::InductanceD
        } else {
            Stage::InductanceQ
        };
        let s = self.bursts.get(b as usize).copied().unwrap_or_default();
        let periods = (s.halves / 2).max(1) as f64;
        let d_a = c.amps(s.d as f64 / periods);
        let v_sq = c.volts(self.sq_bits as f64);
        if d_a < 2e-3 * c.current_base_a {
            return Err(IdentifyError::Noise(stage));
        }
        inductance_from_ripple(d_a, v_sq, s.n_half, c.sample_s, self.r_ohm)
            .ok_or(IdentifyError::Noise(stage))
    }

    fn choose_burst(&mut self, b: u8) -> Result<(), IdentifyError> {
        if b == 0 {
            self.resistance()?;
        }
        let c = self.config;
        let l = self.burst_inductance(b)?;
        // D ≈ V_sq N T / L: the N for the wanted ripple, at least 1, at most 1/4 of a window.
        let v_sq = c.volts(self.sq_bits as f64);
        let want = c.design.ripple_pu * c.current_base_a;
        let n = libm::round(want * l / (v_sq * c.sample_s)).clamp(1.0, (c.n_window / 8) as f64);
        self.start_burst(b + 1, n as u32);
        self.phase = Phase::Burst(b + 1);
        Ok(())
    }

    fn finish(&mut self) -> Result<Identified, IdentifyError> {
        let c = self.config;
        let ld = self.burst_inductance(1)?;
        self.inductance_h[0] = ld;
        let lq = self.burst_inductance(3)?;
        self.inductance_h[1] = lq;
        let p = c.pole_pairs as f64;
        let w = self.windows;
        let mean = |s: &WindowSums, k: usize| -> (f64, f64) {
            let n = s.n.max(1) as f64;
            (
                c.volts(s.v.get(k).copied().unwrap_or(0) as f64 / n),
                c.amps(s.i.get(k).copied().unwrap_or(0) as f64 / n),
            )
        };
        // u = v − R i in the current's frame, against ω.
        let mut ux = [(0.0, 0.0); 3];
        let mut uy = [(0.0, 0.0); 3];
        let speed = |s: &WindowSums| c.omega_e(s.speed_sum) / s.speed_n.max(1) as f64;
        let mut i_f = 0.0;
        for ((s, x), y) in w.iter().zip(ux.iter_mut()).zip(uy.iter_mut()) {
            let om = speed(s);
            let (vx, ix) = mean(s, 0);
            let (vy, iy) = mean(s, 1);
            *x = (om, vx - self.r_ohm * ix);
            *y = (om, vy - self.r_ohm * iy);
            i_f += ix / 3.0;
        }
        let (ax, bx, _) = line(&ux).ok_or(IdentifyError::Noise(Stage::Flux))?;
        let (ay, by, _) = line(&uy).ok_or(IdentifyError::Noise(Stage::Flux))?;
        // u = jω ψ_c + v_off: u_x = −ω ψ_c,y, u_y = ω ψ_c,x.
        let psi_c = (ay, -ax);
        let (psi, delta) = magnet_flux(psi_c, i_f, ld, lq);
        if psi.is_nan() || psi <= 0.0 || !psi.is_finite() {
            return Err(IdentifyError::Noise(Stage::Flux));
        }
        // A rotor that did not turn leaves only the inductive voltage: no EMF worth the name
        // (below 5 % of the voltage the first ramp aimed at).
        let w_top = ux.iter().fold(0.0f64, |m, x| m.max(x.0));
        if psi * w_top < 0.05 * c.design.spin_voltage_pu * c.voltage_base_v {
            return Err(IdentifyError::RotorMoved(Stage::Flux));
        }
        // Each window on its own (offset from the fit) must agree: a rotor that slipped
        // out of the rotating field shows a much smaller flux at one speed.
        for (x, y) in ux.iter().zip(uy.iter()) {
            let om = x.0;
            let pc = ((y.1 - by) / om, -(x.1 - bx) / om);
            let (pk, _) = magnet_flux(pc, i_f, ld, lq);
            let dev = libm::fabs(pk / psi - 1.0);
            if dev.is_nan() || dev >= 0.1 {
                return Err(IdentifyError::RotorMoved(Stage::Flux));
            }
        }
        // Energy: C in Pu bits of (v·i) per sample → joules.
        let joules = 1.5 * c.voltage_base_v * c.current_base_a * c.sample_s / Q24 as f64;
        let cbar = |s: &WindowSums| s.c_sum as f64 / s.n.max(1) as f64 * joules;
        let power = |s: &WindowSums| {
            let half = (c.n_window / 2).max(1) as f64;
            (s.c_second - s.c_first) as f64 / (half * half) * joules / c.sample_s
        };
        // J, B and the losses from the energy between the windows' centres and the windows'
        // mean powers: E = J ΔK + B ΔF + P_loss Δt, P = B ω_m² + P_loss (least squares).
        let rad = core::f64::consts::TAU / 4_294_967_296.0 / c.sample_s / p;
        let f_bar =
            |s: &WindowSums| s.f_sum as f64 / s.speed_n.max(1) as f64 * rad * rad * c.sample_s;
        let t_bar = |s: &WindowSums| s.t_sum as f64 / s.speed_n.max(1) as f64 * c.sample_s;
        let wm = |s: &WindowSums| speed(s) / p;
        let kin = |s: &WindowSums| 0.5 * wm(s) * wm(s);
        let [h1a, h2, h1b] = w;
        let w1 = 0.5 * (wm(&h1a) + wm(&h1b));
        let w2 = wm(&h2);
        if w1.is_nan() || w1 <= w2 {
            return Err(IdentifyError::Noise(Stage::Inertia));
        }
        let step_row = |a: &WindowSums, b: &WindowSums| {
            (
                [kin(b) - kin(a), f_bar(b) - f_bar(a), t_bar(b) - t_bar(a)],
                cbar(b) - cbar(a),
            )
        };
        let power_row = |s: &WindowSums| ([0.0, wm(s) * wm(s), 1.0], power(s));
        let rows = [
            step_row(&h1a, &h2),
            step_row(&h2, &h1b),
            power_row(&h1a),
            power_row(&h2),
            power_row(&h1b),
        ];
        let [j, b, _loss] = least_squares_3(&rows).ok_or(IdentifyError::Noise(Stage::Inertia))?;
        let b = b.max(0.0);
        if j.is_nan() || j <= 0.0 || !j.is_finite() {
            return Err(IdentifyError::Noise(Stage::Inertia));
        }
        let motor = MotorParams::new(c.pole_pairs, self.r_ohm, ld, lq, psi, j, b);
        motor
            .validate()
            .map_err(|_| IdentifyError::Noise(Stage::Inertia))?;
        Ok(Identified {
            motor,
            distortion_v: self.v0_v,
            resistance_residual_v: self.r_rms_v,
            load_angle_rad: delta,
            spin_speeds_rad_s: [w1 * p, w2 * p],
        })
    }
}
