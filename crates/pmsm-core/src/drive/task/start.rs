//! The task's side of the start-up (docs/drive.md, §2): the detection's or the alignment's
//! result, the dead-time calibration at standstill, the start from the rotor's angle and the
//! handover from the open loop to the estimator.

use super::DriveTask;
use crate::angle::Angle;
use crate::drive::calibrate::{Calibration, SCALE_ONE};
use crate::drive::interface::{DriveState, Fault};
use crate::drive::messages::{Mode, Window};
use crate::drive::startup::{HandoverFrame, handover};
use crate::drive::zero_crossing::ZeroCrossing;
use crate::frames::{Dq, park};
use crate::num::Pu;
use crate::observer::Estimate;

impl DriveTask {
    /// The detection found the rotor at `theta`: the dead-time calibration there first, when
    /// on, else the start from it.
    pub(super) fn detected(&mut self, theta: Angle) {
        if self.config.calibration.enabled() {
            self.start_calibration(theta, true);
        } else {
            self.rotor_found(theta);
        }
    }

    /// The alignment ended with the rotor at `theta`.
    pub(super) fn aligned(&mut self, theta: Angle) {
        if self.config.calibration.enabled() {
            self.start_calibration(theta, false);
        } else {
            self.rotor_found(theta);
        }
    }

    fn start_calibration(&mut self, theta: Angle, reset: bool) {
        self.calibration = Calibration::default();
        self.i_ref = Dq {
            d: self.calibration.reference(&self.config.calibration),
            q: Pu::ZERO,
        };
        self.command(DriveState::Align, Mode::Calibrate { theta, reset });
    }

    /// One task period of the dead-time calibration (`calibrate`): a d current along the
    /// rotor's angle through the current loops; at its end the compensation is scaled to what
    /// the inverter does and the drive starts from that angle.
    pub(super) fn calibrate(&mut self, w: &Window) {
        let Mode::Calibrate { theta, .. } = self.mode else {
            return;
        };
        let c = &self.config.calibration;
        let sc = theta.sin_cos();
        // The last sample's command and current in this frame (the rotor stands still), and
        // the compensation's vector (for its reference).
        let y = park(w.v, sc).d;
        let i = w.i_dq.d;
        let d = park(w.v_dt, sc).d;
        let done = self.calibration.record(c, y, i, d);
        self.i_ref.d = self.calibration.reference(c);
        if let Some(s) = done {
            // Relative to the compensation in use: a second start refines the first.
            self.apply_deadtime_scale(crate::num::scale_q28(self.deadtime_scale, s));
            self.rotor_found(theta);
        }
    }

    /// Runs with a compensation whose `V_dead` is `scale` (Q4.28, saturated to [0, 4]) times
    /// the one the drive was told, and the light-load current raised with it.
    pub(super) fn apply_deadtime_scale(&mut self, scale: i32) {
        let scale = scale.clamp(0, 4 * SCALE_ONE);
        // Relative to the scale in use (the configuration holds the scaled values): Q4.28 of
        // new/old, at most 4 (from a scale of zero the compensation stays off).
        let rel = if self.deadtime_scale > 0 {
            (f64::from(scale) / f64::from(self.deadtime_scale) * f64::from(SCALE_ONE))
                .min(f64::from(4 * SCALE_ONE)) as i32
        } else {
            scale
        };
        self.deadtime_scale = scale;
        self.config.deadtime = self.config.deadtime.scaled(rel);
        // Raised with the scale, never lowered (a larger light-load current only costs copper).
        self.config.light_load = self.config.light_load.scaled(rel);
        self.model.deadtime = self.config.deadtime.bus_terms();
        self.model_dirty = true;
    }

    /// The rotor is at `theta`: the estimator starts there and runs, or the open loop starts.
    pub(super) fn rotor_found(&mut self, theta: Angle) {
        let c = &self.config;
        self.flux.reset(&c.flux);
        self.light_load.reset(&c.light_load, Pu::ZERO, Pu::ZERO);
        self.zero_crossing = ZeroCrossing::default();
        self.low_speed_faded = c.low_speed.faded(Pu::ZERO);
        self.low_speed_id = c
            .low_speed
            .within_limit(self.low_speed_faded, Pu::ZERO, Pu::ZERO);
        self.speed.reset(Pu::ZERO, Pu::ZERO);
        self.iq_ref = Pu::ZERO;
        self.speed_filtered = Pu::ZERO;
        self.waited = 0;
        if c.estimator.needs_open_loop_start() {
            // From rest, in the reference's direction.
            let reverse = self.speed_ref < Pu::ZERO;
            self.i_ref = Dq::default();
            self.command(DriveState::OpenLoop, Mode::OpenLoop { theta, reverse });
        } else {
            self.i_ref = self.d_reference();
            self.command(DriveState::Run, Mode::Run { from: Some(theta) });
        }
    }

    /// At the handover speed: the estimate checked against the imposed frame; the closed loop
    /// from the torque current the rotor was getting, or a wait, or a fault.
    pub(super) fn handover(&mut self, w: &Window) {
        let frame = HandoverFrame {
            theta: w.theta,
            omega: w.omega_frame,
            reverse: w.reverse,
            reversal: w.reversal,
        };
        let est = Estimate {
            theta: w.theta_est,
            omega: w.omega,
            ..Estimate::default()
        };
        let iq = match handover(&frame, &est, self.config.open_loop_current) {
            Ok(iq) => iq,
            // A rotor the load holds the old way is named at once.
            Err(Fault::DrivenBackwards) => return self.fault(Fault::DrivenBackwards),
            // A back-EMF estimator started at rest may still be settling, on a light rotor
            // whose ramp took a few milliseconds, when the ramp ends. A reversal does not
            // wait: its rotor may be held by a load that a wait would let run away.
            Err(_) if !w.reversal && self.waited < self.config.handover_wait => {
                self.waited += 1;
                return;
            }
            Err(f) => return self.fault(f),
        };
        let c = &self.config;
        self.handed_over_negative = self.speed_ref_run < Pu::ZERO;
        self.speed_filtered = w.omega;
        self.speed.reset(w.omega, iq);
        #[cfg(feature = "load-observer")]
        self.load.reset(w.omega);
        self.iq_ref = iq;
        self.flux.reset(&c.flux);
        self.light_load.reset(&c.light_load, iq, w.omega);
        // After the start, the open loop's current fades out instead of stepping to zero
        // (`low_speed`, "handover").
        self.low_speed_faded = c.low_speed.faded(w.omega);
        if !w.reversal {
            self.low_speed_faded = self.low_speed_faded.max(c.open_loop_current);
        }
        self.low_speed_id = c.low_speed.within_limit(self.low_speed_faded, iq, Pu::ZERO);
        self.i_ref = Dq {
            d: self.d_reference().d,
            q: iq,
        };
        self.command(DriveState::Run, Mode::Run { from: None });
    }
}
