//! On-line learning of the inverter's distortion voltage while running (docs/distortion.md):
//! off the control path like [`super::Tracker`], in the drive's task (design key
//! `deadtime_learning`), it reads the interrupt side's window at each task period and
//! rescales the dead-time compensation's `V_dead` ([`Drive::set_deadtime_scale`]) to the one
//! the inverter shows.
//!
//! # Measurement
//!
//! The inverter takes `V_true P` from every command, `P` the Clarke transform of the phase
//! currents' signs (a hexagon of length 4/3); the compensation adds back `V_c P` (`V_c` the
//! told `V_dead` times the scale in use). What the current loops put out, which is what the
//! estimator is given, is therefore
//!
//! ```text
//! u = R i + L di/dt + ω J L i + e_ω + e P,     e = V_true − V_c
//! ```
//!
//! In the rotor frame `P` is a constant plus a ripple at six times the electrical angle (the
//! sector steps), which nothing else in a sinusoidal motor carries. Demodulated at `6θ̂` over
//! a batch, with the means taken out, the voltage's and the current's ripple phasors `U`, `I`
//! and the pattern's `P₆` obey, per axis,
//!
//! ```text
//! U_d − (R + j6ωL_d) I_d + ω L_q I_q = e P₆d
//! U_q − (R + j6ωL_q) I_q − ω L_d I_d = e P₆q
//! ```
//!
//! and `ê` is their least-squares solution. The current loops share the ripple between `U`
//! (below their bandwidth) and `I` (above it); the impedance puts the two together, so the
//! estimate holds at any speed the decimated sampling resolves. A wrong `R` or `L` changes the
//! estimate's gain, not its zero: with `e = 0` there is no ripple at all (apart from the
//! fading of the sign near zero current, hence the current gate).
//!
//! # Update
//!
//! At the end of each batch the scale moves by [`DistortionDesign::gain`] times `ê` over the
//! told `V_dead`, within [`DistortionDesign::scale_range`], and is written to the drive when
//! it moved by more than [`DistortionDesign::write_threshold`]; one batch moves it by at most
//! [`DistortionDesign::max_step`]. The batch is thrown away when the speed or the current
//! reference's length moved by more than [`DistortionDesign::max_speed_change`] of its mean
//! in it.
//! Gates (the sample is skipped): outside `Run`, [`DistortionDesign::settle_s`] after
//! entering it, below [`DistortionDesign::min_speed_rad_s`] (too few sector steps per batch)
//! or where the sixth harmonic turns by more than a quarter turn between two updates, with
//! the current within [`DistortionDesign::min_current_bands`] of the compensation's band, or
//! the modulator or a current loop at its limit.
//!
//! # Cost
//!
//! `f32`, about 70 operations per [`DistortionLearner::update`] (one sin/cos), a few more at
//! the end of a batch.

use super::tracking::{pu, sin_cos_f32};
use super::{Drive, DriveConfig, TrackerInput};
use crate::error::ConfigError;
use crate::num::{Pu, pu_from_f64};
use crate::params::{MotorParams, ParamError, ParamReason, in_range};

/// How the learner is designed, SI units; [`DistortionDesign::for_drive`] gives the defaults.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DistortionDesign {
    /// Control samples between two calls of [`DistortionLearner::update`].
    pub interval_samples: u32,
    /// Length of a batch, s.
    pub batch_s: f64,
    /// Least electrical speed at which the learner listens, rad/s.
    pub min_speed_rad_s: f64,
    /// Time in `Run` before the learner listens, s.
    pub settle_s: f64,
    /// The current's length must exceed this many times the compensation's current band.
    pub min_current_bands: f64,
    /// A batch in which the speed, or the current reference's length (the mean of its second
    /// half against its first), moved by more than this fraction of its mean is discarded (a ramp, a load step: a step inside a batch
    /// leaks into the demodulation).
    pub max_speed_change: f64,
    /// Largest change of the scale per batch.
    pub max_step: f64,
    /// Fraction of the measured error taken at each batch (0–1].
    pub gain: f64,
    /// The scale is kept within this range.
    pub scale_range: (f64, f64),
    /// Smallest change of the scale written to the drive.
    pub write_threshold: f64,
    /// The compensation's `V_dead` at the nominal bus, V (what the drive was told).
    pub v_dead_v: f64,
    /// The compensation's current band, A.
    pub band_a: f64,
}

