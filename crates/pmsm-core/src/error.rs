//! Typed errors of the configuration constructors.

use crate::params::ParamError;
use core::fmt;

/// Why a configuration could not be built.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ConfigError {
    /// A physical parameter is invalid; the key names it.
    Param(ParamError),
    /// A derived per-unit quantity falls outside the fixed-point envelope.
    OutOfEnvelope {
        /// What was checked (for instance `"L_d / L_base"`).
        quantity: &'static str,
        /// Its value.
        value: f64,
        /// Smallest supported value.
        min: f64,
        /// Largest supported value.
        max: f64,
        /// What would bring it inside.
        fit: Fit,
    },
    /// A gain (named by its key) outside the range where the discrete algorithm is stable
    /// and representable at the chosen sample rate.
    Gain {
        /// The key of the gain, as in a scenario file or on the command line.
        key: &'static str,
        /// Its value.
        value: f64,
        /// Smallest accepted value.
        min: f64,
        /// Largest accepted value.
        max: f64,
    },
}

/// What would bring a quantity outside the envelope inside it: the one setting that moves it
/// most directly, with the value that makes it fit.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Fit {
    /// A longer or shorter duration, or another motor: no one setting.
    Other,
    /// A control (PWM) frequency of at least this, Hz.
    SampleHzAtLeast(f64),
    /// A control (PWM) frequency of at most this, Hz.
    SampleHzAtMost(f64),
    /// A rated current (the base current's RMS value) of at least this, A.
    RatedCurrentAtLeast(f64),
    /// A rated current of at most this, A.
    RatedCurrentAtMost(f64),
}

impl fmt::Display for Fit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Fit::Other => Ok(()),
            Fit::SampleHzAtLeast(hz) => {
                write!(
                    f,
                    "; a PWM frequency of at least {:.0} Hz would fit",
                    libm::ceil(hz)
                )
            }
            Fit::SampleHzAtMost(hz) => {
                write!(
                    f,
                    "; a PWM frequency of at most {:.0} Hz would fit",
                    libm::floor(hz)
                )
            }
            Fit::RatedCurrentAtLeast(a) => {
                write!(f, "; a rated current of at least {a:.3} A rms would fit")
            }
            Fit::RatedCurrentAtMost(a) => {
                write!(f, "; a rated current of at most {a:.3} A rms would fit")
            }
        }
    }
}

impl From<ParamError> for ConfigError {
    fn from(e: ParamError) -> Self {
        ConfigError::Param(e)
    }
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ConfigError::Param(e) => e.fmt(f),
            ConfigError::OutOfEnvelope {
                quantity,
                value,
                min,
                max,
                fit,
            } => write!(
                f,
                "{quantity} = {value:.3e} is outside the supported envelope [{min:.3e}, {max:.3e}]{fit}"
            ),
            ConfigError::Gain {
                key,
                value,
                min,
                max,
            } => write!(
                f,
                "`{key}` = {value} is outside [{min:.4e}, {max:.4e}], where the discrete \
                 algorithm is stable at this sample rate"
            ),
        }
    }
}
