//! Drives in a closed loop with a simple plant, run alike on the host and on the target: the
//! benchmarks of the drive's two steps on motors outside motor B's envelope, and the check
//! that the target computes the host's bits over the whole loop.
//!
//! The plant ([`DqPlant`]) is `f32` with IEEE basic operations only (no fused multiply–adds,
//! no `libm`), so that the host's x86-64, the Cortex-M4's FPU and the Cortex-M0's soft float
//! give the same bits. [`closed_loop`] folds every step's output into a digest; the host
//! writes the digests ([`digest_file`]) and the firmware compares its own with them.
//!
//! The motors of [`LOOP_MOTORS`] are two of `examples/published/motors.toml`, chosen for
//! where they take the drive beyond motor B: the inductance (a drone outrunner, 17.6 µH, one
//! sample at full voltage moves 1.4 times the base current) and the pole pairs (a legged
//! robot's actuator, 21 pole pairs at 40 kHz). Each runs with the drive's defaults for the
//! motor (its estimator, its gains), as a user gets them.

use pmsm_core::{AlphaBeta, Angle, ConfigError, Drive, DriveConfig, DriveDesign, DriveInput};
use pmsm_core::{DriveOutput, EstimatorKind, InverterParams, MotorParams, PerUnit, Pu};
use pmsm_core::{StartupMode, inverse_clarke};

/// A motor's constants for [`DqPlant`]: `(R Ω, L_d H, L_q H, ψ Wb, J kg m², B N m s, p)`.
pub type Constants = (f32, f32, f32, f32, f32, f32, f32);

/// A motor as a plant: the dq model (linear magnetics, `T_e = 1.5 p (ψ i_q + (L_d − L_q) i_d
/// i_q)`, `J ω̇ = T_e − B ω`) in `f32`, one Euler step per sample, the rotor angle an
/// [`Angle`] (the core's sine table: no `f32` trigonometry to link), the commanded voltage
/// applied as is (an ideal inverter). Unmeasured; it only has to lead the code through its
/// stages as a motor would.
#[derive(Clone, Copy, Debug)]
pub struct DqPlant {
    /// See [`Constants`].
    pub motor: Constants,
    /// Electrical angle of the rotor.
    pub theta: Angle,
    /// Electrical speed, rad/s.
    pub omega_e_rad_s: f32,
    /// Currents in the rotor frame, A.
    pub id_a: f32,
    pub iq_a: f32,
    /// Volts per unit of the drive's voltage, amperes per unit of its current.
    pub vb_v: f32,
    pub ib_a: f32,
}

impl DqPlant {
    /// The motor `motor` at rest at `theta`, no current, on the bases `vb_v`, `ib_a`.
    pub fn at_rest(motor: Constants, theta: Angle, vb_v: f32, ib_a: f32) -> Self {
        Self {
            motor,
            theta,
            omega_e_rad_s: 0.0,
            id_a: 0.0,
            iq_a: 0.0,
            vb_v,
            ib_a,
        }
    }

