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
            } => write!(
                f,
                "{quantity} = {value:.3e} is outside the supported envelope [{min:.3e}, {max:.3e}]"
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
