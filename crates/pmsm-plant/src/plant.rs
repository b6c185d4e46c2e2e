//! Motor, inverter and current sensing stepped one PWM period at a time.
//!
//! A period `[t, t + T)` of the centre-aligned PWM starts and ends in the middle of the zero
//! vector 000 (all high sides off). The phase currents are sampled at its end, `t + T`: the
//! "PWM centre" of the symmetric pattern, where the current ripple crosses its average, so
//! the ADC sees the fundamental without ripple.

use pmsm_core::validate::non_negative;

use crate::PlantError;
use crate::inverter::{Inverter, InverterKind, InverterModel};
use crate::motor::{Mechanics, Motor};
use crate::sensor::{AdcParams, CurrentSensor};

/// What the controller would see at the end of a PWM period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// Time at the sample, s (end of the period just integrated).
    pub t_s: f64,
    /// True phase currents, A.
    pub i_abc_a_true: [f64; 3],
    /// ADC codes of the three phase currents.
    pub adc_codes: [u16; 3],
    /// The currents the codes stand for ([`CurrentSensor::code_to_amps`]), A.
    pub i_abc_a_measured: [f64; 3],
    /// DC bus voltage during the period, V.
    pub vdc_v: f64,
    /// True if at least one duty was outside `[0, 1]` and clamped.
    pub duties_clamped: bool,
}

/// Faults injected into the plant (the reliability tests). Each acts from when it is set.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Injected {
    /// An open phase (0 = a, 1 = b, 2 = c): a broken wire, modelled as a series resistance of
    /// [`OPEN_PHASE_OHM_PER_OHM_BASE`] times the base impedance in that phase.
    pub open_phase: Option<usize>,
    /// A current channel stuck at this code (0 = a, 1 = b, 2 = c).
    pub stuck_adc: Option<(usize, u16)>,
    /// A resistive short between two motor terminals (phases `k` and `(k + 1) mod 3`), Ω. The
    /// inverter legs are stiff voltage sources: the motor still sees their voltages, and the
    /// leg current sensors see the short's period-average current added.
    pub short: Option<(usize, f64)>,
}

/// Series resistance of an open phase, relative to `V_DC/I_FS` (a few kΩ on motor B): its
/// current falls to milliamperes.
pub const OPEN_PHASE_OHM_PER_OHM_BASE: f64 = 30.0;

/// The whole plant: motor, inverter and phase-current sensing.
#[derive(Clone, Debug)]
pub struct Plant {
    motor: Motor,
    inverter: Inverter,
    sensor: CurrentSensor,
    vdc_v: f64,
    periods: u64,
    injected: Injected,
    /// Duties of the last period (the short's current depends on them).
    last_duties: [f64; 3],
}

impl Plant {
    /// Plant at `t = 0` with the bus at the inverter's nominal `vdc_v`. Validates the inverter
    /// and the sensor (the motor is valid by construction).
    pub fn new(motor: Motor, inverter: InverterModel, adc: AdcParams) -> Result<Self, PlantError> {
        Ok(Self {
            motor,
            vdc_v: inverter.params.vdc_v,
            inverter: Inverter::new(inverter)?,
            sensor: CurrentSensor::new(adc)?,
            periods: 0,
            injected: Injected::default(),
            last_duties: [0.0; 3],
        })
    }

    /// The motor.
    pub fn motor(&self) -> &Motor {
        &self.motor
    }

    /// The motor, mutably (to set its state; stepping it directly bypasses the plant clock).
    pub fn motor_mut(&mut self) -> &mut Motor {
        &mut self.motor
    }

    /// The inverter.
    pub fn inverter(&self) -> &Inverter {
        &self.inverter
    }

    /// The current sensor.
    pub fn sensor(&self) -> &CurrentSensor {
        &self.sensor
    }

    /// Switches between the averaged and the switching-level inverter model.
    pub fn set_inverter_kind(&mut self, kind: InverterKind) {
        self.inverter.set_kind(kind);
    }

    /// Sets the mechanics of the motor ([`Motor::set_mechanics`]).
    pub fn set_mechanics(&mut self, mechanics: Mechanics) -> Result<(), PlantError> {
        self.motor.set_mechanics(mechanics)
    }

    /// Scales the motor's true resistance and magnet flux (thermal drift,
    /// [`crate::thermal`]); see [`Motor::set_factors`].
    pub fn set_thermal_factors(
        &mut self,
        rs_factor: f64,
        flux_factor: f64,
    ) -> Result<(), PlantError> {
        self.motor.set_factors(rs_factor, flux_factor)
    }

    /// DC bus voltage, V.
    pub fn vdc_v(&self) -> f64 {
        self.vdc_v
    }

    /// Sets the DC bus voltage from the next period on (bus sag), V; finite, not negative.
    pub fn set_vdc_v(&mut self, vdc_v: f64) -> Result<(), PlantError> {
        self.vdc_v = non_negative("vdc_v", vdc_v)?;
        Ok(())
    }

    /// PWM period, s.
    pub fn period_s(&self) -> f64 {
        self.inverter.model().period_s()
    }

    /// Simulated time, s (a whole number of periods).
    pub fn time_s(&self) -> f64 {
        self.periods as f64 * self.period_s()
    }