    /// One sample of `t_s` under the αβ voltage `v` (per unit); returns the αβ currents (per
    /// unit) the ADC reads at the end of it.
    pub fn step(&mut self, v: AlphaBeta, pwm_on: bool, t_s: f32) -> AlphaBeta {
        let (r, ld, lq, psi, j, b, p) = self.motor;
        let q30 = (1u32 << 30) as f32;
        let q24 = (1u32 << 24) as f32;
        let unit = |a: Angle| {
            let sc = a.sin_cos();
            (sc.sin.to_bits() as f32 / q30, sc.cos.to_bits() as f32 / q30)
        };
        let per_rad = 4_294_967_296.0 / core::f32::consts::TAU;
        let w = self.omega_e_rad_s;
        if pwm_on {
            // The voltage in the frame of the rotor's mean angle over the sample (at 10 to 20
            // samples per electrical period, the angle at its start puts the voltage a
            // twentieth of a turn off).
            let mid = self.theta + Angle((w * t_s * 0.5 * per_rad) as i64 as i32);
            let (s, c) = unit(mid);
            let va = v.alpha.to_bits() as f32 / q24 * self.vb_v;
            let vb = v.beta.to_bits() as f32 / q24 * self.vb_v;
            let (vd, vq) = (c * va + s * vb, -s * va + c * vb);
            let did = (vd - r * self.id_a + w * lq * self.iq_a) / ld;
            let diq = (vq - r * self.iq_a - w * ld * self.id_a - w * psi) / lq;
            self.id_a += did * t_s;
            self.iq_a += diq * t_s;
        } else {
            // Outputs off: the currents die out through the diodes within a sample or two.
            self.id_a = 0.0;
            self.iq_a = 0.0;
        }
        let te = 1.5 * p * (psi * self.iq_a + (ld - lq) * self.id_a * self.iq_a);
        let w_m = w / p;
        self.omega_e_rad_s += (te - b * w_m) / j * t_s * p;
        self.theta = self.theta + Angle((self.omega_e_rad_s * t_s * per_rad) as i64 as i32);
        // The currents the ADC reads at the end of the sample, in the frame of the rotor then.
        let (s, c) = unit(self.theta);
        let (ia, ib) = (c * self.id_a - s * self.iq_a, s * self.id_a + c * self.iq_a);
        AlphaBeta {
            alpha: Pu::from_bits((ia / self.ib_a * q24) as i32),
            beta: Pu::from_bits((ib / self.ib_a * q24) as i32),
        }
    }
}

/// How a closed loop ended.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LoopEnd {
    /// FNV-1a over every step's output words: duties, `pwm_on`, `θ̂`, `ω̂`, the voltage the
    /// estimator is given and the plant's currents.
    pub digest: u32,
    /// The last estimate's angle less the rotor's at that sample, and the rotor's electrical
    /// speed, rad/s.
    pub error: Angle,
    pub omega_e_rad_s: f32,
    /// The drive's state ([`pmsm_core::DriveState::code`]).
    pub state: u8,
}

/// FNV-1a's offset basis and prime.
const FNV_BASIS: u32 = 0x811c_9dc5;
const FNV_PRIME: u32 = 0x0100_0193;

fn fold(mut h: u32, words: &[i32]) -> u32 {
    for w in words {
        for b in w.to_le_bytes() {
            h = (h ^ u32::from(b)).wrapping_mul(FNV_PRIME);
        }
    }
    h
}

/// `samples` steps of the started drive `d` against `plant` on the bus `vdc` (per unit),
/// `t_s` apart; `speed_ref(k)` sets the reference before step `k` when it gives one, and
/// `step` runs the drive's sample (the firmware's measures its two sides).
pub fn closed_loop(
    d: &mut Drive,
    plant: &mut DqPlant,
    vdc: Pu,
    t_s: f32,
    samples: u32,
    speed_ref: &dyn Fn(u32) -> Option<Pu>,
    step: &mut dyn FnMut(&mut Drive, &DriveInput) -> DriveOutput,
) -> LoopEnd {
    let mut digest = FNV_BASIS;
    let mut i = AlphaBeta::default();
    // The rotor's angle at the last sample (the instant the drive's estimate is for).
    let mut sampled = plant.theta;
    for k in 0..samples {
        if let Some(w) = speed_ref(k) {
            d.set_speed_ref(w);
        }
        let x = DriveInput {
            i_abc: inverse_clarke(i),
            vdc,
        };
        let out = step(d, &x);
        let v = d.estimator_voltage();
        sampled = plant.theta;
        i = plant.step(v, d.state() != pmsm_core::DriveState::Idle, t_s);
        let e = d.telemetry().estimate;
        digest = fold(
            digest,
            &[
                out.duties.a.to_bits(),
                out.duties.b.to_bits(),
                out.duties.c.to_bits(),
                i32::from(out.pwm_on),
                e.theta.0,
                e.omega.to_bits(),
                v.alpha.to_bits(),
                v.beta.to_bits(),
                i.alpha.to_bits(),
                i.beta.to_bits(),
            ],
        );
    }
    LoopEnd {
        digest,
        error: d.telemetry().estimate.theta - sampled,
        omega_e_rad_s: plant.omega_e_rad_s,
        state: d.state().code(),
    }
}

