//! The heat maps of `cargo xtask map`: one SVG per motor, one panel per quantity, the cells
//! marked where the drive refused the reference or tripped. Plain SVG text: the time-series
//! plots of `pmsm_cli::plot` have no categorical grid.

use super::{Grid, LOADS_PCT, Outcome, Point};
use std::fmt::Write as _;

/// One panel: title, unit (for the colour bar), the value of a point, logarithmic scale.
struct Quantity {
    title: &'static str,
    unit: &'static str,
    value: fn(&Point) -> f64,
    log: bool,
}

const QUANTITIES: [Quantity; 6] = [
    Quantity {
        title: "position error, rms",
        unit: "rad",
        value: |p| p.angle_rms_rad,
        log: true,
    },
    Quantity {
        title: "speed error, mean |n − n*| / n*",
        unit: "%",
        value: |p| p.speed_err_pct,
        log: true,
    },
    Quantity {
        title: "current magnitude |i_dq| (phase peak)",
        unit: "A",
        value: |p| p.i_mag_a,
        log: false,
    },
    Quantity {
        title: "d-axis current i_d",
        unit: "A",
        value: |p| p.i_d_a,
        log: false,
    },
    Quantity {
        title: "modulation index |v*| / (V_DC/√3)",
        unit: "",
        value: |p| p.modulation,
        log: false,
    },
    Quantity {
        title: "copper loss 1.5·R·|i_dq|²",
        unit: "W",
        value: |p| p.copper_w,
        log: false,
    },
];

/// Panel size and the grid inside it, px.
const PANEL_W: f64 = 600.0;
const PANEL_H: f64 = 250.0;
const GRID_X: f64 = 78.0;
const GRID_Y: f64 = 30.0;
const GRID_W: f64 = 440.0;
const GRID_H: f64 = 160.0;
const HEADER_H: f64 = 80.0;
const FOOTER_H: f64 = 70.0;

/// The smallest value a logarithmic scale shows (below it, the bottom colour).
const LOG_FLOOR: f64 = 1e-4;

/// Viridis at `t` in [0, 1], from five stops.
fn colour(t: f64) -> (u8, u8, u8) {
    const STOPS: [(f64, f64, f64); 5] = [
        (68.0, 1.0, 84.0),
        (59.0, 82.0, 139.0),
        (33.0, 145.0, 140.0),
        (94.0, 201.0, 98.0),
        (253.0, 231.0, 37.0),
    ];
    let x = t.clamp(0.0, 1.0) * 4.0;
    let k = (x.floor() as usize).min(3);
    let f = x - k as f64;
    let (a, b) = (STOPS[k], STOPS[k + 1]);
    let mix = |p: f64, q: f64| (p + f * (q - p)).round() as u8;
    (mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

/// A cell's number in at most six characters.
fn short(x: f64) -> String {
    let a = x.abs();
    // Below what the figures resolve (rounding noise of a current at rest): zero.
    if a < 5e-5 {
        "0".into()
    } else if a >= 100.0 {
        format!("{x:.0}")
    } else if a >= 10.0 {
        format!("{x:.1}")
    } else if a >= 0.1 {
        format!("{x:.2}")
    } else if a >= 0.01 {
        format!("{x:.3}")
    } else {
        format!("{x:.0e}")
    }
}

/// A fault's name as short as a cell allows.
fn fault_tag(name: &str) -> &str {
    match name {
        "loss_of_lock" => "lock",
        "overcurrent" => "I>",
        "overspeed" => "n>",
        "driven_backwards" => "back",
        "initial_position" => "ipd",
        "bus_overvoltage" => "V>",
        "bus_undervoltage" => "V<",
        other => other.get(..5).unwrap_or(other),
    }
}

/// The scale of one quantity over the finite values: `(lo, hi, log)`.
fn scale(values: &[f64], log: bool) -> (f64, f64) {
    let finite = values.iter().copied().filter(|x| x.is_finite());
    let (mut lo, mut hi) = finite.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
        (a.min(x), b.max(x))
    });
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    if log {
        lo = lo.max(LOG_FLOOR).log10();
        hi = hi.max(LOG_FLOOR).log10();
    }
    if hi - lo < 1e-9 {
        (lo - 0.5, hi + 0.5)
    } else {
        (lo, hi)
    }
}

