//! The `## Operating map` section of `docs/PERFORMANCE.md`: how the points are run, per motor
//! a summary and the table of every point; and its place in the file, which `cargo xtask
//! perf` keeps.

use super::{
    ABOVE_MAX, BEFORE_LOAD_S, CASES, Case, Grid, HELD_ANGLE_RAD, HELD_SPEED, LOAD_RAMP_S,
    LOADS_PCT, Outcome, Point, SETTLE_S, WINDOW_S,
};
use std::fmt::Write as _;

/// The header of this command's section of `docs/PERFORMANCE.md`.
const HEADER: &str = "## Operating map";

/// Number format for a table cell: `-` for no value.
fn cell(x: f64, digits: usize) -> String {
    if x.is_finite() {
        // No "-0.00": a value that rounds to zero prints as zero.
        let zero = (x * 10f64.powi(digits as i32)).round() == 0.0;
        format!("{:.digits$}", if zero { 0.0 } else { x })
    } else {
        "-".into()
    }
}

/// The markdown section: how the points are run, then per motor the start-up check and the
/// table of every point.
pub fn section(grids: &[(Grid, Vec<(f64, &'static str)>)], startup_angles: usize) -> String {
    let mut s = format!(
        "{HEADER}\n\n\
         Regenerate with `cargo xtask map` (release build, one to two minutes on 2 cores), which \
         also draws `docs/figures/map-motor-a.svg`, `map-motor-b.svg`, `map-motor-c.svg`; \
         `cargo xtask perf` keeps this section as it is.\n\n\
         Steady operation over the torque–speed plane with MTPA and field weakening on (MTPA \
         changes nothing on the surface motor A) and the drive's default current limit, the \
         rated peak current. Each point is one `pmsm simulate` scenario: the fixed-point drive \
         against the plant with the switching-level inverter (dead time compensated), 12-bit \
         current ADC, the default d-axis saturation; the rotor starts at rest at θ_e = 0 (the \
         start-up from other angles is checked apart, below); after the start-up the speed \
         reference rises to the point's speed at {}, {BEFORE_LOAD_S} s later the load rises to \
         the point's torque in {LOAD_RAMP_S} s, and every figure is taken over the last \
         {WINDOW_S} s, {SETTLE_S} s after that. Speeds in % of rated ({}), and one more column \
         at {ABOVE_MAX} times the drive's maximum speed (`FluxConfig::max_speed`, \
         docs/field-weakening.md §3); loads in % of rated torque ({}), braking the rotor.\n\n\
         Columns: n, the mean true speed (r/min); position error rms (rad, in the closed loop); \
         speed error, mean |n − n*| in % of the reference n* (in r/min at n* = 0; for a refused \
         reference, against the speed the drive held instead); |i|, the mean magnitude of the true dq currents \
         (amplitude-invariant: the phase current's peak, A); i_d, its mean (A); m, the mean \
         |v*|/(V_DC/√3) of the commanded voltage (1 is the SVPWM's linear limit, field weakening \
         holds 0.97); P_cu, the mean 1.5·R·|i|² (W). Outcome: *held* (no fault, no refusal, \
         position error below {HELD_ANGLE_RAD} rad rms, speed within {:.0} % of the reference or of \
         10 % of rated speed below that); *refused* with the drive's reason \
         (`Drive::speed_ref_limit`: `below_estimator_minimum`, held at the least speed of a \
         back-EMF estimator; `above_max_speed`, clamped to the maximum speed); *fault* with its \
         name (figures left out: after a trip they describe a coasting or shorted motor); \
         *missed* when neither.\n\n",
        per_motor(&|c| format!("{} r/min/s", c.accel_rpm_s)),
        per_motor(&|c| format!("{} r/min", c.rated_rpm)),
        per_motor(&|c| format!("{} N·m", c.rated_nm)),
        100.0 * HELD_SPEED
    );
    for (g, failed) in grids {
        let c = &g.case;
        let points: Vec<&Point> = g.points.iter().flatten().collect();
        let _ = write!(
            s,
            "### {}\n\n{} V, {} kHz, {} µs dead time, start-up `{}`; maximum speed {:.0} r/min{}. {} of {} \
             points held; {}. Start-up from {startup_angles} initial angles (no load, to half rated \
             speed): {}.\n\n\
             | speed n* (r/min) | load (N·m) | outcome | n (r/min) | position error (rad) | \
             speed error | \\|i\\| (A) | i_d (A) | m | P_cu (W) |\n\
             |---|---|---|--:|--:|--:|--:|--:|--:|--:|\n",
            c.title,
            c.vdc_v,
            c.pwm_hz / 1e3,
            c.dead_time_s * 1e6,
            c.startup,
            g.max_rpm,
            if g.min_rpm > 0.0 {
                format!(", least closed-loop speed {:.0} r/min", g.min_rpm)
            } else {
                String::new()
            },
            points.iter().filter(|p| p.outcome == Outcome::Held).count(),
            points.len(),
            summary(g),
            if failed.is_empty() {
                "all reached the closed loop".to_owned()
            } else {
                format!(
                    "{} tripped ({})",
                    failed.len(),
                    failed
                        .iter()
                        .map(|(a, f)| format!("{a:.0}°: {f}"))
                        .collect::<Vec<_>>()
                        .join(", ")
                )
            }
        );
        for (l, row) in g.points.iter().enumerate() {
            for (k, p) in row.iter().enumerate() {
                let speed_err = if p.speed_err_pct.is_finite() {
                    format!("{:.2} %", p.speed_err_pct)
                } else if matches!(p.outcome, Outcome::Fault(..)) {
                    "-".into()
                } else {
                    format!("{:.1} r/min", p.speed_err_rpm)
                };
                let _ = writeln!(
                    s,
                    "| {} ({:.0}) | {:.0} % ({:.2}) | {} | {} | {} | {speed_err} | {} | {} | {} | {} |",
                    g.speed_labels[k],
                    g.speeds_rpm[k],
                    LOADS_PCT[l],
                    p.load_nm,
                    p.outcome.describe(),
                    cell(p.speed_rpm, 0),
                    cell(p.angle_rms_rad, 4),
                    cell(p.i_mag_a, 2),
                    cell(p.i_d_a, 2),
                    cell(p.modulation, 3),
                    cell(p.copper_w, 1),
                );
            }
        }
        s.push('\n');
    }
    s
}

/// `"A x, B y, C z"` over [`CASES`].
fn per_motor(f: &dyn Fn(&Case) -> String) -> String {
    CASES
        .iter()
        .map(|c| format!("{} {}", c.key.to_uppercase(), f(c)))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The points not held, by outcome: "refused above_max_speed: 3401 r/min × 0 %, …; …".
fn summary(g: &Grid) -> String {
    let mut groups: Vec<(String, Vec<String>)> = Vec::new();
    for (k, n) in g.speeds_rpm.iter().enumerate() {
        for (l, row) in g.points.iter().enumerate() {
            let kind = match &row[k].outcome {
                Outcome::Held => continue,
                Outcome::BelowMinimum(_) => "refused below_estimator_minimum".to_owned(),
                Outcome::AboveMax(_) => "refused above_max_speed".to_owned(),
                Outcome::Fault(name, _, stage) => format!("{name} {stage}"),
                Outcome::Missed(m) => match (m.current_limit, m.voltage_limit) {
                    (false, false) => "missed within both limits".to_owned(),
                    (true, false) => "missed at the current limit".to_owned(),
                    (false, true) => "missed at the voltage limit".to_owned(),
                    (true, true) => "missed at the current and voltage limits".to_owned(),
                },
            };
            let at = format!("{n:.0} r/min × {:.0} %", LOADS_PCT[l]);
            match groups.iter_mut().find(|(g, _)| *g == kind) {
                Some((_, v)) => v.push(at),
                None => groups.push((kind, vec![at])),
            }
        }
    }
    if groups.is_empty() {
        return "none refused, missed or faulted".into();
    }
    groups
        .iter()
        .map(|(kind, at)| format!("{kind}: {}", at.join(", ")))
        .collect::<Vec<_>>()
        .join("; ")
}

/// Where the operating-map section of `doc` starts and ends (at the next `## ` header or the
/// end).
fn find_section(doc: &str) -> Option<(usize, usize)> {
    let start = doc.find(&format!("{HEADER}\n"))?;
    let end = doc[start + HEADER.len()..]
        .find("\n## ")
        .map_or(doc.len(), |e| start + HEADER.len() + e + 1);
    Some((start, end))
}

/// `doc` with its operating-map section replaced by `section` (or inserted before the
/// instruction counts, or appended).
pub fn splice(doc: &str, section: &str) -> String {
    if let Some((start, end)) = find_section(doc) {
        return format!("{}{section}{}", &doc[..start], &doc[end..]);
    }
    match doc.find("## Instructions per call") {
        Some(at) => format!("{}{section}{}", &doc[..at], &doc[at..]),
        None => format!("{doc}{section}"),
    }
}

/// The operating-map section of `doc` ("" when there is none).
fn section_of(doc: &str) -> &str {
    find_section(doc).map_or("", |(start, end)| &doc[start..end])
}

/// The operating-map section of the `docs/PERFORMANCE.md` at hand, for `cargo xtask perf` to
/// keep.
pub fn kept_section() -> String {
    let doc =
        std::fs::read_to_string(crate::root().join("docs/PERFORMANCE.md")).unwrap_or_default();
    section_of(&doc).to_owned()
}

/// The compact view printed by the command: per motor, one line per load, each cell the
/// outcome's mark or the position error (rad) / speed error (%).
pub fn compact(g: &Grid) -> String {
    let mut s = format!(
        "motor {}: cells are position error rad rms / speed error %\n load  ",
        g.case.key
    );
    for l in &g.speed_labels {
        let _ = write!(s, "{l:>17}");
    }
    s.push('\n');
    for (l, row) in g.points.iter().enumerate().rev() {
        let _ = write!(s, "{:>4} %", LOADS_PCT[l]);
        for p in row {
            let c = match &p.outcome {
                Outcome::Fault(name, ..) => format!("F {name}"),
                o => format!(
                    "{}{:.4}/{}",
                    o.mark(),
                    p.angle_rms_rad,
                    if p.speed_err_pct.is_finite() {
                        format!("{:.2}", p.speed_err_pct)
                    } else {
                        format!("{:.0}rpm", p.speed_err_rpm)
                    }
                ),
            };
            let _ = write!(s, "{c:>17}");
        }
        s.push('\n');
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_section_is_replaced_in_place() {
        let doc = "# P\n\n## A\n\na\n\n## Operating map\n\nold\n\n## Instructions per call\n\nx\n";
        let new = splice(doc, "## Operating map\n\nnew\n\n");
        assert_eq!(
            new,
            "# P\n\n## A\n\na\n\n## Operating map\n\nnew\n\n## Instructions per call\n\nx\n"
        );
        let fresh = splice(
            "# P\n\n## Instructions per call\n\nx\n",
            "## Operating map\n\nm\n\n",
        );
        assert_eq!(
            fresh,
            "# P\n\n## Operating map\n\nm\n\n## Instructions per call\n\nx\n"
        );
        assert_eq!(
            splice("# P\n", "## Operating map\n"),
            "# P\n## Operating map\n"
        );
        // What `cargo xtask perf` keeps is what `cargo xtask map` wrote.
        assert_eq!(section_of(&new), "## Operating map\n\nnew\n\n");
        assert_eq!(
            section_of("# P\n\n## Operating map\n\nlast\n"),
            "## Operating map\n\nlast\n"
        );
        assert_eq!(section_of(doc.split("## Op").next().unwrap()), "");
    }
}