/// A published motor and its inverter, driven to a fraction of its rated speed.
#[derive(Clone, Copy, Debug)]
pub struct LoopMotor {
    /// Name in the reports (`isr_<name>`, `task_<name>`, `loop_<name>`).
    pub name: &'static str,
    pub motor: MotorParams,
    pub inverter: InverterParams,
    /// The speed reference, a fraction of the rated speed.
    pub speed_frac: f64,
}

/// Steps of each loop of [`LOOP_MOTORS`]: the start, the open loop, the handover and the
/// closed loop at the speed.
pub const LOOP_SAMPLES: u32 = 8000;

/// An inverter at `vdc_v`, `pwm_hz`, `dead_time_s`, its current full scale four base currents
/// of `motor` (as `pmsm simulate` defaults it).
fn inverter(motor: &MotorParams, vdc_v: f64, pwm_hz: f64, dead_time_s: f64) -> InverterParams {
    let mut inv = InverterParams {
        vdc_v,
        pwm_hz,
        dead_time_s,
        current_full_scale_a: 1.0,
    };
    if let Ok(base) = PerUnit::new(motor, &inv, pwm_hz) {
        inv.current_full_scale_a = 4.0 * base.current_a;
    }
    inv
}

/// A motor of `examples/published/motors.toml` and the inverter it runs on.
pub struct Published {
    /// The loop's name in the `PIL` lines.
    pub name: &'static str,
    /// [`MotorParams::new`]'s arguments: pole pairs, `R` (Ω), `L_d`, `L_q` (H), `ψ` (Wb),
    /// `J` (kg m²), `B` (N m s).
    pub pole_pairs: u32,
    pub rs_ohm: f64,
    pub ld_h: f64,
    pub lq_h: f64,
    pub flux_wb: f64,
    pub j_kg_m2: f64,
    pub b_nm_s: f64,
    /// Ratings: current (A rms) and speed (r/min).
    pub rated_current_a: f64,
    pub rated_speed_rpm: f64,
    /// The inverter: bus (V), PWM (Hz), dead time (s).
    pub vdc_v: f64,
    pub pwm_hz: f64,
    pub dead_time_s: f64,
}

impl Published {
    /// The loop of this motor at half its rated speed.
    pub fn make(&self) -> LoopMotor {
        let mut m = MotorParams::new(
            self.pole_pairs,
            self.rs_ohm,
            self.ld_h,
            self.lq_h,
            self.flux_wb,
            self.j_kg_m2,
            self.b_nm_s,
        );
        m.rated_current_a = Some(self.rated_current_a);
        m.rated_speed_rpm = Some(self.rated_speed_rpm);
        LoopMotor {
            name: self.name,
            inverter: inverter(&m, self.vdc_v, self.pwm_hz, self.dead_time_s),
            motor: m,
            speed_frac: 0.5,
        }
    }
}

/// The low-inductance and the high-pole-count motor:
/// - "DJI 2212 920KV": a drone outrunner, 7 pole pairs, 0.115 Ω, 17.6 µH, ψ 0.963 mWb (TI's
///   identified values), rated 10 A rms, 9000 r/min, on 14.8 V at 24 kHz with 0.3 µs of
///   dead time;
/// - "MIT Mini Cheetah actuator motor": 21 pole pairs, 0.13 Ω, 80 µH, ψ 2.87 mWb, rated
///   12 A rms, 1800 r/min, on 24 V at 40 kHz with 0.1 µs of dead time.
pub const LOOP_MOTORS: [Published; 2] = [
    Published {
        name: "low_l",
        pole_pairs: 7,
        rs_ohm: 0.115332,
        ld_h: 1.76481e-5,
        lq_h: 1.76481e-5,
        flux_wb: 9.629e-4,
        j_kg_m2: 5.06154e-6,
        b_nm_s: 1.5e-6,
        rated_current_a: 10.0,
        rated_speed_rpm: 9000.0,
        vdc_v: 14.8,
        pwm_hz: 24e3,
        dead_time_s: 3e-7,
    },
    Published {
        name: "high_p",
        pole_pairs: 21,
        rs_ohm: 0.13,
        ld_h: 8e-5,
        lq_h: 8e-5,
        flux_wb: 2.87e-3,
        j_kg_m2: 1.5e-4,
        b_nm_s: 8.1e-5,
        rated_current_a: 12.0,
        rated_speed_rpm: 1800.0,
        vdc_v: 24.0,
        pwm_hz: 40e3,
        dead_time_s: 1e-7,
    },
];