impl DistortionDesign {
    /// For `config`'s dead-time compensation: an update every task period, batches of
    /// 0.2 s, from three electrical turns per batch up, 50 ms after entering `Run`, the
    /// current beyond ten bands, the speed and the current reference within 10 %, three
    /// quarters of the error per batch and at most a quarter, the scale within [0.25, 4], written when it
    /// moved by 3 % (the standstill calibration's dead band).
    pub fn for_drive(config: &DriveConfig) -> Self {
        let batch_s = 0.2;
        let dt = config.deadtime();
        Self {
            interval_samples: super::TASK_PERIOD,
            batch_s,
            min_speed_rad_s: 3.0 * core::f64::consts::TAU / batch_s,
            settle_s: 0.05,
            min_current_bands: 10.0,
            max_speed_change: 0.1,
            max_step: 0.25,
            gain: 0.75,
            scale_range: (0.25, 4.0),
            write_threshold: 0.03,
            v_dead_v: if config.deadtime_compensation() {
                dt.v_dead_nominal_v
            } else {
                0.0
            },
            band_a: dt.design.band_a,
        }
    }
}

/// Why the last update did not listen.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum DistortionFrozen {
    /// Not in `Run`.
    #[default]
    NotRunning,
    /// Within [`DistortionDesign::settle_s`] of entering `Run`.
    Settling,
    /// Below [`DistortionDesign::min_speed_rad_s`], or too fast for the update rate.
    Speed,
    /// The current within [`DistortionDesign::min_current_bands`] bands of zero.
    LowCurrent,
    /// The modulator or a current loop at its limit.
    Saturated,
}

/// What the learner did at its last update, and where its estimate is.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DistortionStatus {
    /// The last update was accumulated.
    pub listening: bool,
    /// Why not (meaningless when `listening`).
    pub frozen: DistortionFrozen,
    /// Batches completed and used.
    pub batches: u32,
    /// Batches discarded (the speed moved).
    pub discarded: u32,
    /// The last batch's `ê = V_true − V_c`, V at the nominal bus's scale.
    pub error_v: f32,
    /// The scale the learner holds (of the told `V_dead`): its own, or the drive's when that
    /// changed since the last write.
    pub scale: f32,
}

/// The sums of one batch: for each of `u_d, u_q, i_d, i_q, p_d, p_q`, its sum and its sums
/// against `cos 6θ`, `sin 6θ`.
#[derive(Clone, Copy, Debug, Default)]
struct Batch {
    n: u32,
    sum: [f32; 6],
    cos: [f32; 6],
    sin: [f32; 6],
    sum_c: f32,
    sum_s: f32,
    sum_w: f32,
    w_min: f32,
    w_max: f32,
    /// The current reference's length summed over the batch's first and second halves (its
    /// ripple averages out, a step does not).
    sum_i: [f32; 2],
    half: [u32; 2],
}

/// A complex number, `(re, im)`.
type C = (f32, f32);

fn mul(a: C, b: C) -> C {
    (a.0 * b.0 - a.1 * b.1, a.0 * b.1 + a.1 * b.0)
}

