// tsa-bench lab page: the live board from /api/live (server-sent events), the catalogue from
// /api/runs, a finished run's figures from /api/runs/ID. Text from runs (names, events, reasons)
// is only ever set as textContent, never parsed as HTML. Plots are drawn on canvases here.
"use strict";

const MAX_POINTS = 4000;   // per run and channel; when full every other point goes (as on the server)
const CHANNELS = [
  ["length", "length", "mm"], ["resistance", "resistance", "ohm"], ["twist", "twist", "turn"],
  ["heater", "heater", "V"], ["load", "load", "N"],
];
const runs = new Map();   // key -> {el, cols, plots, state}

function el(tag, attrs, text) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) e.setAttribute(k, v);
  if (text !== undefined && text !== null) e.textContent = String(text);
  return e;
}

function fmtDuration(s) {
  if (s === null || s === undefined || !isFinite(s)) return "–";
  s = Math.round(s);
  const h = Math.floor(s / 3600), m = Math.floor((s % 3600) / 60), sec = s % 60;
  return (h ? h + " h " : "") + (h || m ? m + " min " : "") + sec + " s";
}

function fmtValue(v, unit) {
  if (v === null || v === undefined) return "not measured";
  const a = Math.abs(v);
  const digits = a >= 100 ? 1 : a >= 1 ? 3 : 4;
  return v.toFixed(digits) + " " + unit;
}

// -- a small line plot --------------------------------------------------------
function drawPlot(canvas, t, y, unit) {
  const dpr = window.devicePixelRatio || 1;
  const w = Math.max(50, Math.round(canvas.clientWidth * dpr)), h = Math.max(30, Math.round(canvas.clientHeight * dpr));
  if (canvas.width !== w || canvas.height !== h) { canvas.width = w; canvas.height = h; }
  const g = canvas.getContext("2d");
  g.clearRect(0, 0, w, h);
  let ymin = Infinity, ymax = -Infinity, n = 0;
  for (const v of y) if (v !== null) { n++; if (v < ymin) ymin = v; if (v > ymax) ymax = v; }
  canvas.dataset.points = String(n);
  canvas.dataset.lastT = t.length ? String(t[t.length - 1]) : "";
  if (!n) return;
  if (ymax - ymin < 1e-12) { ymin -= 1; ymax += 1; }
  const pad = 0.06 * (ymax - ymin); ymin -= pad; ymax += pad;
  const t0 = t[0], t1 = t[t.length - 1] > t0 ? t[t.length - 1] : t0 + 1;
  const left = 46 * dpr, right = w - 4 * dpr, top = 4 * dpr, bottom = h - 14 * dpr;
  const X = (x) => left + (x - t0) / (t1 - t0) * (right - left);
  const Y = (v) => bottom - (v - ymin) / (ymax - ymin) * (bottom - top);
  g.strokeStyle = "#bbb"; g.lineWidth = 1; g.strokeRect(left, top, right - left, bottom - top);
  g.fillStyle = "#555"; g.font = (10 * dpr) + "px sans-serif"; g.textBaseline = "middle";
  const label = (v) => Math.abs(v) >= 100 ? v.toFixed(0) : Math.abs(v) >= 1 ? v.toFixed(2) : v.toFixed(3);
  g.textAlign = "right";
  g.fillText(label(ymax - pad), left - 3 * dpr, Y(ymax - pad));
  g.fillText(label(ymin + pad), left - 3 * dpr, Y(ymin + pad));
  g.textAlign = "left"; g.textBaseline = "alphabetic";
  const minutes = t1 > 600;
  const tl = (x) => (minutes ? (x / 60).toFixed(1) + " min" : x.toFixed(0) + " s");
  g.fillText(tl(t0), left, h - 2 * dpr);
  g.textAlign = "right"; g.fillText(tl(t1), right, h - 2 * dpr);
  g.strokeStyle = "#1f5fbf"; g.lineWidth = 1.2 * dpr; g.beginPath();
  let pen = false;
  for (let i = 0; i < t.length; i++) {
    if (y[i] === null || t[i] === null) { pen = false; continue; }
    if (pen) g.lineTo(X(t[i]), Y(y[i])); else { g.moveTo(X(t[i]), Y(y[i])); pen = true; }
  }
  g.stroke();
}

