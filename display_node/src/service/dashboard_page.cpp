#include <afr/display/service/dashboard.h>

namespace afr::service {

// The whole page: plain HTML, CSS and JavaScript, no library and no asset from elsewhere. It
// polls /image.png (4 a second), /history (each second: the stats periods and events since the
// last it has) and /stats (each second), and draws its charts on canvases. #loads counts what
// arrived (the browser test reads it).
const char* const kDashboardPage = R"HTML(<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>afr display</title>
<style>
body { font: 13px sans-serif; margin: 12px; background: #16181c; color: #ddd; }
h1 { font-size: 16px; margin: 0 0 8px 0; }
#top { display: flex; gap: 16px; flex-wrap: wrap; }
#image { image-rendering: pixelated; background: #000; min-width: 256px; min-height: 256px; }
.chart { background: #22252b; border-radius: 4px; padding: 4px 8px; }
.chart b { display: block; font-weight: normal; color: #aaa; }
canvas { display: block; }
#events { max-height: 260px; overflow-y: auto; font-family: monospace; white-space: pre; }
table { border-collapse: collapse; } td, th { padding: 1px 8px; text-align: right; }
.key { display: inline-block; width: 10px; height: 10px; margin: 0 3px 0 8px; }
</style></head><body>
<h1>afr display <span id="status"></span></h1>
<div id="top">
  <div><img id="image" alt="the latest image"><br>
    <label><input type="checkbox" id="tiling"> tiling and regions</label>
    <span id="loads" data-images="0" data-history="0" data-periods="0" data-last=""></span></div>
  <div>
    <table id="samplers"><tr><th>sampler</th><th>state</th><th>samples/s</th><th>share</th><th>region</th></tr></table>
    <p>Events</p><div id="events"></div>
    <div id="wall"></div>
  </div>
</div>
<div id="charts" style="display:flex; flex-wrap:wrap; gap:8px; margin-top:8px"></div>
<script>
"use strict";
const colors = ["#4e9af1", "#f1a34e", "#5fd068", "#e5534b", "#b07cf2", "#e8d44d", "#4ed6d6", "#d66fb0"];
const periods = [];  // what /history gave, oldest first (at most 600)
let last = -1e30, images = 0, histories = 0;
const charts = [
  {title: "samples/s per sampler", series: p => Object.fromEntries(p.samplers.map(s => ["#" + s.id, s.rate]))},
  {title: "share of the image per sampler", series: p => Object.fromEntries(p.samplers.map(s => ["#" + s.id, s.share]))},
  {title: "refresh (Hz)", series: p => ({refresh: p.refresh_hz})},
  {title: "reconstruction (ms)", series: p => ({mean: p.reconstruct_ms_mean, p99: p.reconstruct_ms_p99})},
  {title: "latency (ms)", series: p => ({p50: p.latency_ms_p50, p99: p.latency_ms_p99})},
  {title: "store fill", series: p => ({fill: p.store_fill})},
];
for (const c of charts) {
  const box = document.createElement("div");
  box.className = "chart";
  box.innerHTML = "<b></b><canvas width=380 height=140></canvas><div class=legend></div>";
  box.querySelector("b").textContent = c.title;
  document.getElementById("charts").appendChild(box);
  c.canvas = box.querySelector("canvas");
  c.legend = box.querySelector(".legend");
}
function draw(c) {
  const g = c.canvas.getContext("2d"), w = c.canvas.width, h = c.canvas.height;
  g.clearRect(0, 0, w, h);
  const names = [];
  const lines = {};
  periods.forEach((p, i) => {
    for (const [k, v] of Object.entries(c.series(p))) {
      if (!(k in lines)) { lines[k] = []; names.push(k); }
      lines[k].push([p.t, v]);
    }
  });
  if (!periods.length) return;
  const t0 = periods[0].t, t1 = Math.max(periods[periods.length - 1].t, t0 + 1e-9);
  let top = 0;
  for (const k of names) for (const [, v] of lines[k]) if (isFinite(v)) top = Math.max(top, v);
  top = top > 0 ? top * 1.1 : 1;
  g.fillStyle = "#888"; g.font = "10px sans-serif";
  g.fillText(top.toPrecision(3), 2, 10); g.fillText("0", 2, h - 2);
  g.fillText((t1 - t0).toFixed(0) + " s", w - 34, h - 2);
  names.forEach((k, n) => {
    g.strokeStyle = colors[n % colors.length]; g.beginPath();
    lines[k].forEach(([t, v], i) => {
      const x = 30 + (w - 34) * (t - t0) / (t1 - t0), y = h - 4 - (h - 16) * (isFinite(v) ? v : 0) / top;
      i ? g.lineTo(x, y) : g.moveTo(x, y);
    });
    g.stroke();
  });
  c.legend.innerHTML = names.map((k, n) => `<span class=key style="background:${colors[n % colors.length]}"></span>${k} ` +
    (lines[k].length ? Number(lines[k][lines[k].length - 1][1]).toPrecision(3) : "")).join("");
}
function loads() {
  const l = document.getElementById("loads");
  l.dataset.images = images; l.dataset.history = histories; l.dataset.periods = periods.length;
  l.dataset.last = periods.length ? JSON.stringify(periods[periods.length - 1]) : "";
}
async function poll_history() {
  try {
    const r = await fetch("/history?since=" + last);
    const h = await r.json();
    for (const p of h.periods) { periods.push(p); last = Math.max(last, p.t); }
    while (periods.length > 600) periods.shift();
    const ev = document.getElementById("events");
    for (const e of h.events) ev.textContent = `${e.t.toFixed(1)} s  ${e.text}\n` + ev.textContent;
    histories++;
    charts.forEach(draw);
  } catch (e) {}
  loads();
}
async function poll_stats() {
  try {
    const s = await (await fetch("/stats")).json(), d = s.display;
    document.getElementById("status").textContent =
      `| ${d.width}x${d.height} ${d.backend} ${d.mode} | ${d.members} sampler(s) | ` +
      `${d.refresh_hz.toFixed(1)} Hz | up ${d.uptime.toFixed(0)} s`;
    const area = d.width * d.height;
    // What a member is doing: receiving the scene (its transfer's progress), loading it (the
    // transfer is done, no sample yet), or sampling.
    const state = x => x.scene.chunks > 0 && x.scene.chunks_sent < x.scene.chunks
      ? `receiving the scene ${Math.floor(100 * x.scene.chunks_sent / x.scene.chunks)}%`
      : x.samples == 0 ? "loading the scene" : x.starved ? "starved" : "sampling";
    const rows = s.samplers.filter(x => x.member).map(x =>
      `<tr><td>#${x.id} ${x.name}</td><td>${state(x)}</td>` +
      `<td>${(x.samples_per_second / 1e3).toFixed(0)} k</td>` +
      `<td>${(100 * (x.region[2] - x.region[0]) * (x.region[3] - x.region[1]) / area).toFixed(0)}%</td>` +
      `<td>[${x.region[0]}, ${x.region[2]}) x [${x.region[1]}, ${x.region[3]})</td></tr>`);
    document.getElementById("samplers").innerHTML =
      "<tr><th>sampler</th><th>state</th><th>samples/s</th><th>share</th><th>region</th></tr>" +
      rows.join("");
    const wall = d.wall;
    // On the lead, every cell of the grid and who shows it (dark: no node, or it was lost).
    const cells = (wall.cells || []).length > 1
      ? " | cells: " + wall.cells.map(c => `[${c.cell}] ` + (c.node ? `#${c.node}` : "dark")).join(", ")
      : "";
    document.getElementById("wall").textContent = wall.nodes > 1 || cells
      ? `wall: node ${wall.node} of ${wall.nodes}, cell [${wall.cell}], coverage in ${wall.exchange.coverage_in}, strays in ${wall.exchange.strays_in}, out ${wall.exchange.strays_out}` + cells
      : "";
  } catch (e) {}
}
function poll_image() {
  const img = new Image();
  img.onload = () => { document.getElementById("image").src = img.src; images++; loads(); };
  img.src = "/image.png?tiling=" + (document.getElementById("tiling").checked ? 1 : 0) + "&n=" + Date.now();
}
setInterval(poll_history, 1000); setInterval(poll_stats, 1000); setInterval(poll_image, 250);
poll_history(); poll_stats(); poll_image();
</script></body></html>
)HTML";

}  // namespace afr::service
