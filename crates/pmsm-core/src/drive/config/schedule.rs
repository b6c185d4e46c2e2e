//! The speed loop's other gains, which the task switches to by operating point
//! (`drive/task/speed_schedule.rs`): slower while the injection holds the rotor, stiffer above
//! twice the handover speed.

use crate::control::speed::{SpeedConfig, SpeedDesign, SpeedGains};
use crate::drive::design::DriveDesign;
use crate::error::ConfigError;
use crate::num::Pu;
use crate::params::MotorParams;
use crate::units::PerUnit;

/// The gains of the slower speed loop while the injection (its configuration and figures)
/// holds the rotor, with the reference below which it does; `None` without the injection or
/// with gains given by hand.
#[cfg(feature = "injection")]
pub(super) fn injecting(
    motor: &MotorParams,
    base: &PerUnit,
    design: &DriveDesign,
    injection: &Option<crate::observer::InjectionConfig>,
    figures: &Option<crate::observer::InjectionFigures>,
) -> Result<Option<(SpeedGains, Pu)>, ConfigError> {
    let (Some(c), Some(f), None) = (injection, figures, design.speed.gains) else {
        return Ok(None);
    };
    // `SPEED_SHARE` of the tracking loop, no slower than a light rotor's stiff loop.
    let w = (crate::observer::injection::SPEED_SHARE * f.bandwidth_rad_s)
        .max(crate::drive::design::stiff_bandwidth_rad_s(motor, base));
    let d = design.speed;
    let slower = SpeedDesign {
        bandwidth_rad_s: d.bandwidth_rad_s.min(w),
        ..d
    };
    Ok(Some((
        SpeedConfig::new(motor, base, slower)?.gains(),
        c.on_below,
    )))
}

/// The gains of the stiff speed loop of [`DriveDesign::speed_stiff_rad_s`], with the speed
/// above which it runs (twice `handover`, per unit); `None` without it or with gains given by
/// hand.
#[inline(never)]
pub(super) fn stiff(
    motor: &MotorParams,
    base: &PerUnit,
    design: &DriveDesign,
    handover: Pu,
) -> Result<Option<(SpeedGains, Pu)>, ConfigError> {
    let (Some(w), None) = (design.speed_stiff_rad_s, design.speed.gains) else {
        return Ok(None);
    };
    let stiff = SpeedDesign {
        bandwidth_rad_s: w,
        ..design.speed
    };
    Ok(Some((
        SpeedConfig::new(motor, base, stiff)?.gains(),
        Pu::from_bits(handover.to_bits().saturating_mul(2)),
    )))
}