    /// Integrates one PWM period with duties `duties` (each clamped to `[0, 1]`, reported in
    /// [`Sample::duties_clamped`]) and load torque `load_nm` (N·m), then samples the currents.
    ///
    /// A NaN duty or non-finite load is an error ([`PlantError::NonFinite`]); on any error the
    /// plant is left exactly as before the call.
    pub fn step_pwm(&mut self, duties: [f64; 3], load_nm: f64) -> Result<Sample, PlantError> {
        let clamped = duties.iter().any(|&d| !(0.0..=1.0).contains(&d));
        let mut motor = self.motor.clone();
        self.last_duties = duties.map(|x| if x.is_nan() { 0.0 } else { x.clamp(0.0, 1.0) });
        match (self.injected.open_phase, self.injected.short) {
            (None, None) => self
                .inverter
                .step_period(&mut motor, duties, self.vdc_v, load_nm)?,
            _ => self.faulty_period(&mut motor, duties, load_nm)?,
        }
        Ok(self.finish_period(motor, clamped))
    }

    /// The faults injected so far.
    pub fn injected(&self) -> Injected {
        self.injected
    }

    /// Injects faults (replacing the previous set).
    pub fn inject(&mut self, faults: Injected) {
        self.injected = faults;
    }

    /// One period with an open phase or a terminal short, on the averaged inverter model.
    ///
    /// An open phase is a series resistance `R_o` in its winding: its terminal sees the leg
    /// voltage minus `R_o i_x` (the neutral shift is the common mode the Clarke transform
    /// drops, so this is exact for a star winding). A short of resistance `R_s` between
    /// terminals `k` and `m` draws `(v_k − v_m)/R_s` from the two legs: the phase currents are
    /// unchanged by it, but the current sensors in the legs see it added (`+` on `k`, `−` on
    /// `m`), as low-side shunts would; the motor sees the legs' voltages.
    fn faulty_period(
        &mut self,
        motor: &mut Motor,
        duties: [f64; 3],
        load_nm: f64,
    ) -> Result<(), PlantError> {
        let m = *self.inverter.model();
        let vdc = self.vdc_v;
        let period = m.period_s();
        let d = duties.map(|x| x.clamp(0.0, 1.0));
        let r_open = OPEN_PHASE_OHM_PER_OHM_BASE * vdc / self.sensor.params().full_scale_a;
        let open = self.injected.open_phase;
        // Stiff: the open phase's R_o/L sets the step.
        let h = m
            .averaged_substep_limit_s(vdc, motor.min_inductance_h())
            .min(0.2 * motor.min_inductance_h() / r_open);
        // The hard sign (no band) is held over the period, from its start.
        let signs = m.period_signs(motor.i_abc());
        motor.step_with_limit(period, load_nm, h, |i| {
            let mut legs = [0, 1, 2].map(|k| {
                let s = signs.map_or_else(|| m.smooth_sign(i[k]), |s| s[k]);
                m.leg_voltage_averaged_signed_v(d[k], vdc, s)
            });
            if let Some(x) = open
                && let Some(v) = legs.get_mut(x)
            {
                *v -= r_open * i[x];
            }
            crate::clarke(legs)
        })
    }

    /// Integrates one PWM period with the inverter's outputs off (all switches open; see
    /// [`Inverter::step_off`]), then samples the currents. On error the plant is unchanged.
    pub fn step_off(&mut self, load_nm: f64) -> Result<Sample, PlantError> {
        let mut motor = self.motor.clone();
        self.last_duties = [0.0; 3];
        self.inverter.step_off(&mut motor, self.vdc_v, load_nm)?;
        Ok(self.finish_period(motor, false))
    }

    /// Accepts the motor advanced by one period and samples it.
    fn finish_period(&mut self, motor: Motor, clamped: bool) -> Sample {
        self.motor = motor;
        self.periods += 1;
        let i_true = self.motor.i_abc();
        let mut i_leg = i_true;
        if let Some((k, r_short)) = self.injected.short {
            // The legs are voltage sources: the short draws the period average of
            // (v_k − v_m)/R_s from them, which the leg shunts measure.
            let m = (k + 1) % 3;
            let dk = self.last_duties.get(k).copied().unwrap_or(0.0);
            let dm = self.last_duties.get(m).copied().unwrap_or(0.0);
            let i_s = (dk - dm) * self.vdc_v / r_short.max(1e-6);
            if let (Some(a), Some(b)) = (i_leg.get(k).copied(), i_leg.get(m).copied()) {
                i_leg[k] = a + i_s;
                i_leg[m] = b - i_s;
            }
        }
        let (mut codes, mut i_meas) = self.sensor.measure(i_leg);
        if let Some((k, code)) = self.injected.stuck_adc
            && let (Some(c), Some(x)) = (codes.get_mut(k), i_meas.get_mut(k))
        {
            *c = code;
            *x = self.sensor.code_to_amps(code);
        }
        Sample {
            t_s: self.time_s(),
            i_abc_a_true: i_true,
            adc_codes: codes,
            i_abc_a_measured: i_meas,
            vdc_v: self.vdc_v,
            duties_clamped: clamped,
        }
    }
}