impl Batch {
    fn add(&mut self, x: &[f32; 6], c6: f32, s6: f32, w: f32, i_ref: f32, second: bool) {
        if self.n == 0 {
            (self.w_min, self.w_max) = (w, w);
        }
        let k = usize::from(second);
        if let (Some(sum), Some(half)) = (self.sum_i.get_mut(k), self.half.get_mut(k)) {
            *sum += i_ref;
            *half += 1;
        }
        self.n += 1;
        let sums = self.sum.iter_mut().zip(&mut self.cos).zip(&mut self.sin);
        for (((sum, cos), sin), &x) in sums.zip(x) {
            *sum += x;
            *cos += x * c6;
            *sin += x * s6;
        }
        self.sum_c += c6;
        self.sum_s += s6;
        self.sum_w += w;
        self.w_min = self.w_min.min(w);
        self.w_max = self.w_max.max(w);
    }

    /// The signals' phasors at `6θ` (`x ≈ mean + Re(X e^{j6θ})`), their means removed.
    fn phasors(&self) -> [C; 6] {
        let n = self.n as f32;
        let mut out = [(0.0, 0.0); 6];
        let sums = self.sum.iter().zip(&self.cos).zip(&self.sin);
        for (o, ((&sum, &cos), &sin)) in out.iter_mut().zip(sums) {
            let mean = sum / n;
            *o = (
                2.0 * (cos - mean * self.sum_c) / n,
                -2.0 * (sin - mean * self.sum_s) / n,
            );
        }
        out
    }
}

/// The least-squares `e` of one batch: the pattern's phasors `p` against the residual of the
/// voltage's `u` after the motor's impedance at six times the speed `w` takes the current's
/// `i` (all per unit, `r`, `ld`, `lq` the model's): docs/distortion.md.
fn batch_error(u: [C; 2], i: [C; 2], p: [C; 2], w: f32, r: f32, ld: f32, lq: f32) -> Option<f32> {
    let zd = (r, 6.0 * w * ld);
    let zq = (r, 6.0 * w * lq);
    let rd = mul(zd, i[0]);
    let rq = mul(zq, i[1]);
    let res = [
        (
            u[0].0 - rd.0 + w * lq * i[1].0,
            u[0].1 - rd.1 + w * lq * i[1].1,
        ),
        (
            u[1].0 - rq.0 - w * ld * i[0].0,
            u[1].1 - rq.1 - w * ld * i[0].1,
        ),
    ];
    let num = p[0].0 * res[0].0 + p[0].1 * res[0].1 + p[1].0 * res[1].0 + p[1].1 * res[1].1;
    let den = p[0].0 * p[0].0 + p[0].1 * p[0].1 + p[1].0 * p[1].0 + p[1].1 * p[1].1;
    (den > 0.0).then(|| num / den)
}

/// The learner: design in per unit, a batch's sums and the scale (`f32`).
#[derive(Clone, Copy, Debug)]
pub struct DistortionLearner {
    design: DistortionDesign,
    r: f32,
    ld: f32,
    lq: f32,
    /// Told `V_dead` per unit; the band per unit; electrical angle per update per unit speed.
    v_dead: f32,
    band: f32,
    min_speed: f32,
    max_speed: f32,
    batch_updates: u32,
    settle_updates: u32,
    run_updates: u32,
    batch: Batch,
    /// The scale last written (or read from the drive); the one held is the status's.
    written: f32,
    status: DistortionStatus,
}

/// The Clarke transform of the phase currents' signs (amplitude-invariant, length 4/3 between
/// sector steps), the sign linear within `band` as the compensation's is, from the current
/// `(i_α, i_β)`.
fn sign_pattern(ia: f32, ib: f32, band: f32) -> (f32, f32) {
    const SQRT_3: f32 = 1.732_050_8;
    let h = 0.5 * SQRT_3;
    let sg = |x: f32| (x / band).clamp(-1.0, 1.0);
    let (sa, sb, sc) = (sg(ia), sg(-0.5 * ia + h * ib), sg(-0.5 * ia - h * ib));
    (
        (2.0 / 3.0) * (sa - 0.5 * (sb + sc)),
        (sb - sc) * (1.0 / SQRT_3),
    )
}

