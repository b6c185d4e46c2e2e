// The workbench's module: loads pmsm_web.wasm and calls its operations (crates/pmsm-web,
// src/exports.rs states the contract). Used by the worker and by Node in the tests.

const encoder = new TextEncoder();
const decoder = new TextDecoder();

export class Pmsm {
  /** `module`: a compiled WebAssembly.Module of pmsm_web.wasm. */
  static async create(module) {
    const instance = await WebAssembly.instantiate(module, {});
    return new Pmsm(instance);
  }

  constructor(instance) {
    this.x = instance.exports;
  }

  memory() {
    return new Uint8Array(this.x.memory.buffer);
  }

  write(request) {
    const bytes = encoder.encode(JSON.stringify(request));
    const at = this.x.wb_request(bytes.length);
    this.memory().set(bytes, at);
  }

  answer() {
    const at = this.x.wb_answer();
    const len = this.x.wb_answer_len();
    return JSON.parse(decoder.decode(this.memory().subarray(at, at + len)));
  }

  /** Calls operation `op` (load, motor, check, start, identify, export) on `request`. */
  call(op, request) {
    this.write(request);
    this.x[`wb_${op}`]();
    return this.answer();
  }

  /** Steps the run `samples` samples: the fraction done; throws the error on a failure. */
  advance(samples) {
    const done = this.x.wb_advance(samples);
    if (done < 0) {
      throw new Error(this.answer().error);
    }
    return done;
  }

  /** Ends the run: the answer and its columns (a copy, one Float32Array per column). */
  finish() {
    this.x.wb_finish();
    const answer = this.answer();
    const columns = {};
    if (answer.ok) {
      const at = this.x.wb_series();
      const all = new Float32Array(this.x.memory.buffer, at, this.x.wb_series_len());
      answer.columns.forEach((name, k) => {
        columns[name] = all.slice(k * answer.rows, (k + 1) * answer.rows);
      });
    }
    return { answer, columns };
  }
}