// -- live cards ---------------------------------------------------------------
function newCard(run) {
  const card = el("article", {class: "run", "data-key": run.key, "data-run-file": run.run_file});
  const h = el("h3");
  const title = el("span", {class: "title"});
  const badge = el("span", {class: "badge"});
  h.append(title, badge);
  const facts = el("p", {class: "facts"});
  const reason = el("p", {class: "reason"});
  const plots = el("div", {class: "plots"});
  const canvases = {};
  const values = {};
  for (const [key, name, unit] of CHANNELS) {
    const fig = el("figure", {"data-channel": key});
    const cap = el("figcaption");
    cap.append(el("span", {}, name + " (" + unit + ")"));
    values[key] = el("span", {class: "value"});
    cap.append(values[key]);
    canvases[key] = el("canvas", {"data-channel": key});
    fig.append(cap, canvases[key]);
    plots.append(fig);
  }
  const events = el("ol", {class: "events"});
  card.append(h, facts, reason, plots, events);
  return {el: card, title, badge, facts, reason, canvases, values, events, cols: null, state: {}, dirty: true};
}

function emptyCols() {
  const c = {t: []};
  for (const [key] of CHANNELS) c[key] = [];
  return c;
}

function addPoints(r, points) {
  if (!points || !points.t) return;
  const last = r.cols.t.length ? r.cols.t[r.cols.t.length - 1] : -Infinity;
  for (let i = 0; i < points.t.length; i++) {
    if (points.t[i] === null || points.t[i] <= last) continue;   // a point seen in a snapshot already
    r.cols.t.push(points.t[i]);
    for (const [key] of CHANNELS) r.cols[key].push(points[key][i]);
  }
  if (r.cols.t.length > MAX_POINTS) {
    for (const k of Object.keys(r.cols)) r.cols[k] = r.cols[k].filter((_, i) => i % 2 === 0);
  }
  r.dirty = true;
}

function addEvents(r, events) {
  for (const e of events || []) {
    const t = e.t === null || e.t === undefined ? "" : "t=" + e.t.toFixed(1) + " s  ";
    const li = el("li", {class: e.severity || "info", "data-kind": e.kind}, t + e.kind + ": " + e.detail);
    r.events.prepend(li);
  }
  while (r.events.children.length > 200) r.events.lastChild.remove();
}

function setState(r, s, run) {
  if (!s) return;
  const before = r.state.status;
  r.state = s;
  const name = s.rig ? s.rig + " · " + (run.plan || "") : (run.plan || run.run_file);
  r.title.textContent = name;
  r.badge.textContent = s.status;
  r.badge.dataset.status = s.status;
  r.el.dataset.status = s.status;
  r.el.classList.toggle("has-fault", s.faults > 0);
  r.facts.replaceChildren();
  const fact = (cls, text) => r.facts.append(el("span", {class: cls}, text));
  fact("file", run.run_file);
  if (s.sample) fact("sample", "sample " + s.sample);
  if (s.load_g !== null && s.load_g !== undefined) fact("load-g", s.load_g + " g");
  fact("segment", "segment " + (s.segment === null ? "–" : s.segment) + " of " + (s.n_segments ?? "?"));
  fact("eta", s.status === "running" ? "ETA " + fmtDuration(s.eta_s) : "ended");
  fact("samples", s.samples + " samples");
  if (s.warnings) fact("warnings", s.warnings + " warning" + (s.warnings > 1 ? "s" : ""));
  if (s.faults) fact("faults", s.faults + " fault" + (s.faults > 1 ? "s" : ""));
  const ended = s.status !== "running";
  r.reason.textContent = ended && s.status !== "success" ? s.status + (s.reason ? ": " + s.reason : "") : "";
  for (const [key, , unit] of CHANNELS) {
    const v = s.latest ? s.latest[key] : undefined;
    r.values[key].textContent = v === undefined ? "" : fmtValue(v, unit);
  }
  if (before === "running" && ended) loadRuns();   // it is in the catalogue's list now
}

function upsert(run) {
  let r = runs.get(run.key);
  if (!r) {
    r = newCard(run);
    r.run = run;
    runs.set(run.key, r);
    document.getElementById("live").prepend(r.el);
  }
  r.run = run;
  r.cols = emptyCols();
  r.events.replaceChildren();
  addPoints(r, run.points);
  addEvents(r, run.events);
  setState(r, run.state, run);
}

function remove(key) {
  const r = runs.get(key);
  if (r) { r.el.remove(); runs.delete(key); }
}

function liveCount() {
  let n = 0;
  for (const r of runs.values()) if (r.state.status === "running") n++;
  document.getElementById("live-count").textContent = "(" + n + ")";
  document.getElementById("no-live").hidden = runs.size > 0;
}

function redraw() {
  for (const r of runs.values()) {
    if (!r.dirty || !r.cols) continue;
    for (const [key, , unit] of CHANNELS) drawPlot(r.canvases[key], r.cols.t, r.cols[key], unit);
    r.dirty = false;
  }
  requestAnimationFrame(redraw);
}