impl DistortionLearner {
    /// The learner of a drive built from `motor` (its model of the motor) with `config`.
    ///
    /// Errors: [`ConfigError::Param`] naming the `distortion.*` field out of its range
    /// (`distortion.v_dead_v` zero: the drive does not compensate, there is nothing to scale).
    pub fn new(
        motor: &MotorParams,
        config: &DriveConfig,
        design: DistortionDesign,
    ) -> Result<Self, ConfigError> {
        motor.validate()?;
        let base = &config.base;
        let d = design;
        in_range(
            "distortion.interval_samples",
            d.interval_samples as f64,
            1.0,
            1e4,
        )?;
        let dt = d.interval_samples as f64 * base.sample_s;
        in_range("distortion.batch_s", d.batch_s, 10.0 * dt, 100.0)?;
        in_range(
            "distortion.min_speed_rad_s",
            d.min_speed_rad_s,
            0.0,
            4.0 * base.omega_e_rad_s,
        )?;
        in_range("distortion.settle_s", d.settle_s, 0.0, 100.0)?;
        in_range(
            "distortion.min_current_bands",
            d.min_current_bands,
            0.0,
            1e3,
        )?;
        in_range("distortion.max_speed_change", d.max_speed_change, 0.0, 10.0)?;
        in_range("distortion.gain", d.gain, 1e-3, 1.0)?;
        in_range("distortion.max_step", d.max_step, 1e-3, 4.0)?;
        in_range("distortion.scale_range.0", d.scale_range.0, 0.0, 1.0)?;
        in_range("distortion.scale_range.1", d.scale_range.1, 1.0, 4.0)?;
        in_range("distortion.write_threshold", d.write_threshold, 0.0, 1.0)?;
        in_range("distortion.band_a", d.band_a, 1e-9, 1e6)?;
        if d.v_dead_v.is_nan() || d.v_dead_v <= 0.0 {
            return Err(ParamError {
                key: "distortion.v_dead_v",
                reason: ParamReason::NotPositive,
            }
            .into());
        }
        let turn = base.omega_e_rad_s * dt;
        Ok(Self {
            design,
            r: (motor.rs_ohm / base.impedance_ohm) as f32,
            ld: (motor.ld_h / base.inductance_h) as f32,
            lq: (motor.lq_h / base.inductance_h) as f32,
            v_dead: (d.v_dead_v / base.voltage_v) as f32,
            band: (d.band_a / base.current_a) as f32,
            min_speed: (d.min_speed_rad_s / base.omega_e_rad_s) as f32,
            // The sixth harmonic turns at most a quarter turn per update.
            max_speed: (core::f64::consts::FRAC_PI_2 / (6.0 * turn)) as f32,
            batch_updates: libm::ceil(d.batch_s / dt) as u32,
            settle_updates: libm::ceil(d.settle_s / dt) as u32,
            run_updates: 0,
            batch: Batch::default(),
            written: 1.0,
            status: DistortionStatus {
                scale: 1.0,
                ..DistortionStatus::default()
            },
        })
    }

    /// The design.
    pub fn design(&self) -> &DistortionDesign {
        &self.design
    }

    /// The status of the last update.
    pub fn status(&self) -> DistortionStatus {
        self.status
    }

    /// One update on what a step left (every [`DistortionDesign::interval_samples`] samples).
    /// `scale` is the drive's ([`Drive::deadtime_scale`]): a standstill calibration since the
    /// last write is taken as it is. Returns the scale to write to the drive, when it moved.
    pub fn update(&mut self, input: &TrackerInput, scale: Pu) -> Option<Pu> {
        let drive_scale = pu(scale);
        if libm::fabsf(drive_scale - self.written) > 1e-6 {
            (self.status.scale, self.written) = (drive_scale, drive_scale);
        }
        self.listen(input);
        if self.batch.n < self.batch_updates {
            return None;
        }
        self.finish_batch();
        let scale = self.status.scale;
        let step = libm::fabsf(scale - self.written);
        if step > self.design.write_threshold as f32 {
            self.written = scale;
            return Some(pu_from_f64(f64::from(scale)));
        }
        None
    }

