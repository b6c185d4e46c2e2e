//! The motor file (TOML, SI units), shared by every subcommand.
//!
//! ```toml
//! name = "motor A"
//! pole_pairs = 3
//! rs_ohm = 1.6
//! ld_h = 0.0134
//! lq_h = 0.0134
//! flux_wb = 0.288            # peak flux linkage, V·s/rad electrical
//! kt_nm_per_a = 1.108        # optional, default 1.5 · pole_pairs · flux_wb
//! j_kg_m2 = 0.04256
//! b_nm_s = 0.004256          # optional, default 0
//! rated_current_a = 6.1      # optional, A RMS
//! rated_speed_rpm = 1200     # optional
//! emf_h5 = 0.042             # optional 5th EMF harmonic, relative (surface model)
//! emf_h7 = 0.025             # optional 7th EMF harmonic, relative
//!
//! [saturation]               # optional; interior motors default to "tanh" scaled to the motor
//! model = "tanh"             # or "none" for linear magnetics
//! psi_s_wb = 0.5             # optional saturation flux of the tanh model, > flux_wb
//! ```
//!
//! Unknown keys, missing keys, values of the wrong type and values out of range are rejected
//! with one line naming the file, the line and the key.

use anyhow::{Result, anyhow};
use pmsm_core::{MotorParams, ParamError};
use pmsm_plant::{MotorModel, Saturation};
use serde::Deserialize;
use std::path::Path;

/// A motor as read from a file: its name and the plant model.
#[derive(Clone, Debug)]
pub struct Motor {
    /// `name`, or the file's stem.
    pub name: String,
    /// Parameters and the plant-only extras (saturation, EMF harmonics).
    pub model: MotorModel,
}

/// The raw contents of a motor file or an inline `motor` table.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawMotor {
    name: Option<String>,
    pole_pairs: i64,
    rs_ohm: f64,
    ld_h: f64,
    lq_h: f64,
    flux_wb: f64,
    kt_nm_per_a: Option<f64>,
    j_kg_m2: f64,
    #[serde(default)]
    b_nm_s: f64,
    rated_current_a: Option<f64>,
    rated_speed_rpm: Option<f64>,
    #[serde(default)]
    emf_h5: f64,
    #[serde(default)]
    emf_h7: f64,
    saturation: Option<RawSaturation>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSaturation {
    model: String,
    psi_s_wb: Option<f64>,
}

impl RawSaturation {
    /// The `[saturation]` table's model for the motor `params`.
    fn into_saturation(self, params: &MotorParams) -> Result<Saturation, ParamError> {
        use pmsm_core::ParamReason;
        match self.model.as_str() {
            "none" => {
                if self.psi_s_wb.is_some() {
                    return Err(ParamError {
                        key: "saturation.psi_s_wb",
                        reason: ParamReason::Inconsistent("model = \"none\""),
                    });
                }
                Ok(Saturation::Linear)
            }
            "tanh" => Ok(match self.psi_s_wb {
                Some(psi_s_wb) => Saturation::Tanh { psi_s_wb },
                // The default strength of the plant, also for a surface motor.
                None => Saturation::Tanh {
                    psi_s_wb: params.flux_wb
                        + pmsm_plant::saturation::DEFAULT_STRENGTH
                            * params.ld_h
                            * Saturation::reference_current_a(params),
                },
            }),
            _ => Err(ParamError {
                key: "saturation.model",
                reason: ParamReason::Inconsistent("the models \"tanh\" and \"none\""),
            }),
        }
    }
}

/// Reads and validates a motor file.
pub fn read(path: &Path) -> Result<Motor> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| anyhow!("{}: cannot read: {e}", path.display()))?;
    parse(&text, path)
}

/// Parses and validates the text of a motor file; `path` is used in messages.
pub fn parse(text: &str, path: &Path) -> Result<Motor> {
    let raw: RawMotor = toml::from_str(text).map_err(|e| toml_error(&e, text, path))?;
    let stem = path
        .file_stem()
        .map_or_else(|| "motor".to_owned(), |s| s.to_string_lossy().into_owned());
    raw.into_motor(&stem)
        .map_err(|e| anyhow!("{}: {e}", path.display()))
}

