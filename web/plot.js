// Stacked time plots on canvases, sharing one time axis: wheel zooms about the pointer, a drag
// pans, a double click shows the whole run. Each line is drawn from the minimum and maximum of
// the samples under each pixel column, so a long run draws as fast as a short one and no peak
// is lost. Faults are marked where they happened; a pinned run is drawn under the current one.

const COLOURS = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd"];
const PINNED = "#9a9a9a";
const MARGIN = { left: 64, right: 12, top: 22, bottom: 22 };

export class Plots {
  /**
   * `panels`: [{ title, lines: [{ key, label }] }]; the columns are the run's
   * (`t_s` and the keys).
   */
  constructor(container, panels) {
    this.panels = panels.map((p) => {
      const canvas = document.createElement("canvas");
      canvas.className = "plot";
      canvas.setAttribute("aria-label", p.title);
      container.appendChild(canvas);
      return { ...p, canvas };
    });
    this.run = null;
    this.pinned = null;
    this.view = null;
    this.panels.forEach((p) => this.listen(p.canvas));
    new ResizeObserver(() => this.draw()).observe(container);
  }

  /** Shows `run` ({ columns, faults }) over its whole time. */
  show(run) {
    this.run = run;
    const t = run.columns.t_s;
    this.view = t.length > 1 ? [t[0], t[t.length - 1]] : [0, 1];
    this.draw();
  }

  /** Draws `run` (or nothing, for null) in grey under the next ones. */
  pin(run) {
    this.pinned = run;
    this.draw();
  }

  listen(canvas) {
    let drag = null;
    canvas.addEventListener("wheel", (e) => {
      if (!this.view) return;
      e.preventDefault();
      const x = this.timeAt(canvas, e.offsetX);
      const k = e.deltaY > 0 ? 1.25 : 0.8;
      const [a, b] = this.view;
      this.setView([x - (x - a) * k, x + (b - x) * k]);
    });
    canvas.addEventListener("pointerdown", (e) => {
      if (!this.view) return;
      drag = { x: e.offsetX, view: this.view.slice() };
      canvas.setPointerCapture(e.pointerId);
    });
    canvas.addEventListener("pointermove", (e) => {
      if (!drag) return;
      const w = canvas.clientWidth - MARGIN.left - MARGIN.right;
      const dt = ((e.offsetX - drag.x) / w) * (drag.view[1] - drag.view[0]);
      this.setView([drag.view[0] - dt, drag.view[1] - dt]);
    });
    canvas.addEventListener("pointerup", () => (drag = null));
    canvas.addEventListener("dblclick", () => this.run && this.show(this.run));
  }

  setView([a, b]) {
    const t = this.run.columns.t_s;
    const lo = t[0];
    const hi = t[t.length - 1];
    const span = Math.min(Math.max(b - a, (hi - lo) / 1e5), hi - lo);
    a = Math.min(Math.max(a, lo), hi - span);
    this.view = [a, a + span];
    this.draw();
  }

  timeAt(canvas, px) {
    const w = canvas.clientWidth - MARGIN.left - MARGIN.right;
    const [a, b] = this.view;
    return a + ((px - MARGIN.left) / w) * (b - a);
  }

  draw() {
    for (const p of this.panels) {
      const c = p.canvas;
      const ratio = window.devicePixelRatio || 1;
      c.width = Math.max(1, Math.round(c.clientWidth * ratio));
      c.height = Math.max(1, Math.round(c.clientHeight * ratio));
      const g = c.getContext("2d");
      g.setTransform(ratio, 0, 0, ratio, 0, 0);
      g.clearRect(0, 0, c.clientWidth, c.clientHeight);
      if (this.run) this.drawPanel(g, p, c.clientWidth, c.clientHeight);
    }
  }

