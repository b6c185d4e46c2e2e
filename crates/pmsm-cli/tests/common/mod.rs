//! What the end-to-end tests of `pmsm` share: a scratch folder, running the binary, reading
//! its CSV output.

#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// A fresh folder for one test's files.
pub fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("pmsm-test-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Runs the `pmsm` binary of this build.
pub fn pmsm(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_pmsm"))
        .args(args)
        .output()
        .unwrap()
}

/// Runs `pmsm`, expects a failure, and returns its stderr, which must be exactly one line.
pub fn one_line_error(args: &[&str]) -> String {
    let r = pmsm(args);
    let err = String::from_utf8_lossy(&r.stderr).into_owned();
    assert!(!r.status.success(), "expected a failure: {args:?}");
    assert_eq!(err.lines().count(), 1, "{err}");
    err
}

/// The columns of a numeric CSV file with a header.
pub fn read_columns(path: &Path) -> Vec<Vec<f64>> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let width = lines.next().unwrap().split(',').count();
    let mut cols = vec![Vec::new(); width];
    for l in lines {
        for (c, x) in cols.iter_mut().zip(l.split(',')) {
            c.push(x.parse::<f64>().unwrap());
        }
    }
    cols
}

/// `path` as `&str`.
pub fn s(path: &Path) -> &str {
    path.to_str().unwrap()
}

/// `examples/name` of the repository.
pub fn example(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../examples")
        .join(name)
}

/// A scenario read from `text`, its `motor = "…"` path taken relative to `examples/` (written
/// to a file of its own: tests of one binary run in parallel).
pub fn scenario_text(tag: &str, text: &str) -> pmsm_cli::scenario_file::Scenario {
    use std::sync::atomic::{AtomicUsize, Ordering};
    static N: AtomicUsize = AtomicUsize::new(0);
    let path = std::env::temp_dir().join(format!(
        "pmsm-scenario-{}-{}-{tag}.toml",
        std::process::id(),
        N.fetch_add(1, Ordering::Relaxed)
    ));
    let motor_dir = example("").canonicalize().unwrap();
    let text = text.replace("motor = \"", &format!("motor = \"{}/", motor_dir.display()));
    std::fs::write(&path, text).unwrap();
    let sc = pmsm_cli::scenario_file::read(&path);
    std::fs::remove_file(&path).ok();
    sc.unwrap()
}

/// The shipped scenario `name` with text replacements, each of which must apply.
pub fn example_edited(name: &str, edits: &[(&str, &str)]) -> pmsm_cli::scenario_file::Scenario {
    let mut text = std::fs::read_to_string(example(name)).unwrap();
    for (from, to) in edits {
        assert!(text.contains(from), "{name} has no `{from}`");
        text = text.replace(from, to);
    }
    scenario_text(name, &text)
}
