//! motor A (examples/motor-a.toml) (Solsona, Valla, Muravchik (2000)) on a 300 V bus, sampled at 20 kHz.

use pmsm_core::{AoConfig, EstimatorKind, MrasEmfConfig, NloConfig};
use pmsm_core::{ConfigError, InverterParams, MotorParams, PerUnit};
use pmsm_core::{DriveConfig, DriveDesign, StartupMode};

/// Control sample rate, Hz.
pub const SAMPLE_HZ: f64 = 20e3;
/// DC bus, V.
pub const VDC_V: f64 = 300.0;
/// Observer gain `g` of the NLO and the AO (motor A, examples/motor-a.toml), rad/s.
pub const OBSERVER_GAIN_RAD_S: f64 = 1000.0;

/// Motor A (surface PMSM, 1.2 kW, 1200 r/min) with the paper's `K_T`.
pub fn motor_a() -> MotorParams {
    let mut m = MotorParams::new(3, 1.6, 0.0134, 0.0134, 0.288, 0.04256, 0.004256);
    m.kt_nm_per_a = 1.108;
    m.rated_current_a = Some(6.1);
    m.rated_speed_rpm = Some(1200.0);
    m
}

/// The inverter: 300 V bus, 20 kHz PWM, 1 µs dead time, 20 A current full scale.
pub fn inverter() -> InverterParams {
    InverterParams {
        vdc_v: VDC_V,
        pwm_hz: SAMPLE_HZ,
        dead_time_s: 1e-6,
        current_full_scale_a: 20.0,
    }
}

/// Motor, inverter and per-unit bases of every PIL run.
#[derive(Clone, Copy, Debug)]
pub struct Setup {
    /// Motor A.
    pub motor: MotorParams,
    /// See [`inverter`].
    pub inverter: InverterParams,
    /// Per-unit bases (`V_b = V_DC/√3`, `I_b = √2 · 6.1 A`, `ω_b = V_b/ψ`).
    pub base: PerUnit,
}

impl Setup {
    /// Motor A at 20 kHz on 300 V.
    pub fn motor_a() -> Result<Self, ConfigError> {
        let motor = motor_a();
        let inverter = inverter();
        let base = PerUnit::new(&motor, &inverter, SAMPLE_HZ)?;
        Ok(Self {
            motor,
            inverter,
            base,
        })
    }

    /// NLO of gain [`OBSERVER_GAIN_RAD_S`].
    pub fn nlo(&self) -> Result<NloConfig, ConfigError> {
        NloConfig::new(&self.motor, &self.base, OBSERVER_GAIN_RAD_S)
    }

    /// AO of gain [`OBSERVER_GAIN_RAD_S`].
    pub fn ao(&self) -> Result<AoConfig, ConfigError> {
        AoConfig::new(&self.motor, &self.base, OBSERVER_GAIN_RAD_S)
    }

    /// Tomita's MRAS with the paper's constants on an AO of gain [`OBSERVER_GAIN_RAD_S`].
    pub fn mras_emf(&self) -> Result<MrasEmfConfig, ConfigError> {
        MrasEmfConfig::paper(&self.motor, &self.base, OBSERVER_GAIN_RAD_S)
    }
}

/// Control sample rate of the drive runs (motor B, Khlaief, Boussak, Gossa (2012)): the 14 kHz PWM, Hz.
pub const DRIVE_SAMPLE_HZ: f64 = 14e3;

/// Motor B of Khlaief, Boussak, Gossa (2012) (interior PMSM, 1.1 kW): p = 3, R = 7.2 Ω, L_d = 25.025 mH,
/// L_q = 40.17 mH, ψ = 0.305 Wb, J = 0.0036 kg·m², B = 0.0011 N·m·s, rated 2.53 A, 3000 r/min
/// (`examples/motor-b.toml`).
pub fn motor_b() -> MotorParams {
    let mut m = MotorParams::new(3, 7.2, 0.025025, 0.04017, 0.305, 0.0036, 0.0011);
    m.rated_current_a = Some(2.53);
    m.rated_speed_rpm = Some(3000.0);
    m
}

/// The inverter of Khlaief, Boussak, Gossa (2012): 540 V bus, 14 kHz SVPWM, 2 µs dead time; current full scale
/// 4 `I_b` (as `pmsm simulate` defaults it).
pub fn inverter_b() -> Result<InverterParams, ConfigError> {
    let mut inv = InverterParams {
        vdc_v: 540.0,
        pwm_hz: DRIVE_SAMPLE_HZ,
        dead_time_s: 2e-6,
        current_full_scale_a: 1.0,
    };
    let base = PerUnit::new(&motor_b(), &inv, DRIVE_SAMPLE_HZ)?;
    inv.current_full_scale_a = 4.0 * base.current_a;
    Ok(inv)
}

impl Setup {
    /// Motor B at 14 kHz on 540 V (the drive runs).
    pub fn motor_b() -> Result<Self, ConfigError> {
        let motor = motor_b();
        let inverter = inverter_b()?;
        let base = PerUnit::new(&motor, &inverter, DRIVE_SAMPLE_HZ)?;
        Ok(Self {
            motor,
            inverter,
            base,
        })
    }

    /// The drive of Khlaief, Boussak, Gossa (2012) of `pmsm simulate` (every default of
    /// [`DriveDesign::default_for`](pmsm_core::DriveDesign::default_for)) with `estimator`
    /// and `startup`, compensating a PWM update delay of one period as on the board.
    pub fn drive(
        &self,
        estimator: EstimatorKind,
        startup: StartupMode,
    ) -> Result<DriveConfig, ConfigError> {
        let base = PerUnit::new(&self.motor, &self.inverter, DRIVE_SAMPLE_HZ)?;
        let mut design = DriveDesign::default_for(&self.motor, &self.inverter, &base, estimator);
        design.startup = startup;
        // As the board (pmsm-stm32's TIM1 loads the duties one period later): the step pays
        // for the delay's compensation.
        design.pwm_delay_samples = 1;
        // The dead-time calibration (40 ms at standstill, before the run; the told dead time
        // is the plant's, so it changes nothing) is left out: the recording, which the
        // micro:bit's flash holds no longer, keeps its closed-loop steps.
        design.deadtime_calibration = false;
        // The detection's pulses 1.5 electrical time constants apart, 5 % of the peak left
        // (the default 1 %, 3.1 time constants on motor B, keeps the recording in the detection
        // longer; the micro:bit's flash holds the recording beside the core, with the task's
        // learners, at about half).
        design.ipd.off_residual = 0.05;
        // The estimator's drive on every build: the Cortex-M4's has the injection (its own
        // case, `isr_injection`), the host's and the Cortex-M0's do not.
        self.config(design.without_injection())
    }

    /// `DriveConfig::new` for this motor and inverter at [`DRIVE_SAMPLE_HZ`]: its one call in
    /// the firmware (it is inlined where it is called; the micro:bit's flash holds one copy).
    #[inline(never)]
    pub fn config(&self, design: DriveDesign) -> Result<DriveConfig, ConfigError> {
        DriveConfig::new(&self.motor, &self.inverter, DRIVE_SAMPLE_HZ, design)
    }
}