/// Where `x` falls on the scale, in [0, 1].
fn position(x: f64, (lo, hi): (f64, f64), log: bool) -> f64 {
    let v = if log { x.max(LOG_FLOOR).log10() } else { x };
    ((v - lo) / (hi - lo)).clamp(0.0, 1.0)
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// The SVG of `g`.
pub fn draw(g: &Grid) -> String {
    let width = 2.0 * PANEL_W;
    let height = HEADER_H + 3.0 * PANEL_H + FOOTER_H;
    let mut s = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{width}\" height=\"{height}\" \
         viewBox=\"0 0 {width} {height}\" font-family=\"sans-serif\">\n\
         <rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n"
    );
    let c = &g.case;
    let _ = writeln!(
        s,
        "<text x=\"20\" y=\"24\" font-size=\"17\">Operating map: {}</text>\n\
         <text x=\"20\" y=\"46\" font-size=\"12\">{} V, {} kHz, switching inverter, MTPA and field \
         weakening on, the drive's default current limit (rated peak); rated {:.0} r/min and {} \
         N·m (100 % load, braking the rotor).</text>\n\
         <text x=\"20\" y=\"64\" font-size=\"12\">Maximum speed n_max = {:.0} r/min. Each \
         cell: the steady window (last 0.3 s) of one run from standstill, built and measured by \
         cargo xtask map.</text>",
        escape(c.title),
        c.vdc_v,
        c.pwm_hz / 1e3,
        c.rated_rpm,
        c.rated_nm,
        g.max_rpm
    );
    for (k, q) in QUANTITIES.iter().enumerate() {
        let x = PANEL_W * (k % 2) as f64;
        let y = HEADER_H + PANEL_H * (k / 2) as f64;
        panel(&mut s, g, q, x, y);
    }
    let fy = HEADER_H + 3.0 * PANEL_H + 10.0;
    let lines = [
        "Marks: <tspan font-weight=\"bold\">min</tspan> refused below the estimator's least speed \
         (below_estimator_minimum): the drive holds that speed, and the errors are against it;",
        "<tspan font-weight=\"bold\">max</tspan> refused above the maximum speed \
         (above_max_speed): clamped to n_max, the errors against it; \
         <tspan font-weight=\"bold\">×</tspan> missed the reference without a fault;",
        "<tspan font-weight=\"bold\">F</tspan> fault (lock: loss_of_lock, stall, I&gt;: \
         overcurrent, n&gt;: overspeed): dark, no figures; grey: no value (zero reference). \
         Every figure: docs/PERFORMANCE.md, Operating map.",
    ];
    for (k, line) in lines.iter().enumerate() {
        let _ = writeln!(
            s,
            "<text x=\"20\" y=\"{:.1}\" font-size=\"12\">{line}</text>",
            fy + 18.0 * k as f64
        );
    }
    s.push_str("</svg>\n");
    s
}