    /// Samples `drive`, updates, and writes a new scale when it moved: a learner of one's
    /// own beside a host [`Drive`] (the drive's task runs its own when the design asks).
    pub fn run(&mut self, drive: &mut Drive) {
        if let Some(s) = self.update(&TrackerInput::sample(drive), drive.deadtime_scale()) {
            drive.set_deadtime_scale(s);
        }
    }

    /// The gates, and the sample's terms added to the batch.
    fn listen(&mut self, input: &TrackerInput) {
        self.status.listening = false;
        if !input.running {
            self.run_updates = 0;
            self.batch = Batch::default();
            self.status.frozen = DistortionFrozen::NotRunning;
            return;
        }
        self.run_updates = self.run_updates.saturating_add(1);
        let w = pu(input.omega);
        let (id, iq) = (pu(input.i_dq.d), pu(input.i_dq.q));
        let frozen = if self.run_updates <= self.settle_updates {
            Some(DistortionFrozen::Settling)
        } else if !(self.min_speed..=self.max_speed).contains(&libm::fabsf(w)) {
            Some(DistortionFrozen::Speed)
        } else if libm::sqrtf(id * id + iq * iq) < self.design.min_current_bands as f32 * self.band
        {
            Some(DistortionFrozen::LowCurrent)
        } else if input.saturated {
            Some(DistortionFrozen::Saturated)
        } else {
            None
        };
        if let Some(f) = frozen {
            self.status.frozen = f;
            return;
        }
        let (s, c) = sin_cos_f32(input.theta);
        // cos 6θ, sin 6θ by three complex products.
        let z2 = mul((c, s), (c, s));
        let z3 = mul(z2, (c, s));
        let z6 = mul(z3, z3);
        let (ua, ub) = (pu(input.v.alpha), pu(input.v.beta));
        let (ud, uq) = (ua * c + ub * s, ub * c - ua * s);
        let (ia, ib) = (id * c - iq * s, id * s + iq * c);
        let (pa, pb) = sign_pattern(ia, ib, self.band);
        let (pd, pq) = (pa * c + pb * s, pb * c - pa * s);
        let (rd, rq) = (pu(input.i_ref.d), pu(input.i_ref.q));
        let i_ref = libm::sqrtf(rd * rd + rq * rq);
        let second = 2 * self.batch.n >= self.batch_updates;
        self.batch
            .add(&[ud, uq, id, iq, pd, pq], z6.0, z6.1, w, i_ref, second);
        self.status.listening = true;
    }

    /// The batch's error, the scale's step, a fresh batch.
    fn finish_batch(&mut self) {
        let b = self.batch;
        self.batch = Batch::default();
        let n = b.n as f32;
        let w = b.sum_w / n;
        let change = self.design.max_speed_change as f32;
        let [a, c] = b.sum_i;
        let [na, nc] = b.half;
        let (ia, ic) = (a / na.max(1) as f32, c / nc.max(1) as f32);
        if b.w_max - b.w_min > change * libm::fabsf(w)
            || libm::fabsf(ic - ia) > change * 0.5 * (ia + ic)
        {
            self.status.discarded = self.status.discarded.saturating_add(1);
            return;
        }
        let [ud, uq, id, iq, pd, pq] = b.phasors();
        let Some(e) = batch_error([ud, uq], [id, iq], [pd, pq], w, self.r, self.ld, self.lq) else {
            return;
        };
        let (lo, hi) = self.design.scale_range;
        let max = self.design.max_step as f32;
        let step = (self.design.gain as f32 * e / self.v_dead)
            .max(-max)
            .min(max);
        self.status.scale = (self.status.scale + step).max(lo as f32).min(hi as f32);
        self.status.batches = self.status.batches.saturating_add(1);
        self.status.error_v = e / self.v_dead * self.design.v_dead_v as f32;
    }
}

#[cfg(test)]
mod tests;
