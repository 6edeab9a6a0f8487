// The page of `kiln serve`: a Leaflet map (the polygon layer as base tiles, the event heatmap
// tiles over it), a time chart with brushing and one bar chart per category (top-k, click to
// filter), linked through one selection; every change is one POST /api/query batch answered by
// the server. Charts are plain SVG written here (two chart kinds, no library needed).
"use strict";
const kiln = (window.kiln = { ready: false, updates: 0, lastUpdateMs: null, lastTilesMs: null, lastInteractionMs: null });
const SVG = "http://www.w3.org/2000/svg";
const state = { time: null, where: {}, box: null };
let events = null, eventBlob = null, polygonBlob = null, map = null, heat = null, seriesBin = 3600;

function el(tag, attrs, parent) {
  const e = document.createElementNS(SVG, tag);
  for (const [k, v] of Object.entries(attrs || {})) e.setAttribute(k, v);
  if (parent) parent.appendChild(e);
  return e;
}

async function post(body) {
  const r = await fetch("/api/query", { method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify(body) });
  const answer = await r.json();
  if (!r.ok) throw new Error(answer.error || "HTTP " + r.status);
  return answer;
}

// The selection as query fields; `skip` leaves one category's own filter out (its bars).
function selection(skip) {
  const q = { blob: eventBlob };
  if (state.time) q.time = state.time;
  if (state.box) q.box = state.box;
  const where = {};
  for (const [name, labels] of Object.entries(state.where))
    if (name !== skip && labels.length) where[name] = labels;
  if (Object.keys(where).length) q.where = where;
  return q;
}

function tileParams() {
  const p = [];
  if (state.time) p.push("time=" + state.time[0] + "," + state.time[1]);
  for (const [name, labels] of Object.entries(state.where))
    if (labels.length) p.push("where=" + encodeURIComponent(name + ":" + labels.join(",")));
  return p.length ? "?" + p.join("&") : "";
}

async function update() {
  const start = performance.now();
  // The heatmap tiles load while the batch below is answered; an interaction is done when both
  // are (kiln.lastInteractionMs, read by the browser test).
  kiln.lastTilesMs = kiln.lastInteractionMs = null;
  let viewsDone = false, tilesDone = !heat;
  const finish = () => {
    if (viewsDone && tilesDone) kiln.lastInteractionMs = performance.now() - start;
  };
  if (heat) {
    heat.once("load", () => {
      kiln.lastTilesMs = performance.now() - start;
      tilesDone = true;
      finish();
    });
    heat.setUrl("/tiles/" + encodeURIComponent(eventBlob) + "/{z}/{x}/{y}.png" + tileParams());
  }
  const series = Object.assign(selection(), { op: "series", bin: seriesBin, time: [events.time_min, events.time_max + 1] });
  const batch = [Object.assign(selection(), { op: "count" }), series];
  for (const c of events.categories) batch.push(Object.assign(selection(c.name), { op: "topk", by: c.name, k: 12 }));
  let answers;
  try {
    answers = await post(batch);
  } catch (e) {
    document.getElementById("status").textContent = e.message;
    return;
  }
  document.getElementById("status").textContent = "";
  document.getElementById("total-count").textContent = String(answers[0].count);
  drawSeries(answers[1].series);
  events.categories.forEach((c, i) => drawBars(c, answers[2 + i].topk));
  kiln.selection = selection();
  kiln.lastUpdateMs = performance.now() - start;
  kiln.updates += 1;
  viewsDone = true;
  finish();
}

// The time chart: one bar per series bin; drag selects [t0, t1) snapped to bins.
function drawSeries(series) {
  const svg = document.getElementById("time-chart");
  svg.textContent = "";
  const W = +svg.getAttribute("width"), H = +svg.getAttribute("height"), pad = 18;
  const t0 = events.time_min - (events.time_min % seriesBin), t1 = events.time_max + 1;
  const top = Math.max(1, ...series.map((s) => s[1]));
  const x = (t) => pad + ((t - t0) / (t1 - t0)) * (W - 2 * pad);
  kiln.timeScale = { t0, t1, pad, W };
  for (const [iso, n] of series) {
    const t = Date.parse(iso) / 1000, h = (n / top) * (H - 2 * pad);
    el("rect", { class: "series", x: x(t), y: H - pad - h, width: Math.max(1, x(t + seriesBin) - x(t)), height: h }, svg);
  }
  el("text", { class: "axis", x: pad, y: H - 4 }, svg).textContent = new Date(t0 * 1000).toISOString().slice(0, 10);
  el("text", { class: "axis", x: W - pad, y: H - 4, "text-anchor": "end" }, svg).textContent = new Date(t1 * 1000).toISOString().slice(0, 10);
  el("text", { class: "axis", x: pad, y: 12 }, svg).textContent = "max " + top + " per " + (seriesBin % 86400 ? seriesBin / 3600 + " h" : seriesBin / 86400 + " d");
  if (state.time)
    el("rect", { class: "brush", x: x(state.time[0]), y: pad / 2, width: x(state.time[1]) - x(state.time[0]), height: H - 1.5 * pad }, svg);
  document.getElementById("time-label").textContent = state.time
    ? new Date(state.time[0] * 1000).toISOString().slice(0, 16) + " to " + new Date(state.time[1] * 1000).toISOString().slice(0, 16)
    : "all times";
}

function timeAt(px) {
  const { t0, t1, pad, W } = kiln.timeScale;
  const t = t0 + ((px - pad) / (W - 2 * pad)) * (t1 - t0);
  return Math.min(t1, Math.max(t0, t0 + Math.round((t - t0) / seriesBin) * seriesBin));
}