/// One quantity's panel with its top-left corner at `(x, y)`.
fn panel(s: &mut String, g: &Grid, q: &Quantity, x: f64, y: f64) {
    let values: Vec<f64> = g.points.iter().flatten().map(q.value).collect();
    let range = scale(&values, q.log);
    let cols = g.speeds_rpm.len();
    let rows = LOADS_PCT.len();
    let (cw, ch) = (GRID_W / cols as f64, GRID_H / rows as f64);
    let (gx, gy) = (x + GRID_X, y + GRID_Y);
    let _ = writeln!(
        s,
        "<text x=\"{}\" y=\"{}\" font-size=\"14\">{}{}</text>",
        x + 20.0,
        y + 20.0,
        escape(q.title),
        if q.unit.is_empty() {
            String::new()
        } else {
            format!(" ({})", q.unit)
        }
    );
    for (l, row) in g.points.iter().enumerate() {
        // 100 % load on top.
        let cy = gy + (rows - 1 - l) as f64 * ch;
        for (k, p) in row.iter().enumerate() {
            let cx = gx + k as f64 * cw;
            let v = (q.value)(p);
            let (fill, ink) = match (&p.outcome, v.is_finite()) {
                (Outcome::Fault(..), _) => ("#3a3a3a".to_owned(), "white"),
                (_, false) => ("#d9d9d9".to_owned(), "black"),
                (_, true) => {
                    let t = position(v, range, q.log);
                    let (r, gg, b) = colour(t);
                    (
                        format!("#{r:02x}{gg:02x}{b:02x}"),
                        if t < 0.6 { "white" } else { "black" },
                    )
                }
            };
            let _ = writeln!(
                s,
                "<rect x=\"{cx:.1}\" y=\"{cy:.1}\" width=\"{cw:.1}\" height=\"{ch:.1}\" \
                 fill=\"{fill}\" stroke=\"white\" stroke-width=\"1\"><title>{:.0} r/min, {:.2} \
                 N·m: {}</title></rect>",
                g.speeds_rpm[k],
                p.load_nm,
                escape(&p.outcome.describe())
            );
            let text = match &p.outcome {
                Outcome::Fault(name, ..) => format!("F {}", fault_tag(name)),
                _ if v.is_finite() => short(v),
                _ => "–".into(),
            };
            let _ = writeln!(
                s,
                "<text x=\"{:.1}\" y=\"{:.1}\" font-size=\"9\" text-anchor=\"middle\" \
                 fill=\"{ink}\">{}</text>",
                cx + cw / 2.0,
                cy + ch / 2.0 + 6.0,
                escape(&text)
            );
            let mark = match &p.outcome {
                Outcome::Fault(..) => "",
                o => o.mark(),
            };
            if !mark.is_empty() {
                let _ = writeln!(
                    s,
                    "<text x=\"{:.1}\" y=\"{:.1}\" font-size=\"8\" font-weight=\"bold\" \
                     fill=\"{ink}\">{mark}</text>",
                    cx + 2.0,
                    cy + 9.0
                );
            }
        }
    }
    // Axes: loads on the left, speeds (% of rated, r/min) below.
    for (l, pct) in LOADS_PCT.iter().enumerate() {
        let cy = gy + (rows - 1 - l) as f64 * ch + ch / 2.0 + 4.0;
        let _ = writeln!(
            s,
            "<text x=\"{:.1}\" y=\"{cy:.1}\" font-size=\"10\" text-anchor=\"end\">{pct:.0} %</text>",
            gx - 5.0
        );
    }
    let _ = writeln!(
        s,
        "<text transform=\"translate({:.1},{:.1}) rotate(-90)\" font-size=\"10\" \
         text-anchor=\"middle\">load, % of rated torque</text>",
        x + 22.0,
        gy + GRID_H / 2.0
    );
    for (k, label) in g.speed_labels.iter().enumerate() {
        let cx = gx + (k as f64 + 0.5) * cw;
        let _ = writeln!(
            s,
            "<text x=\"{cx:.1}\" y=\"{:.1}\" font-size=\"9\" text-anchor=\"middle\">{}</text>\n\
             <text x=\"{cx:.1}\" y=\"{:.1}\" font-size=\"9\" text-anchor=\"middle\" \
             fill=\"#555\">{:.0}</text>",
            gy + GRID_H + 12.0,
            escape(label),
            gy + GRID_H + 23.0,
            g.speeds_rpm[k]
        );
    }
    let _ = writeln!(
        s,
        "<text x=\"{:.1}\" y=\"{:.1}\" font-size=\"10\" text-anchor=\"middle\">speed reference, \
         % of rated (r/min below)</text>",
        gx + GRID_W / 2.0,
        gy + GRID_H + 38.0
    );
    colour_bar(s, q, range, gx + GRID_W + 22.0, gy);
}

