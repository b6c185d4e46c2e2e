//! The task's learners: the tracker of `R` and `ψ` (docs/tracking.md) and the learner of the
//! inverter's distortion (docs/distortion.md), on each window's last sample.

use super::DriveTask;
#[cfg(feature = "distortion-learner")]
use crate::drive::DistortionDesign;
#[cfg(any(feature = "tracking", feature = "distortion-learner"))]
use crate::drive::config::DriveConfig;
#[cfg(feature = "distortion-learner")]
use crate::drive::distortion::DistortionLearner;
use crate::drive::messages::Window;
#[cfg(any(feature = "tracking", feature = "distortion-learner"))]
use crate::drive::tracking::TrackerInput;
#[cfg(feature = "tracking")]
use crate::drive::tracking::{Tracker, TrackerDesign};

impl DriveTask {
    /// The tracker and the learner on the window's last sample; a model update when they
    /// moved.
    #[cfg(any(feature = "tracking", feature = "distortion-learner"))]
    pub(super) fn learn(&mut self, w: &Window, running: bool) {
        #[cfg(feature = "tracking")]
        let tracker = self.tracker.is_some();
        #[cfg(not(feature = "tracking"))]
        let tracker = false;
        #[cfg(feature = "distortion-learner")]
        let learner = self.learner.is_some();
        #[cfg(not(feature = "distortion-learner"))]
        let learner = false;
        if !tracker && !learner {
            return;
        }
        let input = TrackerInput {
            running,
            theta: w.theta,
            omega: w.omega,
            i_dq: w.i_dq,
            i_ref: w.i_ref,
            v: w.v_est,
            saturated: w.saturated,
        };
        #[cfg(feature = "tracking")]
        if let Some(t) = &mut self.tracker
            && let Some(c) = t.task_step(&input)
        {
            self.set_model(&c);
        }
        #[cfg(feature = "distortion-learner")]
        let scale = self.deadtime_scale();
        #[cfg(feature = "distortion-learner")]
        if let Some(l) = &mut self.learner
            && let Some(s) = l.update(&input, scale)
        {
            self.set_deadtime_scale(s);
        }
    }

    /// Without the learners' features: nothing to learn.
    #[cfg(not(any(feature = "tracking", feature = "distortion-learner")))]
    pub(super) fn learn(&mut self, _: &Window, _: bool) {}
}

/// The tracker of `config`'s design (out of line: its `f64` design stays out of
/// [`DriveTask::new`]'s frame).
#[cfg(feature = "tracking")]
#[cold]
#[inline(never)]
pub(super) fn tracker_of(config: &DriveConfig) -> Option<Tracker> {
    Some(Tracker::build(
        &config.motor,
        &config.base,
        TrackerDesign::for_drive(config),
    ))
}

/// The learner of `config`'s design (out of line, as [`tracker_of`]).
#[cfg(feature = "distortion-learner")]
#[cold]
#[inline(never)]
pub(super) fn learner_of(config: &DriveConfig) -> Option<DistortionLearner> {
    DistortionLearner::build(&config.motor, config, DistortionDesign::for_drive(config))
}
