//! Motor, inverter and current sensing stepped one PWM period at a time.
//!
//! A period `[t, t + T)` of the centre-aligned PWM starts and ends in the middle of the zero
//! vector 000 (all high sides off). The phase currents are sampled at its end, `t + T`: the
//! "PWM centre" of the symmetric pattern, where the current ripple crosses its average, so
//! the ADC sees the fundamental without ripple.

use pmsm_core::params::non_negative;

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

/// The whole plant: motor, inverter and phase-current sensing.
#[derive(Clone, Debug)]
pub struct Plant {
    motor: Motor,
    inverter: Inverter,
    sensor: CurrentSensor,
    vdc_v: f64,
    periods: u64,
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
        self.inverter
            .step_period(&mut motor, duties, self.vdc_v, load_nm)?;
        Ok(self.finish_period(motor, clamped))
    }

    /// Integrates one PWM period with the inverter's outputs off (all switches open; see
    /// [`Inverter::step_off`]), then samples the currents. On error the plant is unchanged.
    pub fn step_off(&mut self, load_nm: f64) -> Result<Sample, PlantError> {
        let mut motor = self.motor.clone();
        self.inverter.step_off(&mut motor, self.vdc_v, load_nm)?;
        Ok(self.finish_period(motor, false))
    }

    /// Accepts the motor advanced by one period and samples it.
    fn finish_period(&mut self, motor: Motor, clamped: bool) -> Sample {
        self.motor = motor;
        self.periods += 1;
        let i_true = self.motor.i_abc();
        let (codes, i_meas) = self.sensor.measure(i_true);
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