/// The colour bar of a panel at `(x, y)`, `GRID_H` tall, with its unit and ticks.
fn colour_bar(s: &mut String, q: &Quantity, (lo, hi): (f64, f64), x: f64, y: f64) {
    const STEPS: usize = 40;
    let h = GRID_H / STEPS as f64;
    for k in 0..STEPS {
        let t = (k as f64 + 0.5) / STEPS as f64;
        let (r, g, b) = colour(t);
        let _ = writeln!(
            s,
            "<rect x=\"{x:.1}\" y=\"{:.2}\" width=\"14\" height=\"{:.2}\" \
             fill=\"#{r:02x}{g:02x}{b:02x}\"/>",
            y + GRID_H - (k + 1) as f64 * h,
            h + 0.3
        );
    }
    let _ = writeln!(
        s,
        "<text x=\"{x:.1}\" y=\"{:.1}\" font-size=\"10\">{}</text>",
        y - 6.0,
        if q.unit.is_empty() { "pu" } else { q.unit }
    );
    // Ticks: both ends with their values, and the decades between on a logarithmic scale
    // (five even steps on a linear one).
    let value = |t: f64| if q.log { 10f64.powf(t) } else { t };
    let mut ticks: Vec<f64> = vec![lo, hi];
    if q.log {
        ticks.extend(
            (lo.ceil() as i32..=hi.floor() as i32)
                .map(f64::from)
                .filter(|t| (t - lo).min(hi - t) > 0.12 * (hi - lo)),
        );
    } else {
        ticks.extend((1..4).map(|k| lo + (hi - lo) * k as f64 / 4.0));
    }
    for t in ticks {
        let ty = y + GRID_H * (1.0 - (t - lo) / (hi - lo));
        let label = short(value(t));
        let _ = writeln!(
            s,
            "<line x1=\"{:.1}\" x2=\"{:.1}\" y1=\"{ty:.1}\" y2=\"{ty:.1}\" stroke=\"black\"/>\n\
             <text x=\"{:.1}\" y=\"{:.1}\" font-size=\"9\">{label}</text>",
            x + 14.0,
            x + 18.0,
            x + 20.0,
            ty + 3.0
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::CASES;

    fn point(outcome: Outcome, x: f64) -> Point {
        Point {
            load_nm: 1.0,
            outcome,
            angle_rms_rad: x,
            speed_rpm: 100.0,
            speed_err_rpm: x,
            speed_err_pct: x,
            i_mag_a: x,
            i_d_a: -x,
            modulation: x,
            copper_w: x,
        }
    }

    #[test]
    fn cells_carry_their_outcome_and_the_scales_their_units() {
        let nan = f64::NAN;
        let row = |k: usize| {
            vec![
                point(Outcome::Held, 0.001 * (k + 1) as f64),
                point(Outcome::AboveMax(900.0), 0.01),
                point(Outcome::Fault("loss_of_lock", 1.0, "under load"), nan),
            ]
        };
        let g = Grid {
            case: CASES[1],
            max_rpm: 800.0,
            min_rpm: 0.0,
            speeds_rpm: vec![0.0, 300.0, 880.0],
            speed_labels: vec!["0 %".into(), "10 %".into(), "1.1·n_max".into()],
            points: (0..LOADS_PCT.len()).map(row).collect(),
        };
        let svg = draw(&g);
        // Six panels, each with the marks of its 15 cells.
        assert_eq!(svg.matches("F lock</text>").count(), 6 * LOADS_PCT.len());
        assert_eq!(svg.matches(">max</text>").count(), 6 * LOADS_PCT.len());
        for unit in [
            ">rad</text>",
            ">%</text>",
            ">A</text>",
            ">pu</text>",
            ">W</text>",
        ] {
            assert!(svg.contains(unit), "{unit}");
        }
        // The logarithmic scale spans 1e-3 … 1e-2: both ends labelled.
        assert!(svg.contains(">1e-3</text>") && svg.contains(">0.010</text>"));
        assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
    }

    #[test]
    fn viridis_ends_and_short_numbers() {
        assert_eq!(colour(0.0), (68, 1, 84));
        assert_eq!(colour(1.0), (253, 231, 37));
        assert_eq!(colour(2.0), colour(1.0));
        assert_eq!(short(0.00031), "3e-4");
        assert_eq!(short(-2.126), "-2.13");
        assert_eq!(short(137.9), "138");
        assert_eq!(short(-4e-16), "0");
    }
}
