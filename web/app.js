// The workbench page: a form over a scenario (the JSON image of a scenario file, every key
// kept, the motor inline), the worker that runs it, and the plots of the result.
// docs/workbench.md describes the page; crates/pmsm-web the module behind it.

import { Plots } from "./plot.js";

// Each field: the scenario key it edits, its label, unit, kind and, for a choice, the values
// ("" is the default: the key is left out and the drive computes it from the motor).
const FIELDS = {
  motor: [
    ["motor.name", "name", "", "text"],
    ["motor.pole_pairs", "pole pairs", "", "int"],
    ["motor.rs_ohm", "R (phase)", "Ω", "num"],
    ["motor.ld_h", "L_d", "H", "num"],
    ["motor.lq_h", "L_q", "H", "num"],
    ["motor.flux_wb", "ψ (PM flux, peak)", "Wb", "num"],
    ["motor.j_kg_m2", "J (rotor)", "kg·m²", "num"],
    ["motor.b_nm_s", "B (friction)", "N·m·s", "num"],
    ["motor.rated_current_a", "rated current", "A rms", "num"],
    ["motor.rated_speed_rpm", "rated speed", "r/min", "num"],
  ],
  inverter: [
    ["inverter.vdc_v", "DC bus", "V", "num"],
    ["inverter.pwm_hz", "PWM frequency", "Hz", "num"],
    ["inverter.dead_time_s", "dead time", "s", "num"],
    ["inverter.model", "inverter model", "", "choice", ["averaged", "switching"]],
    ["inverter.current_full_scale_a", "ADC full scale", "A", "num"],
    ["sensing.adc_bits", "ADC resolution", "bits", "int"],
    ["sensing.noise_rms_a", "ADC noise", "A rms", "num"],
  ],
  control: [
    ["control.observer", "estimator", "", "choice", ["auto", "mras-current", "nlo", "ao", "mras-emf"]],
    ["control.startup", "start-up", "", "choice", ["auto", "ipd", "align", "known"]],
    ["control.mtpa", "MTPA", "", "bool"],
    ["control.field_weakening", "field weakening", "", "bool"],
    ["control.overmodulation", "overmodulation", "", "bool"],
    ["control.tracking", "R/ψ tracking", "", "bool"],
    ["control.injection", "HF injection at standstill", "", "bool"],
    ["control.current_bandwidth_hz", "current loop bandwidth", "Hz", "num"],
    ["control.speed_bandwidth_hz", "speed loop bandwidth", "Hz", "num"],
  ],
  run: [
    ["duration_s", "duration", "s", "num"],
    ["initial.theta_e_deg", "initial rotor angle", "° electrical", "num"],
  ],
};

const PANELS = [
  { title: "speed (r/min)", lines: [
    { key: "speed_ref_rpm", label: "reference" },
    { key: "speed_rpm", label: "true" },
    { key: "speed_est_rpm", label: "estimated" }] },
  { title: "angle error, estimated − true (rad, electrical)", lines: [
    { key: "angle_err_rad", label: "error" }] },
  { title: "current in the rotor frame (A)", lines: [
    { key: "i_d_a", label: "i_d" },
    { key: "i_q_a", label: "i_q" },
    { key: "i_q_ref_a", label: "i_q reference" }] },
  { title: "duties", lines: [
    { key: "duty_a", label: "a" },
    { key: "duty_b", label: "b" },
    { key: "duty_c", label: "c" }] },
];

const $ = (id) => document.getElementById(id);

const state = {
  name: "scenario.toml",
  scenario: null,
  examples: null,
  /** Fields whose text is not a value of their kind: path → message. */
  typed: new Map(),
  valid: false,
  running: false,
  last: null,
};

// ---------------------------------------------------------------- the worker

let module = null;
let worker = null;
let nextId = 1;
const waiting = new Map();

function startWorker() {
  worker = new Worker("worker.js", { type: "module" });
  worker.onmessage = (event) => {
    const msg = event.data;
    const w = waiting.get(msg.id);
    if (!w) return;
    if (msg.type === "progress") {
      w.progress?.(msg.done);
      return;
    }
    waiting.delete(msg.id);
    if (msg.type === "error") w.reject(new Error(`the drive's module failed: ${msg.error}`));
    else w.resolve(msg);
  };
  worker.onerror = (e) => {
    for (const w of waiting.values()) w.reject(new Error(e.message || "the worker failed"));
    waiting.clear();
  };
  worker.postMessage({ type: "init", module });
}

