//! Instructions per call on Cortex-M4 and Cortex-M0, from `scripts/pil.sh` (QEMU).

use std::collections::BTreeMap;
use std::process::Command;

/// The markdown section; says how to get it when QEMU is missing.
pub fn section() -> String {
    let mut s = String::from(
        "## Instructions per call on the MCUs (processor-in-the-loop)\n\n\
         `scripts/pil.sh` runs the core in QEMU (`qemu-system-arm`, `mps2-an386` Cortex-M4 and \
         `microbit` Cortex-M0, release builds) and counts instructions with SysTick under \
         `-icount` (calibrated exactly at every start; `examples/qemu/README.md`). Figures per \
         call over realistic inputs, mean and max; the replay compares the target's outputs \
         with the host's bit for bit.\n\n",
    );
    let out = Command::new("bash")
        .arg(super::root().join("scripts/pil.sh"))
        .output();
    let text = match out {
        Ok(o) if o.status.success() => String::from_utf8_lossy(&o.stdout).into_owned(),
        _ => {
            s.push_str("Not measured here: `scripts/pil.sh` did not pass (is `qemu-system-arm` installed?).\n\n");
            return s;
        }
    };
    // component -> [m4 mean, m4 max, m0 mean, m0 max]
    let mut table: BTreeMap<String, [String; 4]> = BTreeMap::new();
    let mut replay = Vec::new();
    let mut images = Vec::new();
    let mut closed = Vec::new();
    let mut per_sample = Vec::new();
    let mut loops = Vec::new();
    for line in text.lines() {
        let f: Vec<&str> = line.split_whitespace().collect();
        match f.as_slice() {
            ["PIL", cpu, "per_sample", mean, period] => per_sample.push(format!(
                "{cpu} {} instructions ({})",
                mean.trim_start_matches("insn_mean="),
                period.replace('=', " ")
            )),
            ["PIL", cpu, name, mean, max] if mean.starts_with("insn_mean=") => {
                let col = if *cpu == "cortex-m4" { 0 } else { 2 };
                let e = table.entry((*name).to_owned()).or_default();
                e[col] = mean.trim_start_matches("insn_mean=").to_owned();
                e[col + 1] = max.trim_start_matches("insn_max=").to_owned();
            }
            ["PIL", cpu, "replay", exact, steps] => replay.push(format!("{cpu}: {exact}, {steps}")),
            ["PIL", cpu, "image", exact, words] => images.push(format!("{cpu}: {exact}, {words}")),
            ["PIL", cpu, "closed_loop", exact, steps] => {
                closed.push(format!("{cpu}: {exact}, {steps}"))
            }
            ["PIL", cpu, name, exact, held] if name.starts_with("loop_") => loops.push(format!(
                "{cpu} {}: {exact}, {held}",
                name.trim_start_matches("loop_")
            )),
            _ => {}
        }
    }
    s.push_str("| component | M4 mean | M4 max | M0 mean | M0 max |\n|---|--:|--:|--:|--:|\n");
    for (name, v) in &table {
        s.push_str(&format!(
            "| {name} | {} | {} | {} | {} |\n",
            v[0], v[1], v[2], v[3]
        ));
    }
    s.push_str(&format!("\nReplay: {}.\n\n", replay.join("; ")));
    if !images.is_empty() {
        s.push_str(&format!(
            "Drive image (docs/image.md): the replayed drive's configuration written on the host, \
             read on the target and written again, and designed on the target and written, word \
             for word the host's: {}.\n\n",
            images.join("; ")
        ));
    }
    if !closed.is_empty() {
        s.push_str(&format!(
            "Closed loop on the target (the drive and the plant, motor B from rest, 0.1 s; \
             state, estimate, duty and the plant's `f64` state compared with the host's run): \
             {}.\n\n",
            closed.join("; ")
        ));
    }
    if !loops.is_empty() {
        s.push_str(&format!(
            "Published motors outside motor B's envelope, each with the drive's defaults for it \
             (examples/qemu/pil/src/loops.rs; `low_l`: the DJI 2212 drone outrunner, 17.6 µH, \
             `V_b·T_s/(L·I_b)` 1.43, 24 kHz; `high_p`: the Mini Cheetah actuator, 21 pole pairs, \
             40 kHz; both get the NLO) in a closed loop with an `f32` dq plant on the target, to \
             half rated speed: `isr_low_l`, `isr_high_p` and their tasks above, within the NLO's \
             budgets (2600 / 6500 and 4000 / 12000). Every step's outputs, the plant's included, \
             folded into a digest and compared with the host's run; the rotor held (angle within \
             0.15 rad, speed within 5 %): {}.\n\n",
            loops.join("; ")
        ));
    }
    let over = |x: &str, budget: u32| {
        x.parse::<u32>().map_or("?".to_owned(), |n| {
            format!(
                "{n} (budget {budget}: {})",
                if n <= budget { "met" } else { "NOT met" }
            )
        })
    };
    if let Some(v) = table.get("isr_mras_current") {
        s.push_str(&format!(
            "The drive's interrupt step (`DriveIsr::step`, docs/drive.md \"two rates\"), \
             current-model MRAS, worst case: Cortex-M4 {}, Cortex-M0 {}.\n\n",
            over(&v[1], 1500),
            over(&v[3], 4000)
        ));
    }
    if let Some(v) = table.get("isr_flux") {
        s.push_str(&format!(
            "The same with MTPA and field weakening on (`isr_flux`; their updates run in the \
             task, `task_flux`, docs/field-weakening.md \"Cost\"): Cortex-M4 {}, \
             Cortex-M0 {}.\n\n",
            over(&v[1], 1500),
            over(&v[3], 4000)
        ));
    }
    if let Some(v) = table.get("isr_saturated") {
        s.push_str(&format!(
            "With the voltage on the circle (`isr_saturated`: the default drive on the \
             same inputs with the bus read at a quarter of the recorded one, so that the current \
             loops' circle and the modulator's hexagon act; held to the budget like the \
             others): Cortex-M4 {}, Cortex-M0 {}; mean {} and {}.\n\n",
            over(&v[1], 1500),
            over(&v[3], 4000),
            v[0],
            v[2]
        ));
    }
    if let Some(v) = table.get("isr_bus_noise") {
        s.push_str(&format!(
            "With a bus reading that changes at every sample (`isr_bus_noise`: the default drive \
             on the same inputs, the reading moved by up to three steps of 1/2048 of itself at \
             each sample, as a 12-bit converter's does on a real board; reported, not held to a \
             budget): the bus terms of the modulator, the current loops' circle and the \
             dead-time compensation are kept while the reading stays within 0.2 % of the one \
             they were computed from (`BusReciprocal`), so they are taken once, not at every \
             step: Cortex-M4 {}, Cortex-M0 {}; mean {} and {}. The recorded runs read a \
             constant bus.\n\n",
            v[1], v[3], v[0], v[2]
        ));
    }
    if let Some(v) = table.get("task") {
        s.push_str(&format!(
            "The drive's task step (`DriveTask::step`, once per task period), worst case: \
             Cortex-M4 {}, Cortex-M0 {}.\n\n",
            over(&v[1], 4000),
            over(&v[3], 12000)
        ));
    }
    if let Some(v) = table.get("task_saturated") {
        s.push_str(&format!(
            "The same on the bus read at a quarter (`task_saturated`): Cortex-M4 {}, \
             Cortex-M0 {}.\n\n",
            over(&v[1], 4000),
            over(&v[3], 12000)
        ));
    }
    if let (Some(t), Some(u)) = (table.get("task"), table.get("task_tracker")) {
        let sum = |a: &str, b: &str| match (a.parse::<u32>(), b.parse::<u32>()) {
            (Ok(a), Ok(b)) => (a + b).to_string(),
            _ => "?".to_owned(),
        };
        s.push_str(&format!(
            "The tracker of `R` and `ψ` learning (`task_tracker`: `Tracker::task_step`, its \
             share of a task step, on motor B's steady states with the plant's `R` ×1.3, its \
             writes included; in the runs above it is frozen below its speed), worst case: \
             Cortex-M4 {}, Cortex-M0 {}. The task's worst case with the tracker learning is at \
             most `task`'s plus this: Cortex-M4 {}, Cortex-M0 {}.\n\n",
            u[1],
            u[3],
            over(&sum(&t[1], &u[1]), 4000),
            over(&sum(&t[3], &u[3]), 12000)
        ));
    }
    if !per_sample.is_empty() {
        s.push_str(&format!(
            "Both steps per sample (the interrupt's mean and the task's over its period): {}.\n\n",
            per_sample.join("; ")
        ));
    }
    s
}
