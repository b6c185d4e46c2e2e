//! Writes the recorded scenario of the C replays (see `tests/common/scenario.rs`) to the file
//! named by the first argument: `cargo run -p pmsm-ffi --example record -- out.bin`.

#[path = "../tests/common/scenario.rs"]
mod scenario;

fn main() {
    let Some(path) = std::env::args_os().nth(1) else {
        eprintln!("usage: record OUT.bin");
        std::process::exit(2);
    };
    let rows = scenario::record();
    let states = rows.iter().fold([0usize; 6], |mut n, r| {
        if let Some(c) = n.get_mut(r[scenario::Word::State as usize] as usize) {
            *c += 1;
        }
        n
    });
    if let Err(e) = std::fs::write(&path, scenario::encode(&rows)) {
        eprintln!("record: {}: {e}", std::path::Path::new(&path).display());
        std::process::exit(1);
    }
    println!(
        "recorded {} steps to {} (samples per state idle/ipd/align/open-loop/run/fault: {states:?})",
        rows.len(),
        std::path::Path::new(&path).display()
    );
}
