// The live view's page: tiles with overlays and a figures panel, kept up to date over a WebSocket.
#include "page.h"

namespace mixray::liveview {
namespace {

// Everything the browser needs, no CDN and no downloads. The page reports what it received into
// data- attributes (images and distinct images per tile, status messages, device states), which
// the tests read back through headless Chromium.
constexpr std::string_view kPage = R"PAGE(<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>mixray</title>
<meta name="viewport" content="width=device-width, initial-scale=1">
<style>
body{margin:0;font:13px/1.35 system-ui,sans-serif;background:#15171a;color:#ddd}
header{padding:6px 12px;background:#22262b;display:flex;gap:16px;align-items:baseline}
header h1{font-size:16px;margin:0}
#conn{font-weight:600}
#conn.up{color:#6c6}#conn.down{color:#e66}
main{display:flex;gap:12px;padding:12px;align-items:flex-start}
#tiles{display:flex;flex-wrap:wrap;gap:10px;flex:1;align-items:flex-start}
.tile{background:#000;position:relative;border:1px solid #333}
.tile .frame{position:relative}
.tile img{display:block;width:100%;height:auto}
.tile canvas{position:absolute;left:0;top:0;width:100%;height:100%;pointer-events:none}
.tile .cap{padding:3px 6px;background:#22262b;display:flex;justify-content:space-between;gap:8px}
.tile .legend{display:flex;align-items:center;gap:4px;padding:2px 6px;background:#22262b}
.tile .legend canvas{position:static;width:120px;height:10px}
.tile .err{color:#e66;padding:2px 6px}
#figures{width:340px;background:#1d2024;padding:8px;border:1px solid #333}
#figures h2{font-size:13px;margin:10px 0 4px}
table{border-collapse:collapse;width:100%}
td,th{padding:1px 4px;text-align:right}td:first-child,th:first-child{text-align:left}
.state-streaming{color:#6c6}.state-lost{color:#e66}.state-reconnecting{color:#eb4}
.state-stalled{color:#eb4}.state-ended{color:#999}.state-waiting{color:#999}
#messages li{color:#eb4}
</style></head>
<body data-connected="0" data-status-count="0" data-tiles="0">
<header><h1 id="title">mixray</h1><span id="conn" class="down">connecting</span>
<span id="summary"></span></header>
<main><div id="tiles"></div>
<aside id="figures">
<h2>Devices</h2><ul id="devices"></ul>
<h2>Streams</h2><table id="streams"><thead><tr><th>stream</th><th>fps</th><th>published</th>
<th>dropped</th><th>view fps</th></tr></thead><tbody></tbody></table>
<h2>Latency</h2><div id="latency">-</div>
<h2>Sync</h2><div id="sync">-</div>
<h2>Quality</h2><div id="ladder">-</div>
<h2>Messages</h2><ul id="messages"></ul>
<h2>Other</h2><table id="other"><tbody></tbody></table>
</aside></main>
<script>
"use strict";
let tiles = [];
let statusCount = 0;
const dec = new TextDecoder();
function el(tag, cls, text) {
  const e = document.createElement(tag);
  if (cls) e.className = cls;
  if (text !== undefined) e.textContent = text;
  return e;
}
function turbo(t) {
  t = Math.min(1, Math.max(0, t));
  const t2 = t * t, t3 = t2 * t, t4 = t3 * t, t5 = t4 * t;
  const c = v => Math.round(255 * Math.min(1, Math.max(0, v)));
  return [c(0.13572138 + 4.61539260 * t - 42.66032258 * t2 + 132.13108234 * t3 - 152.94239396 * t4 + 59.28637943 * t5),
          c(0.09140261 + 2.19418839 * t + 4.84296658 * t2 - 14.18503333 * t3 + 4.27729857 * t4 + 2.82956604 * t5),
          c(0.10667330 + 12.64194608 * t - 60.58204836 * t2 + 110.36276771 * t3 - 89.90310912 * t4 + 27.34824973 * t5)];
}
function fnv1a(bytes) {
  let h = 0x811c9dc5;
  for (let i = 0; i < bytes.length; i++) { h ^= bytes[i]; h = Math.imul(h, 0x01000193); }
  return (h >>> 0).toString(16);
}
function fmt(v, digits) { return typeof v === "number" ? v.toFixed(digits) : String(v); }
function setup(config) {
  document.title = config.title;
  document.getElementById("title").textContent = config.title;
  const box = document.getElementById("tiles");
  box.textContent = "";
  tiles = config.tiles.map(t => {
    const div = el("div", "tile");
    div.dataset.stream = t.stream;
    div.dataset.kind = t.kind;
    div.dataset.images = "0";
    div.dataset.distinct = "0";
    div.dataset.overlays = "0";
    div.style.width = Math.min(t.tile_width, 640) + "px";
    const frame = el("div", "frame");
    const img = el("img");
    img.alt = t.stream;
    img.width = t.tile_width;
    img.height = t.tile_height;
    const canvas = el("canvas");
    canvas.width = t.tile_width;
    canvas.height = t.tile_height;
    frame.append(img, canvas);
    const cap = el("div", "cap");
    const name = el("span", "", t.stream + " (" + t.format + " " + t.width + "x" + t.height + ")");
    const fps = el("span", "fps", "");
    cap.append(name, fps);
    div.append(frame, cap);
    let legend = null;
    if (t.format === "depth16") {
      legend = el("div", "legend");
      const lo = el("span", "", fmt(config.depth_min_m, 1) + " m");
      const bar = el("canvas");
      bar.width = 120; bar.height = 10;
      const g = bar.getContext("2d");
      for (let x = 0; x < 120; x++) { const [r, gg, b] = turbo(x / 119); g.fillStyle = `rgb(${r},${gg},${b})`; g.fillRect(x, 0, 1, 10); }
      const hi = el("span", "", fmt(config.depth_max_m, 1) + " m");
      legend.append(lo, bar, hi, el("span", "", config.depth_auto_range ? "(auto)" : ""));
      legend.lo = lo; legend.hi = hi;
      div.append(legend);
    }
    const err = el("div", "err", "");
    div.append(err);
    box.append(div);
    return {info: t, div, img, canvas, fps, legend, err, url: null, hashes: new Set(), overlay: null, images: 0};
  });
  document.body.dataset.tiles = String(tiles.length);
}
function drawOverlay(tile) {
  const c = tile.canvas, g = c.getContext("2d");
  g.clearRect(0, 0, c.width, c.height);
  const o = tile.overlay;
  if (!o) return;
  const sx = c.width / tile.info.width, sy = c.height / tile.info.height;
  const P = p => [p[0] * sx, p[1] * sy];
  g.lineWidth = 2;
  g.font = "14px sans-serif";
  for (const poly of o.polygons || []) {
    if (!poly.points || poly.points.length < 2) continue;
    g.strokeStyle = g.fillStyle = poly.color || "#00ff00";
    g.beginPath();
    poly.points.forEach((p, i) => { const [x, y] = P(p); if (i) g.lineTo(x, y); else g.moveTo(x, y); });
    g.closePath(); g.stroke();
    if (poly.label !== undefined) { const [x, y] = P(poly.points[0]); g.fillText(String(poly.label), x + 3, y - 3); }
  }
  for (const ci of o.circles || []) {
    if (!ci.centre) continue;
    g.strokeStyle = ci.color || "#ffff00";
    const [x, y] = P(ci.centre);
    g.beginPath(); g.arc(x, y, (ci.radius || 1) * sx, 0, 2 * Math.PI); g.stroke();
  }
  for (const l of o.lines || []) {
    if (!l.from || !l.to) continue;
    g.strokeStyle = l.color || "#ff0000";
    const [x0, y0] = P(l.from), [x1, y1] = P(l.to);
    g.beginPath(); g.moveTo(x0, y0); g.lineTo(x1, y1); g.stroke();
  }
  for (const t of o.texts || []) {
    if (!t.at) continue;
    g.fillStyle = t.color || "#ffffff";
    const [x, y] = P(t.at);
    g.fillText(String(t.text), x, y);
  }
}
function onImage(buffer) {
  const view = new DataView(buffer);
  const n = view.getUint32(0, true);
  const header = JSON.parse(dec.decode(new Uint8Array(buffer, 4, n)));
  const tile = tiles[header.tile];
  if (!tile) return;
  const jpeg = new Uint8Array(buffer, 4 + n);
  const hash = fnv1a(jpeg);
  if (tile.hashes.size < 10000) tile.hashes.add(hash);
  tile.images++;
  const url = URL.createObjectURL(new Blob([jpeg], {type: "image/jpeg"}));
  const old = tile.url;
  tile.url = url;
  tile.img.onload = () => { if (old) URL.revokeObjectURL(old); };
  tile.img.src = url;
  tile.div.dataset.images = String(tile.images);
  tile.div.dataset.distinct = String(tile.hashes.size);
  tile.div.dataset.hash = hash;
  tile.div.dataset.seq = String(header.seq);
  if (tile.legend && header.hi > header.lo) {
    tile.legend.lo.textContent = fmt(header.lo, 2) + " m";
    tile.legend.hi.textContent = fmt(header.hi, 2) + " m";
  }
}
function fill(id, items) {
  const box = document.getElementById(id);
  box.textContent = "";
  for (const i of items) box.append(i);
}
function onStatus(s) {
  statusCount++;
  document.body.dataset.statusCount = String(statusCount);
  const view = s.view || {tiles: []};
  view.tiles.forEach((t, i) => {
    const tile = tiles[i];
    if (!tile) return;
    tile.fps.textContent = fmt(t.fps, 1) + " fps";
    tile.div.dataset.viewFps = String(t.fps);
    tile.err.textContent = t.error || "";
  });
  const p = s.pipeline || {};
  fill("devices", (p.devices || []).map(d => {
    const li = el("li", "device state-" + String(d.state), d.name + ": " + d.state + (d.clock ? " · " + d.clock : ""));
    li.dataset.name = d.name; li.dataset.state = d.state;
    return li;
  }));
  const viewFps = {};
  view.tiles.forEach(t => { viewFps[t.stream] = t.fps; });
  const rows = (p.streams || []).map(st => {
    const tr = el("tr");
    tr.dataset.stream = st.name;
    tr.append(el("td", "", st.name), el("td", "", fmt(st.fps ?? "-", 1)),
              el("td", "", String(st.published ?? "-")), el("td", "", String(st.dropped ?? "-")),
              el("td", "", viewFps[st.name] !== undefined ? fmt(viewFps[st.name], 1) : "-"));
    return tr;
  });
  if (!p.streams) view.tiles.forEach(t => {
    const tr = el("tr");
    tr.append(el("td", "", t.stream), el("td", "", "-"), el("td", "", String(t.frames_in)),
              el("td", "", String(t.skipped)), el("td", "", fmt(t.fps, 1)));
    rows.push(tr);
  });
  document.querySelector("#streams tbody").replaceChildren(...rows);
  const lat = p.latency_ms;
  document.getElementById("latency").textContent = lat ?
    `p50 ${fmt(lat.p50, 1)} ms, p95 ${fmt(lat.p95, 1)} ms, p99 ${fmt(lat.p99, 1)} ms` : "-";
  const sy = p.sync;
  document.getElementById("sync").textContent = sy ?
    `skew mean ${fmt(sy.skew_ms_mean, 2)} ms, max ${fmt(sy.skew_ms_max, 2)} ms, sets ${sy.sets ?? "-"}, skipped ${sy.skipped ?? "-"}` : "-";
  const la = p.ladder;
  document.getElementById("ladder").textContent = la ?
    `rung ${la.rung} of ${la.rungs}${la.label ? " (" + la.label + ")" : ""}` : "-";
  const messages = (p.messages || []).map(m => el("li", "", String(m)));
  if (s.error) messages.unshift(el("li", "", s.error));
  fill("messages", messages);
  const known = new Set(["devices", "streams", "latency_ms", "sync", "ladder", "messages"]);
  document.querySelector("#other tbody").replaceChildren(...Object.keys(p).filter(k => !known.has(k)).map(k => {
    const tr = el("tr");
    tr.append(el("td", "", k), el("td", "", typeof p[k] === "object" ? JSON.stringify(p[k]) : String(p[k])));
    return tr;
  }));
  document.getElementById("summary").textContent = `${view.clients ?? "?"} browser(s)`;
}
// The view's token, when its URL has one, goes on to the WebSocket as the same query parameter.
// No cookie: a cookie is sent to every port of the host, so other servers there would get it.
const token = new URLSearchParams(location.search).get("token");
function connect() {
  const ws = new WebSocket((location.protocol === "https:" ? "wss://" : "ws://") + location.host + "/ws" +
                           (token ? "?token=" + encodeURIComponent(token) : ""));
  ws.binaryType = "arraybuffer";
  const conn = document.getElementById("conn");
  ws.onopen = () => { conn.textContent = "live"; conn.className = "up"; document.body.dataset.connected = "1"; };
  ws.onclose = () => {
    conn.textContent = "disconnected, retrying"; conn.className = "down";
    document.body.dataset.connected = "0";
    setTimeout(connect, 1000);
  };
  ws.onmessage = ev => {
    try {
      if (typeof ev.data !== "string") { onImage(ev.data); return; }
      const m = JSON.parse(ev.data);
      if (m.type === "config") setup(m);
      else if (m.type === "status") onStatus(m);
      else if (m.type === "overlay" && tiles[m.tile]) {
        const tile = tiles[m.tile];
        tile.overlay = m.overlay;
        tile.div.dataset.overlays = String(Number(tile.div.dataset.overlays) + 1);
        drawOverlay(tile);
      }
    } catch (e) {
      document.body.dataset.error = String(e);
    }
  };
}
connect();
</script></body></html>
)PAGE";

}  // namespace

std::string_view pageHtml() {
    return kPage;
}

}  // namespace mixray::liveview
