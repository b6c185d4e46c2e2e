// The workbench in a real browser: Debian's Chromium, headless, driven by Playwright.
//
// Needs `cargo xtask web --no-serve` (the page and the module) and the release `pmsm` and
// `xtask` binaries built; serves the page with `xtask web --no-build --port 0` and checks:
//   - no request leaves 127.0.0.1;
//   - the shipped scenario examples/b-800rpm-load.toml gives the summary `pmsm simulate`
//     prints, character for character, in at most twice the native run's time;
//   - the page answers while a run goes on (a click, and the event loop never held 100 ms),
//     shows its progress, and a run can be cancelled;
//   - a negative inductance shows the drive's message by its field and runs nothing;
//   - Identify on motor B prints what `pmsm identify` prints;
//   - a screenshot is saved to target/workbench-test/workbench.png.
// Exits non-zero on the first failed check. Run from the repository: `node web/test/e2e.mjs`.

import { chromium } from "playwright-core";
import { execFileSync, spawn } from "node:child_process";
import { mkdirSync } from "node:fs";
import path from "node:path";
import { fileURLToPath } from "node:url";

const root = path.resolve(path.dirname(fileURLToPath(import.meta.url)), "../..");
const out = path.join(root, "target/workbench-test");
mkdirSync(out, { recursive: true });
const bin = (name) => path.join(root, "target/release", name);
const SCENARIO = "examples/b-800rpm-load.toml";

function check(ok, what) {
  if (!ok) {
    console.error(`FAIL ${what}`);
    process.exit(1);
  }
  console.log(`ok   ${what}`);
}

/** Runs `pmsm` with `args` from the repository's root: its standard output and wall time. */
function pmsm(args) {
  const t0 = performance.now();
  const stdout = execFileSync(bin("pmsm"), args, { cwd: root, encoding: "utf8" });
  return { stdout, ms: performance.now() - t0 };
}

/** A report's lines up to (not with) the line naming its output file. */
function report(stdout) {
  const lines = stdout.split("\n");
  const end = lines.findIndex((l) => l.startsWith("  output "));
  return lines.slice(0, end < 0 ? lines.length : end).join("\n").trimEnd();
}

// The native figures.
let nativeMs = Infinity;
let native = "";
for (let k = 0; k < 3; k++) {
  const r = pmsm(["simulate", SCENARIO, "--output", path.join(out, "native.csv")]);
  nativeMs = Math.min(nativeMs, r.ms);
  native = report(r.stdout);
}
const identifyNative = report(
  pmsm([
    "identify", "--motor", "examples/motor-b.toml", "--vdc", "540", "--pwm-hz", "14000",
    "--dead-time-s", "2e-6", "--output", path.join(out, "identified.toml"),
  ]).stdout,
);

