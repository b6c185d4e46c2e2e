//! `pmsm simulate --fault-dump`: a locked rotor trips the drive, the fault recorder's samples
//! before the trip are written, and `pmsm observe` replays them.

mod common;

use common::{pmsm, read_columns, s, scratch};
use std::path::Path;

fn examples() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../examples")
        .canonicalize()
        .unwrap()
}

/// Column `name` of a CSV file whose cells may be text (parsed as NaN).
fn column(path: &Path, name: &str) -> Vec<f64> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let k = lines
        .next()
        .unwrap()
        .split(',')
        .position(|c| c == name)
        .unwrap_or_else(|| panic!("{}: no column {name}", path.display()));
    lines
        .map(|l| l.split(',').nth(k).unwrap().parse().unwrap_or(f64::NAN))
        .collect()
}

#[test]
fn locked_rotor_dump_replays_with_observe() {
    let dir = scratch("fault-dump");
    let motor = examples().join("motor-b.toml");
    let text = std::fs::read_to_string(examples().join("b-800rpm-load.toml"))
        .unwrap()
        .replace(
            "motor = \"motor-b.toml\"",
            &format!("motor = \"{}\"", motor.display()),
        )
        + "\n[faults]\nlocked_rotor_at_s = 1.3\n";
    // The MRAS's design gains: their estimate follows the locked rotor down and the stall
    // check trips 150 ms later, so the dump holds the stop for the replay (with the low-speed
    // schedule's raised gains the estimate falls so fast that loss_of_lock trips within 1 ms).
    // Without the injection, which takes the angle below 6 % of rated speed and would fill the
    // dump's last samples with its square wave, a voltage the replayed NLO does not model.
    let text = text.replace(
        "[control]\n",
        "[control]\nmras_low_speed_schedule = false\ninjection = false\n",
    );
    let scenario = dir.join("locked.toml");
    std::fs::write(&scenario, text).unwrap();
    let (out, dump, replay) = (
        dir.join("run.csv"),
        dir.join("dump.csv"),
        dir.join("replay.csv"),
    );
    let r = pmsm(&[
        "simulate",
        s(&scenario),
        "--output",
        s(&out),
        "--fault-dump",
        s(&dump),
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));

    // The dump: 8192 uniform samples ending at the run's first faulted sample (state 5).
    let t = column(&dump, "t_s");
    let state = column(&dump, "state");
    assert_eq!(t.len(), 8192);
    let ts = 1.0 / 14_000.0;
    for w in t.windows(2) {
        assert!(
            (w[1] - w[0] - ts).abs() < 1e-9,
            "non-uniform step {}",
            w[1] - w[0]
        );
    }
    assert_eq!(*state.last().unwrap() as u8, 5);
    assert!(
        state[..state.len() - 1].iter().all(|&x| x as u8 == 4),
        "all in Run before the trip"
    );
    let run_t = column(&out, "t_s");
    let fault_names: Vec<String> = {
        let text = std::fs::read_to_string(&out).unwrap();
        let mut lines = text.lines();
        let k = lines
            .next()
            .unwrap()
            .split(',')
            .position(|c| c == "fault")
            .unwrap();
        lines
            .map(|l| l.split(',').nth(k).unwrap().to_owned())
            .collect()
    };
    let k_trip = fault_names.iter().position(|f| !f.is_empty()).unwrap();
    assert!((run_t[k_trip] - t[t.len() - 1]).abs() < 1e-9);
    let dt_ms = 1e3 * (run_t[k_trip] - 1.3);
    assert!(
        (0.0..200.0).contains(&dt_ms),
        "tripped {dt_ms} ms after the lock"
    );

    // The commanded voltage is the run's, sample for sample (same words, same bases).
    let k0 = k_trip + 1 - t.len();
    for c in ["v_alpha_v", "v_beta_v"] {
        let (d, o) = (column(&dump, c), column(&out, c));
        let worst = d
            .iter()
            .enumerate()
            .map(|(n, x)| (x - o[k0 + n]).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-9, "{c}: dump differs from the run by {worst} V");
    }
    // The sampled current matches the true one within the 12-bit ADC's resolution.
    let (ia, ib) = (column(&dump, "i_alpha_a"), column(&dump, "i_beta_a"));
    let (id, iq) = (column(&out, "i_d_a"), column(&out, "i_q_a"));
    let worst_i = (0..t.len())
        .map(|n| (ia[n].hypot(ib[n]) - id[k0 + n].hypot(iq[k0 + n])).abs())
        .fold(0.0, f64::max);
    println!("|i| dump vs true: worst {worst_i:.4} A");
    assert!(worst_i < 0.1, "sampled |i| off the true one by {worst_i} A");

    // Replay: the NLO on the dump follows the rotor while it turns and sees it stop. The NLO
    // models a surface motor and motor B is interior
    // (L_q/L_d = 1.6): its speed carries a saliency bias of about a quarter of the running
    // speed (measured: 67 rad/s at 251 rad/s, and 67 rad/s on the locked rotor), so the
    // bounds are 30 % of the running speed on either side of the lock.
    let r = pmsm(&[
        "observe",
        "--motor",
        s(&motor),
        "--observer",
        "nlo",
        "--voltage",
        "held",
        "--input",
        s(&dump),
        "--output",
        s(&replay),
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let est = read_columns(&replay);
    assert_eq!(est[0].len(), t.len());
    let w_truth = column(&dump, "omega_m_rad_s");
    let p: f64 = std::fs::read_to_string(&motor)
        .unwrap()
        .lines()
        .find_map(|l| l.strip_prefix("pole_pairs = "))
        .unwrap()
        .trim()
        .parse()
        .unwrap();
    let lock = t.iter().position(|&x| x >= 1.3).unwrap();
    let before = (lock.saturating_sub(140)..lock)
        .map(|n| (est[2][n] - p * w_truth[n]).abs())
        .fold(0.0, f64::max);
    let w_run = p * w_truth[lock - 1];
    println!("replay before the lock: worst |ω̂ − ω| {before:.2} rad/s at ω {w_run:.1} rad/s");
    assert!(
        w_run > 150.0,
        "the rotor was turning before the lock ({w_run} rad/s)"
    );
    assert!(
        before < 0.3 * w_run,
        "replay speed error {before} rad/s before the lock"
    );
    let end = est[2][t.len() - 100..]
        .iter()
        .map(|x| x.abs())
        .fold(0.0, f64::max);
    println!("replay at the trip: |ω̂| up to {end:.2} rad/s");
    assert!(
        end < 0.3 * w_run,
        "replay still sees {end} rad/s with the rotor locked"
    );
    std::fs::remove_dir_all(&dir).ok();
}