function connect() {
  const status = document.getElementById("connection");
  const source = new EventSource("/api/live");
  source.addEventListener("open", () => { status.dataset.state = "live"; status.textContent = "live"; });
  source.addEventListener("error", () => { status.dataset.state = "reconnecting"; status.textContent = "reconnecting"; });
  source.addEventListener("snapshot", (ev) => {
    const data = JSON.parse(ev.data);
    const keep = new Set(data.runs.map((run) => run.key));
    for (const key of [...runs.keys()]) if (!keep.has(key)) remove(key);
    for (const run of data.runs) upsert(run);
    liveCount();
  });
  source.addEventListener("update", (ev) => {
    const data = JSON.parse(ev.data);
    for (const u of data.runs) {
      if (u.gone) { remove(u.key); continue; }
      if (u.new || !runs.has(u.key)) { if (u.new) upsert(u); continue; }
      const r = runs.get(u.key);
      addPoints(r, u.points);
      addEvents(r, u.events);
      setState(r, u.state, r.run);
    }
    liveCount();
  });
}

// -- the catalogue ------------------------------------------------------------
let searching = null;

async function loadRuns() {
  const form = document.getElementById("search");
  const params = new URLSearchParams({q: form.q.value, status: form.status.value, since: form.since.value, limit: "100"});
  if (searching) searching.abort();
  searching = new AbortController();
  let data;
  try {
    const resp = await fetch("/api/runs?" + params, {signal: searching.signal});
    data = await resp.json();
  } catch (e) {
    if (e.name !== "AbortError") document.getElementById("catalogue-problem").textContent = "cannot reach the page's server";
    return;
  }
  document.getElementById("source").textContent = data.catalogue ? "catalogue: " + data.catalogue : "";
  document.getElementById("catalogue-problem").textContent = data.error || data.problem || "";
  const body = document.querySelector("#runs tbody");
  if (data.error) return;
  body.replaceChildren();
  for (const row of data.rows) {
    const tr = el("tr", {"data-id": row.id, "data-status": row.status, "data-name": row.name});
    const cell = (text, cls) => tr.append(el("td", cls ? {class: cls} : {}, text ?? ""));
    cell(row.id, "num");
    cell(row.status + (row.file_state !== "ok" && row.file_state !== "running" ? " (file " + row.file_state + ")" : ""),
         "status-" + row.status);
    tr.lastChild.title = row.reason || "";
    cell(row.started ? row.started.replace("T", " ").replace("Z", "") : "");
    cell(row.plan); cell(row.rig); cell(row.sample);
    cell(row.load_g, "num");
    cell(row.device_time_s === null ? "" : fmtDuration(row.device_time_s), "num");
    cell(row.samples, "num"); cell(row.samples_lost, "num");
    cell(row.name);
    tr.addEventListener("click", () => showRun(row.id));
    body.append(tr);
  }
}

async function showRun(id) {
  const detail = document.getElementById("detail");
  detail.hidden = false;
  detail.dataset.id = String(id);
  const title = document.getElementById("detail-title");
  const note = document.getElementById("detail-note");
  const figures = document.getElementById("figures");
  title.textContent = "Run " + id;
  note.textContent = "drawing the report figures…";
  figures.replaceChildren();
  document.getElementById("detail-events").replaceChildren();
  const resp = await fetch("/api/runs/" + id);
  const data = await resp.json();
  if (detail.dataset.id !== String(id)) return;   // another run was chosen meanwhile
  if (data.error) { note.textContent = data.error; return; }
  const row = data.row, rep = data.report;
  title.textContent = "Run " + row.id + ": " + (row.plan || "") + (row.rig ? " on " + row.rig : "") + "  (" + row.name + ")";
  document.getElementById("detail-status").textContent =
    row.status + (row.reason ? ": " + row.reason : "") + "  ·  " + row.path;
  note.textContent = rep.unavailable || "";
  for (const f of rep.figures || []) {
    const fig = el("figure", {"data-figure": f.name});
    fig.append(el("img", {src: f.url, alt: f.caption}), el("figcaption", {}, f.name + ": " + f.caption));
    figures.append(fig);
  }
  const events = document.getElementById("detail-events");
  for (const e of rep.events || []) {
    const t = e.t === null ? "" : "t=" + e.t.toFixed(1) + " s  ";
    events.append(el("li", {"data-kind": e.kind}, t + e.kind + ": " + e.detail));
  }
  detail.scrollIntoView({behavior: "smooth"});
}

document.getElementById("search").addEventListener("submit", (ev) => { ev.preventDefault(); loadRuns(); });
connect();
loadRuns();
setInterval(loadRuns, 5000);
requestAnimationFrame(redraw);
