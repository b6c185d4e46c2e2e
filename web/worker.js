// The workbench's worker: runs the drive and the plant (pmsm_web.wasm) off the page's thread.
//
// Messages from the page:
//   { type: "init", module }                       the compiled module, once
//   { type: "call", id, op, request }              load | motor | check | identify | export
//   { type: "run", id, request }                   a scenario run, with progress
// Messages to the page:
//   { type: "answer", id, answer }
//   { type: "progress", id, done }                 fraction of the samples stepped
//   { type: "result", id, answer, columns, ms }    columns: Float32Arrays, transferred
//   { type: "error", id, error }                   the module trapped (a bug: say so)
// Cancelling a run is terminating the worker; the page starts another.

import { Pmsm } from "./pmsm.js";

let pmsm = null;
const pending = [];

/** Samples per step between two progress messages (a few ms of work each). */
const CHUNK = 1000;

function handle(msg) {
  const { id } = msg;
  try {
    if (msg.type === "call") {
      postMessage({ type: "answer", id, answer: pmsm.call(msg.op, msg.request) });
    } else if (msg.type === "run") {
      const t0 = performance.now();
      const started = pmsm.call("start", msg.request);
      if (!started.ok) {
        postMessage({ type: "answer", id, answer: started });
        return;
      }
      let done = 0;
      let shown = 0;
      while (done < 1) {
        done = pmsm.advance(CHUNK);
        if (done - shown >= 0.01 || done >= 1) {
          postMessage({ type: "progress", id, done });
          shown = done;
        }
      }
      const { answer, columns } = pmsm.finish();
      const ms = performance.now() - t0;
      postMessage(
        { type: "result", id, answer, columns, ms },
        Object.values(columns).map((c) => c.buffer),
      );
    }
  } catch (e) {
    postMessage({ type: "error", id, error: String(e && e.message ? e.message : e) });
  }
}

onmessage = async (event) => {
  const msg = event.data;
  if (msg.type === "init") {
    pmsm = await Pmsm.create(msg.module);
    pending.splice(0).forEach(handle);
    return;
  }
  if (pmsm === null) {
    pending.push(msg);
  } else {
    handle(msg);
  }
};
