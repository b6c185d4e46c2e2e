//! `pmsm simulate --fault-dump FILE`: the core's fault recorder, fed by the simulated drive as
//! firmware feeds it, written after a fault as a CSV that `pmsm observe` replays.
//!
//! Columns: `t_s, i_alpha_a, i_beta_a, v_alpha_v, v_beta_v` (what `pmsm observe` reads; the
//! voltage is the drive's command, held over the next sample: replay with `--voltage held`),
//! then `i_a_a, i_b_a, i_c_a, vdc_v` (the sampled phase currents and bus), `theta_e_est_rad,
//! omega_e_est_rad_s` (the drive's own estimate), `state` ([`DriveState::code`]), and the
//! simulation's truth, `theta_e_rad, omega_m_rad_s`, which `pmsm observe` compares with. One
//! row per control sample, oldest first; the last row is the sample at which the drive
//! tripped. The SI values are the recorder's per-unit words times the drive's bases.
//!
//! [`DriveState::code`]: pmsm_core::DriveState::code

use super::simulate::Row;
use crate::csv_io;
use anyhow::Result;
use pmsm_core::FaultRecorder;
use pmsm_core::PerUnit;
use pmsm_core::clarke;
use pmsm_core::{Drive, DriveInput, Fault};
use std::f64::consts::TAU;
use std::path::Path;

/// Samples kept before a fault: 8192 (0.59 s at 14 kHz, 0.41 s at 20 kHz), enough for an
/// observer replayed from rest to converge before the fault.
pub const SAMPLES: usize = 8192;

/// The columns of a dump, in order.
pub const COLUMNS: [&str; 14] = [
    "t_s",
    "i_alpha_a",
    "i_beta_a",
    "v_alpha_v",
    "v_beta_v",
    "i_a_a",
    "i_b_a",
    "i_c_a",
    "vdc_v",
    "theta_e_est_rad",
    "omega_e_est_rad_s",
    "state",
    "theta_e_rad",
    "omega_m_rad_s",
];

/// The recorder of a simulation, with what it takes to write its samples in SI.
#[derive(Debug)]
pub struct Recorder {
    samples: Box<FaultRecorder<SAMPLES>>,
    base: PerUnit,
    sample_hz: f64,
    /// Index of the last recorded control sample.
    last_k: usize,
}

impl Recorder {
    /// An empty recorder for a drive on `base` stepped at `sample_hz`.
    pub fn new(base: PerUnit, sample_hz: f64) -> Self {
        Self {
            samples: Box::default(),
            base,
            sample_hz,
            last_k: 0,
        }
    }

    /// Records control sample `k` (after `drive.step(input)`), as firmware does.
    pub fn record(&mut self, k: usize, drive: &Drive, input: &DriveInput) {
        if !self.samples.is_frozen() {
            self.samples.record(drive.isr(), input);
            self.last_k = k;
        }
    }

    /// The fault that froze the recorder, if the drive tripped.
    pub fn fault(&self) -> Option<Fault> {
        self.samples.fault()
    }

    /// Writes the samples before the fault to `path` (`rows`: the run's rows, for the
    /// truth); returns the fault and the number of rows, or `None` (and writes nothing) if
    /// the drive did not trip.
    pub fn write(&self, path: &Path, rows: &[Row]) -> Result<Option<(Fault, usize)>> {
        let Some(fault) = self.samples.fault() else {
            return Ok(None);
        };
        let b = &self.base;
        let first_k = self.last_k + 1 - self.samples.len();
        let mut w = csv_io::Writer::create(path, &COLUMNS)?;
        for (n, s) in self.samples.samples().enumerate() {
            let k = first_k + n;
            let i_ab = clarke(s.i_abc);
            let truth = rows
                .get(k)
                .map_or([f64::NAN; 2], |r| [r.theta_e_rad, r.speed_rpm * TAU / 60.0]);
            w.row(&[
                k as f64 / self.sample_hz,
                b.current_a(i_ab.alpha),
                b.current_a(i_ab.beta),
                b.voltage_v(s.v.alpha),
                b.voltage_v(s.v.beta),
                b.current_a(s.i_abc.a),
                b.current_a(s.i_abc.b),
                b.current_a(s.i_abc.c),
                b.voltage_v(s.vdc),
                s.estimate.theta.to_rad(),
                b.speed_rad_s(s.estimate.omega),
                f64::from(s.state),
                truth[0],
                truth[1],
            ])?;
        }
        Ok(Some((fault, w.finish()?)))
    }
}

/// `--fault-dump`: writes the dump if the run ended in a fault, and says so.
pub fn write_if_faulted(path: Option<&Path>, rec: &Recorder, rows: &[Row]) -> Result<()> {
    let Some(path) = path else { return Ok(()) };
    match rec.write(path, rows)? {
        Some((fault, n)) => crate::outln!(
            "  fault dump {} ({n} samples before {}; replay: pmsm observe --voltage held)",
            path.display(),
            fault.name()
        ),
        None => crate::outln!("  fault dump: no fault, {} not written", path.display()),
    }
    Ok(())
}