// The server.
const server = spawn(bin("xtask"), ["web", "--no-build", "--port", "0"], { cwd: root });
const base = await new Promise((resolve, reject) => {
  let text = "";
  server.stdout.on("data", (d) => {
    text += d;
    const m = text.match(/http:\/\/127\.0\.0\.1:\d+\//);
    if (m) resolve(m[0]);
  });
  server.on("exit", (code) => reject(new Error(`the server exited (${code})`)));
  setTimeout(() => reject(new Error("the server did not start")), 20000);
});

const browser = await chromium.launch({
  executablePath: process.env.CHROMIUM || "/usr/bin/chromium",
  args: [
    "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
    "--disable-background-networking", "--disable-component-update", "--disable-sync",
  ],
});
try {
  const page = await browser.newPage({ viewport: { width: 1400, height: 1100 } });
  const requests = [];
  page.on("request", (r) => requests.push(r.url()));
  const problems = [];
  page.on("pageerror", (e) => problems.push(String(e)));
  await page.goto(base);
  await page.waitForSelector("body[data-ready=true]", { timeout: 30000 });
  check(problems.length === 0, `the page loads without a script error ${problems.join("; ")}`);
  check(
    (await page.inputValue("#scenario-select")) === SCENARIO,
    `the page opens on ${SCENARIO}`,
  );

  // Runs, best of three like the native figure; the event loop watched meanwhile.
  let pageMs = Infinity;
  let summary = "";
  for (let k = 0; k < 3; k++) {
    await page.evaluate(() => {
      window.__gaps = [];
      let last = performance.now();
      window.__watch = setInterval(() => {
        const now = performance.now();
        window.__gaps.push([now - last, now]);
        last = now;
      }, 5);
    });
    await page.click("#run");
    await page.waitForFunction(() => document.getElementById("run-time").dataset.ms, null, {
      timeout: 60000,
    });
    const r = await page.evaluate(() => {
      clearInterval(window.__watch);
      const t = document.getElementById("run-time");
      const ms = Number(t.dataset.ms);
      const doneAt = Number(t.dataset.doneAt);
      delete t.dataset.ms;
      // While it ran: up to the result's arrival (drawing it is the page's own work).
      const gaps = window.__gaps.filter(([, at]) => at <= doneAt).map(([g]) => g);
      return { ms, gap: Math.max(0, ...gaps), summary: document.getElementById("summary").textContent };
    });
    pageMs = Math.min(pageMs, r.ms);
    summary = r.summary.trimEnd();
    check(r.gap < 100, `run ${k + 1}: the page's event loop never held more than 100 ms while it ran (${r.gap.toFixed(0)} ms)`);
  }
  if (summary !== native) {
    console.error(`page:\n${summary}\nnative:\n${native}`);
  }
  check(summary === native, "the page's summary is pmsm simulate's, character for character");
  console.log(`     native ${nativeMs.toFixed(0)} ms, page ${pageMs.toFixed(0)} ms (ratio ${(pageMs / nativeMs).toFixed(2)})`);
  check(pageMs <= 2 * nativeMs, "the page runs the scenario in at most twice the native time");

  // A run answered while it goes on, its progress shown, and cancelled.
  await page.fill('[data-path="duration_s"]', "20");
  await page.waitForFunction(() => !document.getElementById("run").disabled);
  await page.click("#run");
  await page.waitForFunction(() => {
    const v = document.getElementById("progress").value;
    return v > 0.02 && v < 1;
  });
  const t0 = Date.now();
  await page.click("#pin");
  const clickMs = Date.now() - t0;
  check(await page.isChecked("#pin"), `a click is answered during a run (${clickMs} ms)`);
  await page.click("#pin");
  await page.click("#cancel");
  await page.waitForFunction(() => document.getElementById("status").textContent === "cancelled");
  check(!(await page.isDisabled("#run")), "a run is cancelled and the page can run again");
  await page.fill('[data-path="duration_s"]', "2");

  // A bad value: the drive's message by the field, nothing run.
  const before = await page.textContent("#summary");
  await page.fill('[data-path="motor.ld_h"]', "-0.025025");
  await page.waitForFunction(
    () => document.querySelector('[data-error-for="motor.ld_h"]').textContent.includes("ld_h"),
  );
  const message = await page.textContent('[data-error-for="motor.ld_h"]');
  check(/`ld_h` must be greater than zero/.test(message), `a negative L_d is named: "${message}"`);
  check(await page.isDisabled("#run"), "Run is refused while a value is out of range");
  await page.evaluate(() => document.getElementById("run").click());
  await page.waitForTimeout(300);
  check((await page.textContent("#summary")) === before, "nothing runs with the bad value");
  check(
    (await page.inputValue('[data-path="motor.ld_h"]')) === "-0.025025",
    "the typed value stays in the field",
  );
  await page.fill('[data-path="motor.ld_h"]', "0.025025");
  await page.waitForFunction(() => !document.getElementById("run").disabled);

  // Identify: pmsm identify's figures.
  await page.click("#identify");
  await page.waitForFunction(() => document.getElementById("identify-report").textContent, null, {
    timeout: 60000,
  });
  const identified = (await page.textContent("#identify-report")).trimEnd();
  if (identified !== identifyNative) {
    console.error(`page:\n${identified}\nnative:\n${identifyNative}`);
  }
  check(identified === identifyNative, "Identify prints pmsm identify's figures");

  // Export, and the picture for a person.
  await page.click("#export");
  await page.waitForFunction(() => document.getElementById("ex-c").value.includes("pmsm_config_t"));
  check(true, "Export writes the scenario, the motor and the C configuration");
  await page.screenshot({ path: path.join(out, "workbench.png"), fullPage: true });
  console.log(`     screenshot: ${path.relative(root, path.join(out, "workbench.png"))}`);

  const foreign = requests.filter((u) => !u.startsWith(base) && !u.startsWith("blob:"));
  check(foreign.length === 0, `every request went to ${base} (${requests.length} requests) ${foreign.join(" ")}`);
} finally {
  await browser.close();
  server.kill();
}