impl LoopMotor {
    /// The drive's defaults for the motor (`DriveDesign::default_for` with the estimator
    /// `EstimatorKind::for_motor` chooses), started at the rotor's angle (the plant has no
    /// saturation for a detection to read), the PWM update delay of one period as on the
    /// board, without the dead-time calibration (the plant has no dead time).
    pub fn config(&self) -> Result<DriveConfig, ConfigError> {
        let hz = self.inverter.pwm_hz;
        let base = self.base()?;
        let estimator = EstimatorKind::for_motor(&self.motor);
        let mut design = DriveDesign::default_for(&self.motor, &self.inverter, &base, estimator);
        design.startup = StartupMode::Known(Angle::ZERO);
        design.pwm_delay_samples = 1;
        design.deadtime_calibration = false;
        DriveConfig::new(&self.motor, &self.inverter, hz, design.without_injection())
    }

    /// The per-unit bases.
    pub fn base(&self) -> Result<PerUnit, ConfigError> {
        PerUnit::new(&self.motor, &self.inverter, self.inverter.pwm_hz)
    }

    /// The speed reference, per unit of the base speed.
    pub fn speed_ref(&self, base: &PerUnit) -> Pu {
        let rpm = self.speed_frac * self.motor.rated_speed_rpm.unwrap_or(0.0);
        base.speed_pu(rpm * core::f64::consts::TAU / 60.0 * self.motor.p())
    }

    /// The plant of the motor at rest at angle 0.
    pub fn plant(&self, base: &PerUnit) -> DqPlant {
        let m = &self.motor;
        DqPlant::at_rest(
            (
                m.rs_ohm as f32,
                m.ld_h as f32,
                m.lq_h as f32,
                m.flux_wb as f32,
                m.j_kg_m2 as f32,
                m.b_nm_s as f32,
                m.p() as f32,
            ),
            Angle::ZERO,
            base.voltage_v as f32,
            base.current_a as f32,
        )
    }

    /// Whether the loop ended holding the rotor: running, the angle within 0.15 rad, the speed
    /// within 5 % of the reference (the published motors' bars).
    pub fn held(&self, end: &LoopEnd) -> bool {
        let rpm = self.speed_frac * self.motor.rated_speed_rpm.unwrap_or(0.0);
        let w = (rpm * core::f64::consts::TAU / 60.0 * self.motor.p()) as f32;
        let angle = end.error.0 as f32 * (core::f32::consts::TAU / 4_294_967_296.0);
        end.state == pmsm_core::DriveState::Run.code()
            && angle.abs() <= 0.15
            && (end.omega_e_rad_s - w).abs() <= 0.05 * w
    }
}

/// The file of the host's digests: per loop of [`LOOP_MOTORS`], in order, its digest (a
/// little-endian `u32`).
pub fn digest_file(digests: &[u32]) -> [u8; 4 * LOOP_MOTORS.len()] {
    let mut out = [0u8; 4 * LOOP_MOTORS.len()];
    for (chunk, d) in out.chunks_exact_mut(4).zip(digests) {
        chunk.copy_from_slice(&d.to_le_bytes());
    }
    out
}

/// Digest `k` of a file written by [`digest_file`] (`None` if short).
pub fn digest_at(file: &[u8], k: usize) -> Option<u32> {
    let b = file.get(4 * k..4 * k + 4)?;
    Some(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
}

/// Runs the loop of `m` with `step` running each sample: the end, or the configuration's
/// error.
pub fn run(
    m: &LoopMotor,
    step: &mut dyn FnMut(&mut Drive, &DriveInput) -> DriveOutput,
) -> Result<LoopEnd, ConfigError> {
    let config = m.config()?;
    let base = m.base()?;
    let mut d = crate::cases::started(config);
    let mut plant = m.plant(&base);
    let w = m.speed_ref(&base);
    let vdc = base.voltage_pu(m.inverter.vdc_v);
    Ok(closed_loop(
        &mut d,
        &mut plant,
        vdc,
        base.sample_s as f32,
        LOOP_SAMPLES,
        &|k| (k == 0).then_some(w),
        step,
    ))
}
