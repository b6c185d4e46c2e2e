//! The floating-point plant of a scenario (true motor, inverter model, current ADC) and the
//! injection of its `[faults]`.

use crate::scenario_file::{self, InverterKind, Scenario};
use anyhow::{Result, anyhow};
use pmsm_core::InverterParams;
use pmsm_plant::{AdcParams, InverterModel, Mechanics, Motor, Plant, PlantError};

/// Builds the plant of `sc` on `inverter` (the drive's, so that both share the ADC range):
/// the true motor at `[initial]`, the `[inverter]` model and the `[sensing]` ADC.
pub fn build_plant(sc: &Scenario, inverter: &InverterParams) -> Result<Plant> {
    let shown = sc.path.display();
    let motor = Motor::new(sc.motor.model, sc.theta0_rad, sc.omega_m0_rad_s)
        .map_err(|e| anyhow!("{shown}: {e}"))?;
    let kind = match sc.inverter.model {
        InverterKind::Averaged => pmsm_plant::InverterKind::Averaged,
        InverterKind::Switching => pmsm_plant::InverterKind::Switching,
    };
    let mut plant_inverter = InverterModel::new(*inverter, kind);
    plant_inverter.v_sat_v = sc.inverter.v_sat_v;
    plant_inverter.v_f_v = sc.inverter.v_f_v;
    if let Some(band) = sc.inverter.sign_band_a {
        plant_inverter.sign_band_a = band;
    }
    let mut adc = AdcParams::from_inverter(inverter);
    adc.bits = sc.sensing.adc_bits.unwrap_or(12);
    adc.noise_rms_a = sc.sensing.noise_rms_a;
    adc.offset_a = sc.sensing.offset_a;
    adc.gain_error = sc.sensing.gain_error;
    Plant::new(motor, plant_inverter, adc).map_err(|e| anyhow!("{shown}: {e}"))
}

/// Applies the `[faults]` of a scenario to the plant when their time comes, once each.
pub(super) struct Injector {
    faults: scenario_file::Faults,
    done: [bool; 5],
}

impl Injector {
    pub(super) fn new(faults: &scenario_file::Faults) -> Self {
        Self {
            faults: *faults,
            done: [false; 5],
        }
    }

    fn due(&mut self, k: usize, at: Option<f64>, t: f64) -> bool {
        match (at, self.done.get(k).copied()) {
            (Some(at), Some(false)) if t >= at => {
                self.done[k] = true;
                true
            }
            _ => false,
        }
    }

    /// Injects what is due at `t`; `codes` are the ADC's last codes, at which a stuck channel
    /// freezes.
    pub(super) fn apply(
        &mut self,
        t: f64,
        plant: &mut Plant,
        codes: [u16; 3],
    ) -> Result<(), PlantError> {
        let f = self.faults;
        let mut inj = plant.injected();
        if self.due(0, f.phase_open_at_s, t) {
            inj.open_phase = f.phase_open.map(scenario_file::Phase::index);
        }
        if self.due(1, f.adc_stuck_at_s, t)
            && let Some(k) = f.adc_stuck_phase.map(scenario_file::Phase::index)
        {
            inj.stuck_adc = codes.get(k).map(|c| (k, *c));
        }
        if self.due(2, f.short_at_s, t) {
            inj.short = f
                .short_phases
                .map(|p| (p.first(), f.short_ohm.unwrap_or(0.1)));
        }
        plant.inject(inj);
        if self.due(3, f.locked_rotor_at_s, t) {
            plant.set_mechanics(Mechanics::Locked)?;
        }
        if self.due(4, f.vdc_sag_at_s, t)
            && let Some(v) = f.vdc_sag_to_v
        {
            plant.set_vdc_v(v)?;
        }
        Ok(())
    }
}