function post(message, progress) {
  const id = nextId++;
  return new Promise((resolve, reject) => {
    waiting.set(id, { resolve, reject, progress });
    worker.postMessage({ ...message, id });
  });
}

async function call(op, request) {
  return (await post({ type: "call", op, request })).answer;
}

function cancelWorker() {
  worker.terminate();
  for (const w of waiting.values()) w.reject(new Error("cancelled"));
  waiting.clear();
  startWorker();
}

// ---------------------------------------------------------------- the form

function get(path) {
  return path.split(".").reduce((o, k) => (o == null ? undefined : o[k]), state.scenario);
}

function set(path, value) {
  const keys = path.split(".");
  let o = state.scenario;
  for (const k of keys.slice(0, -1)) {
    if (typeof o[k] !== "object" || o[k] === null) o[k] = {};
    o = o[k];
  }
  const last = keys[keys.length - 1];
  if (value === undefined) delete o[last];
  else o[last] = value;
  // An emptied table goes: its defaults are the file's.
  if (keys.length > 1 && keys[0] !== "motor" && Object.keys(o).length === 0) delete state.scenario[keys[0]];
}

function buildForm() {
  for (const [group, fields] of Object.entries(FIELDS)) {
    const box = document.querySelector(`.fields[data-group="${group}"]`);
    for (const [path, label, unit, kind, choices] of fields) {
      const id = `f-${path.replace(/\./g, "-")}`;
      const l = document.createElement("label");
      l.htmlFor = id;
      const key = path.split(".").pop();
      l.innerHTML = `${label} <code class="key">${key}</code>${unit ? ` <span class="unit">(${unit})</span>` : ""}`;
      let input;
      if (kind === "choice" || kind === "bool") {
        input = document.createElement("select");
        const values = kind === "bool" ? ["on", "off"] : choices;
        input.add(new Option("(default)", ""));
        for (const v of values) input.add(new Option(v, v));
        input.addEventListener("change", () => edited(input));
      } else {
        input = document.createElement("input");
        input.type = "text";
        input.inputMode = kind === "text" ? "text" : "decimal";
        input.placeholder = "(default)";
        input.addEventListener("input", () => edited(input));
      }
      input.id = id;
      input.dataset.path = path;
      input.dataset.kind = kind;
      const err = document.createElement("span");
      err.className = "field-error";
      err.dataset.errorFor = path;
      box.append(l, input, err);
    }
  }
}

/** Shows the scenario's values in the form (the typed text is replaced: a new scenario). */
function fillForm() {
  state.typed.clear();
  for (const input of document.querySelectorAll("[data-path]")) {
    const v = get(input.dataset.path);
    if (input.dataset.kind === "bool") input.value = v === true ? "on" : v === false ? "off" : "";
    else input.value = v === undefined ? "" : String(v);
  }
  fillProfiles();
}

/** A field's text as a value of its kind; `undefined` for empty (the default). */
function parse(kind, text) {
  const t = text.trim();
  if (t === "") return { value: undefined };
  if (kind === "text" || kind === "choice") return { value: t };
  if (kind === "bool") return { value: t === "on" };
  const x = Number(t);
  if (!Number.isFinite(x)) return { error: `"${t}" is not a number` };
  if (kind === "int" && !Number.isInteger(x)) return { error: `"${t}" is not a whole number` };
  return { value: x };
}

function edited(input) {
  const { path, kind } = input.dataset;
  const p = parse(kind, input.value);
  if (p.error) {
    state.typed.set(path, p.error);
  } else {
    state.typed.delete(path);
    set(path, p.value);
  }
  scheduleCheck();
}

// ---------------------------------------------------------------- speed and load tables

function fillProfiles() {
  profileTable($("speed-table"), "speed_ref", "rpm", "r/min");
  profileTable($("load-table"), "load", "nm", "N·m");
}