function brushing() {
  const svg = document.getElementById("time-chart");
  let from = null, rect = null;
  const px = (e) => e.clientX - svg.getBoundingClientRect().left;
  svg.addEventListener("mousedown", (e) => {
    from = px(e);
    rect = el("rect", { class: "brush", x: from, y: 9, width: 0, height: 120 }, svg);
  });
  svg.addEventListener("mousemove", (e) => {
    if (from === null) return;
    const p = px(e);
    rect.setAttribute("x", Math.min(from, p));
    rect.setAttribute("width", Math.abs(p - from));
  });
  window.addEventListener("mouseup", (e) => {
    if (from === null) return;
    const a = timeAt(Math.min(from, px(e))), b = timeAt(Math.max(from, px(e)));
    from = null;
    state.time = b - a >= seriesBin ? [a, b] : null;  // a click clears
    update();
  });
}

// A category's top labels as horizontal bars; a click toggles the label in the filter.
function drawBars(category, topk) {
  let svg = document.getElementById("bars-" + category.name);
  if (!svg) {
    const h = document.createElement("h2");
    h.textContent = "Top " + category.name + " (click to filter)";
    document.getElementById("bars").appendChild(h);
    svg = el("svg", { id: "bars-" + category.name, "data-testid": "bars-" + category.name, width: 520, height: 12 * 17 + 4 }, document.getElementById("bars"));
  }
  svg.textContent = "";
  const top = Math.max(1, ...topk.map((t) => t[1]));
  const chosen = state.where[category.name] || [];
  topk.forEach(([label, n], i) => {
    const g = el("g", { "data-label": label, transform: "translate(0," + (2 + i * 17) + ")" }, svg);
    el("text", { class: "bar-label", x: 4, y: 12 }, g).textContent = label;
    el("rect", { class: "bar" + (chosen.includes(label) ? " on" : ""), x: 90, y: 1, height: 14, width: Math.max(1, (n / top) * 340) }, g);
    el("text", { class: "axis", x: 94 + Math.max(1, (n / top) * 340), y: 12 }, g).textContent = n;
    g.addEventListener("click", () => {
      const list = state.where[category.name] || (state.where[category.name] = []);
      const at = list.indexOf(label);
      if (at >= 0) list.splice(at, 1);
      else list.push(label);
      update();
    });
  });
}

async function locate(e) {
  const out = document.getElementById("feature");
  try {
    const a = await post({ op: "polygon", blob: polygonBlob, points: [[e.latlng.lng, e.latlng.lat]] });
    const f = a.features[0];
    out.textContent = f ? f.name + " (id " + f.id + ", feature " + f.index + ")" : "no feature here";
    if (f) L.popup().setLatLng(e.latlng).setContent(out.textContent).openOn(map);
  } catch (err) {
    out.textContent = err.message;
  }
}

function setupMap(bounds) {
  if (typeof L === "undefined") {
    document.getElementById("map").textContent = "Leaflet is not installed (libjs-leaflet): no map";
    return;
  }
  map = kiln.map = L.map("map", { worldCopyJump: false, minZoom: 1, maxZoom: 14 });
  if (polygonBlob)
    L.tileLayer("/tiles/" + encodeURIComponent(polygonBlob) + "/{z}/{x}/{y}.png", { attribution: "base: " + polygonBlob }).addTo(map);
  if (eventBlob) heat = L.tileLayer("/tiles/" + encodeURIComponent(eventBlob) + "/{z}/{x}/{y}.png", { opacity: 0.85 }).addTo(map);
  map.fitBounds([[bounds[1], bounds[0]], [bounds[3], bounds[2]]]);
  if (polygonBlob) map.on("click", locate);
  map.on("moveend", () => {
    if (!document.getElementById("map-filter").checked || !eventBlob) return;
    const b = map.getBounds();
    state.box = [b.getWest(), b.getSouth(), b.getEast(), b.getNorth()];
    update();
  });
}

async function main() {
  const blobs = (await (await fetch("/api/blobs")).json()).blobs;
  const ev = blobs.find((b) => b.events);
  const poly = blobs.find((b) => b.polygon_layer);
  polygonBlob = poly ? poly.name : null;
  document.getElementById("blob-name").textContent = blobs.map((b) => b.name).join(" + ");
  if (ev) {
    eventBlob = ev.name;
    events = ev.events;
    // The first round bin that the cube's bin divides and that gives at most 250 bars.
    const span = events.time_max - events.time_min + 1;
    const round = [3600, 3 * 3600, 6 * 3600, 12 * 3600, 86400, 7 * 86400].filter((b) => b % events.time_bin === 0);
    seriesBin = round.find((b) => span / b <= 250) || events.time_bin * Math.max(1, Math.ceil(span / 250 / events.time_bin));
  }
  setupMap(ev ? events.bounds : poly ? [poly.polygon_layer.bounds.min[0], poly.polygon_layer.bounds.min[1], poly.polygon_layer.bounds.max[0], poly.polygon_layer.bounds.max[1]] : [-180, -60, 180, 75]);
  document.getElementById("map-filter").addEventListener("change", (e) => {
    if (!map) return;
    const b = map.getBounds();
    state.box = e.target.checked ? [b.getWest(), b.getSouth(), b.getEast(), b.getNorth()] : null;
    update();
  });
  document.getElementById("reset").addEventListener("click", () => {
    state.time = null;
    state.where = {};
    update();
  });
  if (ev) {
    brushing();
    await update();
  }
  kiln.ready = true;
}

main();
