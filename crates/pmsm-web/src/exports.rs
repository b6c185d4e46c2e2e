//! The WebAssembly functions the page's worker calls (web/worker.js).
//!
//! Contract: the worker asks [`wb_request`] for a buffer of `len` bytes, writes a UTF-8
//! JSON request into it, and calls one operation; the operation answers a status (0 done,
//! 1 failed: the answer names the error and its key) and leaves a UTF-8 JSON answer at
//! [`wb_answer`] (`wb_answer_len` bytes), and after [`wb_finish`] the run's columns at
//! [`wb_series`] (`wb_series_len` `f32` values). Pointers are offsets into the module's
//! memory, valid until the next call. One caller at a time (a worker is single-threaded).
//!
//! Their names begin with `wb_`, apart from the C library's `pmsm_*` (a program may link both).
//!
//! The only unsafe code is the `#[unsafe(no_mangle)]` that exports each function under its
//! name; every body is safe Rust on buffers the module owns.
#![allow(unsafe_code)]

use crate::{IdentifyAsk, LoadRequest, ScenarioRequest, Workbench, error_answer};
use anyhow::Result;
use serde::de::DeserializeOwned;
use serde_json::{Value, json};
use std::cell::RefCell;

/// The module's buffers and the workbench between calls.
#[derive(Default)]
struct State {
    request: Vec<u8>,
    answer: Vec<u8>,
    series: Vec<f32>,
    bench: Workbench,
}

thread_local! {
    static STATE: RefCell<State> = RefCell::new(State::default());
}

/// A buffer of `len` bytes for the next request; its address.
#[unsafe(no_mangle)]
pub extern "C" fn wb_request(len: usize) -> usize {
    STATE.with_borrow_mut(|s| {
        s.request.clear();
        s.request.resize(len, 0);
        s.request.as_ptr() as usize
    })
}

/// The address of the last answer.
#[unsafe(no_mangle)]
pub extern "C" fn wb_answer() -> usize {
    STATE.with_borrow(|s| s.answer.as_ptr() as usize)
}

/// The length of the last answer, bytes.
#[unsafe(no_mangle)]
pub extern "C" fn wb_answer_len() -> usize {
    STATE.with_borrow(|s| s.answer.len())
}

/// The address of the last run's columns (`f32`).
#[unsafe(no_mangle)]
pub extern "C" fn wb_series() -> usize {
    STATE.with_borrow(|s| s.series.as_ptr() as usize)
}

/// The number of `f32` values at [`wb_series`].
#[unsafe(no_mangle)]
pub extern "C" fn wb_series_len() -> usize {
    STATE.with_borrow(|s| s.series.len())
}

/// Runs `op` on the request just written, parsed as `T`; stores its answer.
fn call<T: DeserializeOwned>(op: impl FnOnce(&mut Workbench, T) -> Result<Value>) -> u32 {
    STATE.with_borrow_mut(|s| {
        let answer = serde_json::from_slice::<T>(&s.request)
            .map_err(|e| anyhow::anyhow!("the page's request: {e}"))
            .and_then(|request| op(&mut s.bench, request))
            .unwrap_or_else(|e| error_answer(&e));
        let failed = answer.get("ok") != Some(&Value::Bool(true));
        s.answer = answer.to_string().into_bytes();
        u32::from(failed)
    })
}

/// Reads a scenario file and the motor files it names ([`Workbench::load`]).
#[unsafe(no_mangle)]
pub extern "C" fn wb_load() -> u32 {
    call(|b, r: LoadRequest| b.load(&r))
}

/// Reads a motor file's text ([`Workbench::motor`]); the request is a JSON string.
#[unsafe(no_mangle)]
pub extern "C" fn wb_motor() -> u32 {
    call(|b, text: String| b.motor(&text))
}

/// Checks a scenario ([`Workbench::check`]).
#[unsafe(no_mangle)]
pub extern "C" fn wb_check() -> u32 {
    call(|b, r: ScenarioRequest| Ok(b.check(&r)))
}

/// Starts a run ([`Workbench::start`]).
#[unsafe(no_mangle)]
pub extern "C" fn wb_start() -> u32 {
    call(|b, r: ScenarioRequest| b.start(&r))
}

/// Steps the run `samples` samples ([`Workbench::advance`]): the fraction done, or −1 on
/// an error (the answer says which).
#[unsafe(no_mangle)]
pub extern "C" fn wb_advance(samples: u32) -> f64 {
    STATE.with_borrow_mut(|s| match s.bench.advance(samples as usize) {
        Ok(done) => done,
        Err(e) => {
            s.answer = error_answer(&e).to_string().into_bytes();
            -1.0
        }
    })
}

/// Ends the run ([`Workbench::finish`]): the summary as the answer, the columns at
/// [`wb_series`].
#[unsafe(no_mangle)]
pub extern "C" fn wb_finish() -> u32 {
    STATE.with_borrow_mut(|s| {
        let answer = match s.bench.finish() {
            Ok((answer, series)) => {
                s.series = series;
                answer
            }
            Err(e) => {
                s.series.clear();
                error_answer(&e)
            }
        };
        let failed = answer.get("ok") != Some(&json!(true));
        s.answer = answer.to_string().into_bytes();
        u32::from(failed)
    })
}

/// Identifies a motor ([`Workbench::identify`]).
#[unsafe(no_mangle)]
pub extern "C" fn wb_identify() -> u32 {
    call(|b, r: IdentifyAsk| b.identify(&r))
}

/// The files to take away ([`Workbench::export`]).
#[unsafe(no_mangle)]
pub extern "C" fn wb_export() -> u32 {
    call(|b, r: ScenarioRequest| b.export(&r))
}