  drawPanel(g, panel, width, height) {
    const box = {
      x: MARGIN.left,
      y: MARGIN.top,
      w: width - MARGIN.left - MARGIN.right,
      h: height - MARGIN.top - MARGIN.bottom,
    };
    const runs = [this.pinned, this.run].filter(Boolean);
    const traces = [];
    for (const run of runs) {
      panel.lines.forEach((line, k) => {
        const v = run.columns[line.key];
        if (v) traces.push({ run, line, k, env: envelope(run.columns.t_s, v, this.view, box.w) });
      });
    }
    let lo = Infinity;
    let hi = -Infinity;
    for (const tr of traces) {
      for (let i = 0; i < tr.env.min.length; i++) {
        if (tr.env.min[i] < lo) lo = tr.env.min[i];
        if (tr.env.max[i] > hi) hi = tr.env.max[i];
      }
    }
    if (!(hi > lo)) {
      lo = Number.isFinite(lo) ? lo - 0.5 : 0;
      hi = lo + 1;
    }
    const pad = (hi - lo) * 0.05;
    lo -= pad;
    hi += pad;
    const y = (v) => box.y + box.h - ((v - lo) / (hi - lo)) * box.h;
    axes(g, box, this.view, [lo, hi], panel.title);
    for (const tr of traces) {
      const pinned = tr.run === this.pinned;
      g.strokeStyle = pinned ? PINNED : COLOURS[tr.k % COLOURS.length];
      g.setLineDash(pinned ? [4, 3] : []);
      g.lineWidth = 1.2;
      g.beginPath();
      let on = false;
      for (let i = 0; i < tr.env.min.length; i++) {
        if (!Number.isFinite(tr.env.min[i])) {
          on = false;
          continue;
        }
        const x = box.x + i + 0.5;
        if (on) g.lineTo(x, y(tr.env.min[i]));
        else g.moveTo(x, y(tr.env.min[i]));
        g.lineTo(x, y(tr.env.max[i]));
        on = true;
      }
      g.stroke();
    }
    g.setLineDash([]);
    legend(g, box, panel.lines);
    for (const f of this.run.faults || []) {
      const [a, b] = this.view;
      if (f.t_s < a || f.t_s > b) continue;
      const x = box.x + ((f.t_s - a) / (b - a)) * box.w;
      g.strokeStyle = "#c00";
      g.beginPath();
      g.moveTo(x, box.y);
      g.lineTo(x, box.y + box.h);
      g.stroke();
      g.fillStyle = "#c00";
      g.fillText(f.fault, Math.min(x + 3, box.x + box.w - 60), box.y + 10);
    }
  }
}

/** Per pixel column of `width` over the time window `view`: min and max of `v` (NaN: none). */
function envelope(t, v, [a, b], width) {
  const n = Math.max(1, Math.floor(width));
  const min = new Float64Array(n).fill(NaN);
  const max = new Float64Array(n).fill(NaN);
  let i = lowerBound(t, a);
  const scale = n / (b - a);
  for (; i < t.length && t[i] <= b; i++) {
    const x = v[i];
    if (!Number.isFinite(x)) continue;
    const k = Math.min(n - 1, Math.floor((t[i] - a) * scale));
    if (!(x >= min[k])) min[k] = x;
    if (!(x <= max[k])) max[k] = x;
  }
  return { min, max };
}

function lowerBound(t, x) {
  let lo = 0;
  let hi = t.length;
  while (lo < hi) {
    const mid = (lo + hi) >> 1;
    if (t[mid] < x) lo = mid + 1;
    else hi = mid;
  }
  return lo;
}

function axes(g, box, [t0, t1], [lo, hi], title) {
  g.strokeStyle = "#888";
  g.lineWidth = 1;
  g.strokeRect(box.x, box.y, box.w, box.h);
  g.fillStyle = "#222";
  g.font = "12px sans-serif";
  g.fillText(title, box.x, box.y - 7);
  g.fillStyle = "#555";
  g.font = "11px sans-serif";
  for (const v of ticks(lo, hi, 4)) {
    const yy = box.y + box.h - ((v - lo) / (hi - lo)) * box.h;
    g.strokeStyle = "#eee";
    g.beginPath();
    g.moveTo(box.x, yy);
    g.lineTo(box.x + box.w, yy);
    g.stroke();
    g.fillText(format(v), 4, yy + 4);
  }
  for (const v of ticks(t0, t1, 8)) {
    const xx = box.x + ((v - t0) / (t1 - t0)) * box.w;
    g.fillText(`${format(v)} s`, xx - 10, box.y + box.h + 15);
  }
}

function legend(g, box, lines) {
  let x = box.x + box.w;
  g.font = "11px sans-serif";
  for (let k = lines.length - 1; k >= 0; k--) {
    const w = g.measureText(lines[k].label).width + 22;
    x -= w;
    g.fillStyle = COLOURS[k % COLOURS.length];
    g.fillRect(x, box.y - 12, 12, 3);
    g.fillStyle = "#333";
    g.fillText(lines[k].label, x + 15, box.y - 7);
  }
}

function ticks(lo, hi, n) {
  const step = niceStep((hi - lo) / n);
  const out = [];
  for (let v = Math.ceil(lo / step) * step; v <= hi; v += step) out.push(v);
  return out;
}

function niceStep(raw) {
  const p = Math.pow(10, Math.floor(Math.log10(raw)));
  const m = raw / p;
  return (m < 1.5 ? 1 : m < 3 ? 2 : m < 7 ? 5 : 10) * p;
}

function format(v) {
  const a = Math.abs(v);
  if (a === 0) return "0";
  if (a >= 1000 || a < 0.01) return v.toExponential(1);
  return String(Number(v.toPrecision(3)));
}
