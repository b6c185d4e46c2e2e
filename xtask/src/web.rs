//! `cargo xtask web [--port N] [--no-build] [--no-serve]`: the workbench in a browser
//! (docs/workbench.md). Builds the WebAssembly module (`crates/pmsm-web`, profile `web`),
//! puts it beside the page (`web/`) and the shipped motors and scenarios under `target/workbench/`,
//! and serves that directory on 127.0.0.1 (default port 8080; 0 takes a free one) until
//! stopped. Nothing is fetched from elsewhere: the page has no library but its own files.

use crate::published;
use anyhow::{Context, Result, bail};
use serde_json::{Value, json};
use std::io::{BufRead, BufReader, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::Command;

/// The page's files, copied from `web/`.
const PAGE: [&str; 6] = [
    "index.html",
    "style.css",
    "app.js",
    "plot.js",
    "worker.js",
    "pmsm.js",
];

/// The usage line.
pub const USAGE: &str = "web [--port N] [--no-build] [--no-serve]";

/// Runs `cargo xtask web` with its arguments.
pub fn main(args: &[String]) -> Result<()> {
    let mut port = 8080u16;
    let (mut build, mut serve) = (true, true);
    let mut it = args.iter();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--port" => {
                let v = it.next().context("--port needs a number")?;
                port = v
                    .parse()
                    .with_context(|| format!("--port: {v:?} is not a port number (0–65535)"))?;
            }
            "--no-build" => build = false,
            "--no-serve" => serve = false,
            other => bail!("unknown argument {other:?}; usage: cargo xtask {USAGE}"),
        }
    }
    let root = crate::root();
    let dir = root.join("target/workbench");
    if build {
        assemble(&root, &dir)?;
    } else if !dir.join("pmsm_web.wasm").exists() {
        bail!(
            "{}: no workbench built; run `cargo xtask web` without --no-build",
            dir.display()
        );
    }
    if serve {
        serve_dir(&dir, port)?;
    }
    Ok(())
}

/// Builds the module and writes the page, the module and `examples.json` into `dir`.
fn assemble(root: &Path, dir: &Path) -> Result<()> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let status = Command::new(cargo)
        .current_dir(root)
        .args([
            "build",
            "--locked",
            "-p",
            "pmsm-web",
            "--profile",
            "web",
            "--target",
            "wasm32-unknown-unknown",
        ])
        .status()
        .context("running cargo")?;
    if !status.success() {
        bail!(
            "building the WebAssembly module failed (is the target installed? \
             `rustup target add wasm32-unknown-unknown`)"
        );
    }
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    for f in PAGE {
        std::fs::copy(root.join("web").join(f), dir.join(f))
            .with_context(|| format!("copying web/{f}"))?;
    }
    std::fs::copy(
        root.join("target/wasm32-unknown-unknown/web/pmsm_web.wasm"),
        dir.join("pmsm_web.wasm"),
    )
    .context("copying the module")?;
    let examples = shipped(root)?;
    std::fs::write(dir.join("examples.json"), examples.to_string())
        .context("writing examples.json")?;
    println!("workbench built in target/workbench/");
    Ok(())
}

/// The shipped scenarios and motor files of `examples/` (their text, named by their path
/// from the repository's root) and the published motors with their inverters.
fn shipped(root: &Path) -> Result<Value> {
    let mut scenarios = Vec::new();
    let mut motors = Vec::new();
    let mut paths: Vec<PathBuf> = std::fs::read_dir(root.join("examples"))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    paths.sort();
    for p in paths {
        let text = std::fs::read_to_string(&p)?;
        let file = p.file_name().unwrap_or_default().to_string_lossy();
        let entry = json!({ "path": format!("examples/{file}"), "file": file, "text": text });
        if text.lines().any(|l| l.starts_with("duration_s")) {
            scenarios.push(entry);
        } else {
            motors.push(entry);
        }
    }
    let published: Vec<Value> = published::read(&root.join(published::MOTORS))?
        .iter()
        .map(|m| {
            json!({
                "name": m.name,
                "class": m.class,
                "source": m.source,
                "motor": {
                    "name": m.name,
                    "pole_pairs": m.pole_pairs,
                    "rs_ohm": m.rs_ohm,
                    "ld_h": m.ld_h,
                    "lq_h": m.lq_h,
                    "flux_wb": m.flux_wb,
                    "j_kg_m2": m.j_kg_m2,
                    "b_nm_s": m.b_nm_s,
                    "rated_current_a": m.rated_current_a,
                    "rated_speed_rpm": m.rated_speed_rpm,
                },
                "inverter": { "vdc_v": m.vdc_v, "pwm_hz": m.pwm_hz, "dead_time_s": m.dead_time_s },
            })
        })
        .collect();
    Ok(json!({ "scenarios": scenarios, "motors": motors, "published": published }))
}

/// Serves the files of `dir` on 127.0.0.1:`port` until the process is stopped.
fn serve_dir(dir: &Path, port: u16) -> Result<()> {
    let listener = TcpListener::bind(("127.0.0.1", port))
        .with_context(|| format!("127.0.0.1:{port} is taken; try --port 0 or another"))?;
    let addr = listener.local_addr()?;
    println!("workbench: http://{addr}/ (Ctrl-C stops it)");
    std::io::stdout().flush()?;
    for stream in listener.incoming() {
        let Ok(stream) = stream else { continue };
        let dir = dir.to_owned();
        std::thread::spawn(move || {
            if let Err(e) = answer(&dir, stream) {
                eprintln!("workbench: {e:#}");
            }
        });
    }
    Ok(())
}

/// Answers one request: a file of `dir` by its name, `index.html` for `/`, 404 otherwise.
fn answer(dir: &Path, mut stream: TcpStream) -> Result<()> {
    let mut line = String::new();
    let mut reader = BufReader::new(stream.try_clone()?);
    reader.read_line(&mut line)?;
    // The headers are read and ignored.
    let mut header = String::new();
    while reader.read_line(&mut header)? > 2 {
        header.clear();
    }
    let mut parts = line.split_whitespace();
    let (method, target) = (parts.next().unwrap_or(""), parts.next().unwrap_or("/"));
    let path = target.split(['?', '#']).next().unwrap_or("/");
    let name = match path.trim_start_matches('/') {
        "" => "index.html",
        n => n,
    };
    let file = (method == "GET" && !name.contains("..") && !name.contains('/'))
        .then(|| dir.join(name))
        .and_then(|p| std::fs::read(p).ok());
    let Some(body) = file else {
        let msg = b"not found\n";
        write!(
            stream,
            "HTTP/1.1 404 Not Found\r\nContent-Type: text/plain\r\nContent-Length: {}\r\nConnection: close\r\n\r\n",
            msg.len()
        )?;
        stream.write_all(msg)?;
        return Ok(());
    };
    let kind = match name.rsplit('.').next() {
        Some("html") => "text/html; charset=utf-8",
        Some("js") => "text/javascript; charset=utf-8",
        Some("css") => "text/css; charset=utf-8",
        Some("json") => "application/json",
        Some("wasm") => "application/wasm",
        _ => "application/octet-stream",
    };
    write!(
        stream,
        "HTTP/1.1 200 OK\r\nContent-Type: {kind}\r\nContent-Length: {}\r\nCache-Control: no-store\r\nConnection: close\r\n\r\n",
        body.len()
    )?;
    stream.write_all(&body)?;
    Ok(())
}