function profileTable(table, key, valueKey, unit) {
  const caption = table.caption;
  table.replaceChildren(caption);
  const head = table.insertRow();
  head.innerHTML = `<th>t (s)</th><th>${unit}</th><th></th>`;
  const p = state.scenario[key] || { t_s: [], [valueKey]: [] };
  p.t_s.forEach((t, k) => {
    const row = table.insertRow();
    for (const [arr, v] of [["t_s", t], [valueKey, p[valueKey][k]]]) {
      const input = document.createElement("input");
      input.value = String(v);
      input.dataset.profile = `${key}.${arr}.${k}`;
      input.addEventListener("input", () => {
        const x = parse("num", input.value);
        const path = `${key}.${arr}.${k}`;
        input.classList.toggle("invalid", Boolean(x.error) || x.value === undefined);
        if (x.error || x.value === undefined) {
          state.typed.set(path, x.error || "empty");
        } else {
          state.typed.delete(path);
          state.scenario[key][arr][k] = x.value;
        }
        scheduleCheck();
      });
      row.insertCell().appendChild(input);
    }
    const del = document.createElement("button");
    del.type = "button";
    del.textContent = "−";
    del.title = "remove this breakpoint";
    del.addEventListener("click", () => {
      p.t_s.splice(k, 1);
      p[valueKey].splice(k, 1);
      if (p.t_s.length === 0) delete state.scenario[key];
      fillProfiles();
      scheduleCheck();
    });
    row.insertCell().appendChild(del);
  });
  const add = document.createElement("button");
  add.type = "button";
  add.textContent = "+ breakpoint";
  add.addEventListener("click", () => {
    const q = (state.scenario[key] ||= { t_s: [], [valueKey]: [] });
    const t = q.t_s.length ? q.t_s[q.t_s.length - 1] + 0.1 : 0;
    q.t_s.push(Number(t.toFixed(6)));
    q[valueKey].push(q[valueKey].length ? q[valueKey][q[valueKey].length - 1] : 0);
    fillProfiles();
    scheduleCheck();
  });
  table.insertRow().insertCell().appendChild(add);
}

/** Speed and load breakpoints of a preset, from the motor's ratings. */
function preset(name) {
  const m = state.scenario.motor || {};
  const rated = m.rated_speed_rpm || 1000;
  const torque = m.rated_current_a
    ? 1.5 * (m.pole_pairs || 1) * (m.flux_wb || 0) * Math.SQRT2 * m.rated_current_a
    : 0;
  const round = (x) => Number(x.toPrecision(4));
  const half = round(rated / 2);
  const table = {
    start: [1.0, [[0, 0], [0.1, 0], [0.6, half]], [[0, 0]]],
    "load-step": [2.0, [[0, 0], [0.1, 0], [0.6, half]], [[0, 0], [1.0, 0], [1.01, round(torque)]]],
    reversal: [2.5, [[0, 0], [0.1, 0], [0.6, half], [1.2, half], [1.8, -half]], [[0, 0], [0.7, 0], [0.71, round(0.2 * torque)]]],
    "low-speed": [2.0, [[0, 0], [0.1, 0], [0.6, round(rated / 20)]], [[0, 0], [1.0, 0], [1.01, round(0.2 * torque)]]],
  }[name];
  const [duration, speed, load] = table;
  state.scenario.duration_s = duration;
  state.scenario.speed_ref = { t_s: speed.map((x) => x[0]), rpm: speed.map((x) => x[1]) };
  state.scenario.load = { t_s: load.map((x) => x[0]), nm: load.map((x) => x[1]) };
  fillForm();
  scheduleCheck();
}

// ---------------------------------------------------------------- checks and errors

let checkTimer = null;

function scheduleCheck() {
  state.valid = false;
  updateButtons();
  clearTimeout(checkTimer);
  checkTimer = setTimeout(check, 250);
}

/** Checks the scenario with the drive's own validation; shows the errors by their fields. */
async function check() {
  clearTimeout(checkTimer);
  for (const e of document.querySelectorAll(".field-error")) e.textContent = "";
  for (const i of document.querySelectorAll("[data-path]")) i.classList.remove("invalid");
  $("error").textContent = "";
  for (const [path, message] of state.typed) showError(path, message);
  if (state.typed.size > 0) {
    state.valid = false;
    updateButtons();
    return false;
  }
  const answer = await call("check", { name: state.name, scenario: state.scenario });
  state.valid = answer.ok;
  if (answer.ok) {
    $("chosen").textContent = `estimator ${answer.estimator}${answer.estimator_auto ? " (chosen for this motor)" : ""}, start-up ${answer.startup}, ${answer.samples} samples at ${answer.sample_hz} Hz`;
  } else {
    $("chosen").textContent = "";
    showError(answer.key, answer.error);
  }
  updateButtons();
  return answer.ok;
}

