//! The design keys a build without their cargo features cannot run: refused by name.

use crate::drive::design::DriveDesign;
use crate::error::ConfigError;

/// `Ok` unless `design` asks for what this build leaves out: the tracker (feature
/// `tracking`), the distortion learner (`distortion-learner`), the initial position detection
/// (`ipd`; `design.startup` resolved already).
pub(super) fn check(design: &DriveDesign) -> Result<(), ConfigError> {
    #[cfg(not(feature = "tracking"))]
    if design.tracking {
        return Err(unbuilt(
            "tracking",
            "a build with the tracker (feature tracking)",
        ));
    }
    #[cfg(not(feature = "distortion-learner"))]
    if design.deadtime_learning {
        return Err(unbuilt(
            "deadtime_learning",
            "a build with the learner (feature distortion-learner)",
        ));
    }
    #[cfg(not(feature = "ipd"))]
    if design.startup == crate::drive::design::StartupMode::Ipd {
        return Err(unbuilt(
            "startup",
            "a build with the initial position detection (feature ipd)",
        ));
    }
    let _ = design;
    Ok(())
}

/// The error of a design key this build cannot run: `key`, and the build it `needs`.
#[cfg(any(
    not(feature = "tracking"),
    not(feature = "distortion-learner"),
    not(feature = "ipd")
))]
fn unbuilt(key: &'static str, needs: &'static str) -> ConfigError {
    crate::params::ParamError {
        key,
        reason: crate::params::ParamReason::Inconsistent(needs),
    }
    .into()
}