impl RawMotor {
    /// Validates the values and builds the plant model; the error names the key.
    pub fn into_motor(self, default_name: &str) -> Result<Motor, ParamError> {
        use pmsm_core::ParamReason;
        use pmsm_core::validate::in_range;
        let pole_pairs = u32::try_from(self.pole_pairs)
            .ok()
            .filter(|p| (1..=100).contains(p))
            .ok_or(ParamError {
                key: "pole_pairs",
                reason: ParamReason::OutOfRange {
                    min: 1.0,
                    max: 100.0,
                },
            })?;
        let params = MotorParams {
            pole_pairs,
            rs_ohm: self.rs_ohm,
            ld_h: self.ld_h,
            lq_h: self.lq_h,
            flux_wb: self.flux_wb,
            kt_nm_per_a: self
                .kt_nm_per_a
                .unwrap_or(1.5 * pole_pairs as f64 * self.flux_wb),
            j_kg_m2: self.j_kg_m2,
            b_nm_s: self.b_nm_s,
            rated_current_a: self.rated_current_a,
            rated_speed_rpm: self.rated_speed_rpm,
        };
        params.validate()?;
        in_range("emf_h5", self.emf_h5, 0.0, 0.5)?;
        in_range("emf_h7", self.emf_h7, 0.0, 0.5)?;
        let saturation = match self.saturation {
            None => Saturation::default_for(&params),
            Some(s) => s.into_saturation(&params)?,
        };
        let mut model = MotorModel::new(params);
        model.saturation = saturation;
        model.emf_h5 = self.emf_h5;
        model.emf_h7 = self.emf_h7;
        model.validate()?;
        Ok(Motor {
            name: self.name.unwrap_or_else(|| default_name.to_owned()),
            model,
        })
    }
}

/// One line from a TOML error: file, line, the key on that line, and what is wrong.
pub fn toml_error(e: &toml::de::Error, text: &str, path: &Path) -> anyhow::Error {
    let message = e.message().trim().replace('\n', " ");
    let span = e.span().filter(|_| !message.starts_with("missing field"));
    let Some(span) = span else {
        return anyhow!("{}: {message}", path.display());
    };
    let line_no = text
        .get(..span.start)
        .map_or(1, |t| t.matches('\n').count() + 1);
    let line = text.lines().nth(line_no - 1).unwrap_or("");
    match line.split_once('=') {
        Some((key, _)) => anyhow!(
            "{}:{line_no}: key `{}`: {message}",
            path.display(),
            key.trim()
        ),
        None => anyhow!("{}:{line_no}: {message}", path.display()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MOTOR_A: &str = r#"
name = "motor A"
pole_pairs = 3
rs_ohm = 1.6
ld_h = 0.0134
lq_h = 0.0134
flux_wb = 0.288
kt_nm_per_a = 1.108
j_kg_m2 = 0.04256
b_nm_s = 0.004256
"#;

    fn err(text: &str) -> String {
        format!("{:#}", parse(text, Path::new("m.toml")).unwrap_err())
    }

    #[test]
    fn reads_motor_a() {
        let m = parse(MOTOR_A, Path::new("m.toml")).unwrap();
        assert_eq!(m.name, "motor A");
        assert!((m.model.params.kt_nm_per_a - 1.108).abs() < 1e-12);
        assert!(matches!(m.model.saturation, Saturation::Linear));
    }

    #[test]
    fn unknown_key_is_named() {
        let e = err(&format!("{MOTOR_A}rs_mohm = 3\n"));
        assert!(e.starts_with("m.toml:11:"), "{e}");
        assert!(e.contains("rs_mohm"), "{e}");
    }

    #[test]
    fn bad_values_are_named() {
        let e = err(&MOTOR_A.replace("rs_ohm = 1.6", "rs_ohm = -1.6"));
        assert_eq!(e, "m.toml: `rs_ohm` must be greater than zero");
        let e = err(&MOTOR_A.replace("flux_wb = 0.288", "flux_wb = nan"));
        assert_eq!(e, "m.toml: `flux_wb` must be a finite number");
        let e = err(&MOTOR_A.replace("pole_pairs = 3", "pole_pairs = 0"));
        assert!(e.starts_with("m.toml: `pole_pairs` must lie in"), "{e}");
        let e = err(&MOTOR_A.replace("ld_h = 0.0134", "ld_h = \"small\""));
        assert!(e.starts_with("m.toml:5: key `ld_h`:"), "{e}");
        let e = err(&MOTOR_A.replace("j_kg_m2 = 0.04256\n", ""));
        assert!(e.contains("missing field `j_kg_m2`"), "{e}");
        let e = err(&format!("{MOTOR_A}[saturation]\nmodel = \"cubic\"\n"));
        assert!(e.contains("saturation.model"), "{e}");
    }

    #[test]
    fn saturation_table() {
        let b = MOTOR_A.replace("lq_h = 0.0134", "lq_h = 0.02");
        let m = parse(&b, Path::new("m.toml")).unwrap();
        assert!(matches!(m.model.saturation, Saturation::Tanh { .. }));
        let m = parse(
            &format!("{b}[saturation]\nmodel = \"none\"\n"),
            Path::new("m.toml"),
        )
        .unwrap();
        assert!(matches!(m.model.saturation, Saturation::Linear));
        let m = parse(
            &format!("{MOTOR_A}[saturation]\nmodel = \"tanh\"\npsi_s_wb = 0.5\n"),
            Path::new("m.toml"),
        )
        .unwrap();
        assert!(
            matches!(m.model.saturation, Saturation::Tanh { psi_s_wb } if (psi_s_wb - 0.5).abs() < 1e-12)
        );
    }
}