/** Shows `message` by the field of `key` (`ld_h`, `inverter.vdc_v`, …), else above Run. */
function showError(key, message) {
  const inputs = [...document.querySelectorAll("[data-path]")];
  const input = key && (inputs.find((i) => i.dataset.path === key) ||
    inputs.find((i) => i.dataset.path.endsWith(`.${key}`)));
  if (input) {
    input.classList.add("invalid");
    document.querySelector(`[data-error-for="${input.dataset.path}"]`).textContent = message;
    input.closest("details").open = true;
  }
  $("error").textContent = message;
}

function updateButtons() {
  const ready = module !== null && state.scenario !== null;
  $("run").disabled = !ready || state.running || !state.valid;
  $("cancel").disabled = !state.running;
  $("identify").disabled = !ready || state.running;
  $("export").disabled = !ready || state.running || !state.valid;
}

// ---------------------------------------------------------------- run, identify, export

async function run() {
  // From the click: the check, the run, the columns' transfer.
  const t0 = performance.now();
  if (!(await check())) return;
  state.running = true;
  updateButtons();
  $("progress").value = 0;
  $("status").textContent = "running…";
  $("run-time").textContent = "";
  try {
    const msg = await post(
      { type: "run", request: { name: state.name, scenario: state.scenario } },
      (done) => ($("progress").value = done),
    );
    if (msg.type === "answer") {
      showError(msg.answer.key, msg.answer.error);
      $("status").textContent = "not run: the scenario has an error";
      return;
    }
    const ms = performance.now() - t0;
    const result = { columns: msg.columns, faults: msg.answer.faults };
    if ($("pin").checked && state.last) plots.pin(state.last);
    else plots.pin(null);
    plots.show(result);
    state.last = result;
    $("summary").textContent = msg.answer.summary;
    $("progress").value = 1;
    $("run-time").textContent = `ran in ${(ms / 1000).toFixed(2)} s`;
    $("run-time").dataset.ms = String(ms);
    $("run-time").dataset.doneAt = String(t0 + ms);
    $("status").textContent = msg.answer.faults.length
      ? `done: ${msg.answer.faults.map((f) => `${f.fault} at ${f.t_s.toFixed(4)} s`).join(", ")}`
      : "done: no fault";
  } catch (e) {
    $("status").textContent = e.message === "cancelled" ? "cancelled" : e.message;
    $("progress").value = 0;
  } finally {
    state.running = false;
    updateButtons();
  }
}

async function identify() {
  const inv = state.scenario.inverter || {};
  $("status").textContent = "identifying…";
  $("identify").disabled = true;
  try {
    const answer = await call("identify", {
      motor: state.scenario.motor,
      vdc_v: inv.vdc_v,
      pwm_hz: inv.pwm_hz,
      dead_time_s: inv.dead_time_s ?? 0,
    });
    if (!answer.ok) {
      showError(answer.key, answer.error);
      $("status").textContent = "identification failed";
      return;
    }
    const t = $("identify-table");
    t.innerHTML = "<tr><th></th><th>identified</th><th>true</th><th>error</th></tr>";
    for (const r of answer.rows) {
      const err = r.true !== 0 ? `${(100 * (r.identified - r.true) / r.true).toFixed(2)} %` : "-";
      t.insertRow().innerHTML = `<td>${r.key}</td><td>${r.identified.toExponential(4)}</td><td>${r.true.toExponential(4)}</td><td>${err}</td>`;
    }
    $("identify-report").textContent = answer.report;
    $("identify-out").hidden = false;
    $("status").textContent = "identified";
  } catch (e) {
    $("status").textContent = e.message;
  } finally {
    updateButtons();
  }
}

async function exportFiles() {
  const answer = await call("export", { name: state.name, scenario: state.scenario });
  if (!answer.ok) {
    showError(answer.key, answer.error);
    return;
  }
  for (const [area, link, text] of [
    ["ex-scenario", "dl-scenario", answer.scenario_toml],
    ["ex-motor", "dl-motor", answer.motor_toml],
    ["ex-c", "dl-c", answer.c_config],
  ]) {
    $(area).value = text;
    const old = $(link).href;
    if (old.startsWith("blob:")) URL.revokeObjectURL(old);
    $(link).href = URL.createObjectURL(new Blob([text], { type: "text/plain" }));
  }
  $("export-out").hidden = false;
}

// ---------------------------------------------------------------- loading

function motorFiles() {
  const files = {};
  for (const m of state.examples.motors) files[m.file] = m.text;
  return files;
}

async function loadScenario(name, text) {
  const answer = await call("load", { name, text, files: motorFiles() });
  if (!answer.ok) {
    $("error").textContent = answer.error;
    return;
  }
  state.name = name;
  state.scenario = answer.scenario;
  fillForm();
  await check();
  $("status").textContent = `${name} loaded`;
}

async function loadMotorText(text) {
  const answer = await call("motor", text);
  if (!answer.ok) {
    $("error").textContent = answer.error;
    return false;
  }
  state.scenario.motor = answer.motor;
  fillForm();
  await check();
  return true;
}

function fillSelectors() {
  const s = $("scenario-select");
  for (const sc of state.examples.scenarios) s.add(new Option(sc.path, sc.path));
  s.addEventListener("change", () => {
    const sc = state.examples.scenarios.find((x) => x.path === s.value);
    if (sc) loadScenario(sc.path, sc.text);
  });
  const m = $("motor-select");
  m.add(new Option("(the scenario's)", ""));
  state.examples.motors.forEach((x, k) => m.add(new Option(x.path, `file:${k}`)));
  state.examples.published.forEach((x, k) => m.add(new Option(`${x.name} (${x.class})`, `pub:${k}`)));
  m.addEventListener("change", async () => {
    const [kind, k] = m.value.split(":");
    if (kind === "file") await loadMotorText(state.examples.motors[Number(k)].text);
    if (kind === "pub") {
      const p = state.examples.published[Number(k)];
      state.scenario.motor = structuredClone(p.motor);
      state.scenario.inverter = { ...(state.scenario.inverter || {}), ...p.inverter };
      fillForm();
      await check();
    }
  });
}

function acceptDrops() {
  window.addEventListener("dragover", (e) => {
    e.preventDefault();
    document.body.classList.add("dragging");
  });
  window.addEventListener("dragleave", () => document.body.classList.remove("dragging"));
  window.addEventListener("drop", async (e) => {
    e.preventDefault();
    document.body.classList.remove("dragging");
    const file = e.dataTransfer.files[0];
    if (!file) return;
    const text = await file.text();
    if (/^\s*duration_s\s*=/m.test(text)) await loadScenario(file.name, text);
    else await loadMotorText(text);
  });
}

let plots = null;

async function main() {
  buildForm();
  plots = new Plots($("plots"), PANELS);
  try {
    const [compiled, examples] = await Promise.all([
      WebAssembly.compileStreaming(fetch("pmsm_web.wasm")),
      fetch("examples.json").then((r) => r.json()),
    ]);
    module = compiled;
    state.examples = examples;
  } catch (e) {
    $("status").textContent = `the drive could not be loaded: ${e.message}`;
    return;
  }
  startWorker();
  fillSelectors();
  acceptDrops();
  $("run").addEventListener("click", run);
  $("cancel").addEventListener("click", cancelWorker);
  $("identify").addEventListener("click", identify);
  $("export").addEventListener("click", exportFiles);
  $("motor-paste-apply").addEventListener("click", () => loadMotorText($("motor-paste").value));
  for (const b of document.querySelectorAll("[data-preset]")) {
    b.addEventListener("click", () => preset(b.dataset.preset));
  }
  const first = state.examples.scenarios.find((x) => x.path === "examples/b-800rpm-load.toml") ||
    state.examples.scenarios[0];
  $("scenario-select").value = first.path;
  await loadScenario(first.path, first.text);
  document.body.dataset.ready = "true";
}

main();
