// hydromon dashboard, rig page: every parameter over time with its +-3 SE band against the health
// bands, the grade timeline, and the rig's events.
"use strict";

const RIG = decodeURIComponent(location.pathname.split("/").pop());
const STATUS_BAD = {"bad-input": 1, stale: 1};
let data = null;       // columns: wall, t, level, status, conf, value{p}, se{p}
let ranges = null, units = {}, words = {}, params = [], gradedNames = [];
const plots = new Map();  // param -> uPlot
let row = null;
const evs = [];

function zonesOf(r) {
  // [lo, hi, grade] of each band, from the four edges in grade order or the fault threshold
  const inf = Infinity, rising = r.direction === "rising";
  const e = r.edges ? r.edges : [r.threshold, r.threshold, r.threshold, r.threshold];
  const bounds = rising ? [-inf].concat(e, [inf]) : [inf].concat(e, [-inf]);
  const out = [];
  for (let i = 0; i < 5; i++) {
    if (!r.edges && i > 0 && i < 4) continue;
    const a = bounds[i], b = r.edges || i < 4 ? bounds[i + 1] : bounds[5];
    out.push([Math.min(a, b), Math.max(a, b), GRADES[i]]);
  }
  return out;
}

function hexAlpha(hex, a) {
  const n = parseInt(hex.slice(1), 16);
  return "rgba(" + (n >> 16) + "," + ((n >> 8) & 255) + "," + (n & 255) + "," + a + ")";
}

function zonesHook(p) {
  return (u) => {
    const r = ranges && ranges[p];
    if (!r) return;
    const ctx = u.ctx, b = u.bbox;
    ctx.save();
    ctx.font = Math.round(11 * devicePixelRatio) + "px system-ui, sans-serif";
    for (const [lo, hi, g] of zonesOf(r)) {
      const y0 = Math.max(b.top, Math.min(b.top + b.height, u.valToPos(Math.min(hi, u.scales.y.max), "y", true)));
      const y1 = Math.max(b.top, Math.min(b.top + b.height, u.valToPos(Math.max(lo, u.scales.y.min), "y", true)));
      if (y1 - y0 < 1) continue;
      ctx.fillStyle = hexAlpha(GRADE_COLOURS[g], 0.16);
      ctx.fillRect(b.left, y0, b.width, y1 - y0);
      if (y1 - y0 > 14 * devicePixelRatio) {
        ctx.fillStyle = g === "average" || g === "sub-health" ? "#5d4037" : hexAlpha(GRADE_COLOURS[g], 0.95);
        ctx.textAlign = "right";  // at the right: the axis' numbers are at the left
        ctx.fillText(g, b.left + b.width - 4 * devicePixelRatio, y0 + 12 * devicePixelRatio);
      }
    }
    if (r.baseline !== null && r.baseline !== undefined) {
      const y = u.valToPos(r.baseline, "y", true);
      if (y >= b.top && y <= b.top + b.height) {
        ctx.strokeStyle = "#5f6b76"; ctx.setLineDash([4, 4]); ctx.beginPath();
        ctx.moveTo(b.left, y); ctx.lineTo(b.left + b.width, y); ctx.stroke();
      }
    }
    ctx.restore();
  };
}

function yRange(p) {
  return (u, dmin, dmax) => {
    let lo = Infinity, hi = -Infinity;
    for (const v of (data ? data.value[p] : [])) if (v !== null) { lo = Math.min(lo, v); hi = Math.max(hi, v); }
    const r = ranges && ranges[p];
    if (r) for (const e of (r.edges || [r.threshold])) { lo = Math.min(lo, e); hi = Math.max(hi, e); }
    if (r && r.baseline !== null && r.baseline !== undefined) { lo = Math.min(lo, r.baseline); hi = Math.max(hi, r.baseline); }
    if (!isFinite(lo)) return [0, 1];
    const pad = (hi - lo) * 0.12 || Math.abs(hi) * 0.1 || 1;
    return [lo - pad, hi + pad];
  };
}

function columns(p) {
  const v = data.value[p], se = data.se[p];
  const hi = v.map((x, i) => (x === null || se[i] === null) ? null : x + 3 * se[i]);
  const lo = v.map((x, i) => (x === null || se[i] === null) ? null : x - 3 * se[i]);
  return [data.wall, v, hi, lo];
}

// axis ticks with the digits their spacing needs (a valve damping of 99.95 .. 100.05 rad/s)
function ticks(u, vals, axis, space, incr) {
  return vals.map((v) => {
    if (v === null) return "";
    if (v === 0) return "0";
    const a = Math.abs(v);
    if (a !== 0 && (a < 1e-3 || a >= 1e6)) return v.toExponential(Math.max(1, Math.min(6, Math.ceil(Math.log10(a / incr)))));
    const digits = Math.max(0, -Math.floor(Math.log10(incr)));
    return v.toFixed(Math.min(digits, 8));
  });
}

function fmt(v) {
  if (v === null || v === undefined) return "-";
  const a = Math.abs(v);
  return a !== 0 && (a < 1e-3 || a >= 1e5) ? v.toExponential(2) : String(+v.toPrecision(4));
}

// time axis labels on a 24-hour clock and ISO dates, whatever the browser's locale (the page's
// times name their zone): dates alone for steps of days, with the time over a span of days,
// fractions of a second for a recording made faster than real time
function timeTicks(u, splits, axisIdx, space, incr) {
  const two = (n) => String(n).padStart(2, "0");
  const frac = incr < 1 ? ((+incr.toFixed(3)).toString().split(".")[1] || "").length : 0;
  const days = u && u.scales && u.scales.x.max - u.scales.x.min > 86400;
  return splits.map((t) => {
    const ms = Math.round(t * 1000);
    const d = new Date(ms);
    const date = d.getFullYear() + "-" + two(d.getMonth() + 1) + "-" + two(d.getDate());
    if (incr >= 86400) return date;
    let time = two(d.getHours()) + ":" + two(d.getMinutes());
    if (incr < 60) time += ":" + two(d.getSeconds());
    if (frac) time += "." + String(d.getMilliseconds()).padStart(3, "0").slice(0, frac);
    return days ? date + " " + time : time;
  });
}

// one verdict (or several at one time) spans nothing, and uPlot pads a lone time by a day each
// way: a minute around it instead
function timeRange(u, min, max) {
  const x = u.data[0];
  return x.length && x[0] === x[x.length - 1] ? [x[0] - 30, x[0] + 30] : [min, max];
}

function makePlot(p, box) {
  const unit = units[p] || "";
  const div = el("div", "plot");
  div.dataset.param = p;
  div.append(el("h3", null, RIG + ": " + p + " (" + (words[p] || p) + ") [" + unit + "]"));
  box.append(div);
  const width = Math.max(380, div.clientWidth - 10);
  const opts = {
    width: width, height: 220,
    scales: {x: {time: true, range: timeRange}, y: {range: yRange(p)}},
    axes: [{label: "time (" + RIG + ")", values: timeTicks}, {label: p + " [" + unit + "]", size: 70, values: ticks}],
    series: [{value: (u, v) => (v === null ? "-" : clock(v))}, {label: p + " [" + unit + "]", stroke: "#1d2228", width: 1.5, value: (u, v) => fmt(v)},
      {label: "+3 SE", stroke: "rgba(29,34,40,0.25)", value: (u, v) => fmt(v)},
      {label: "-3 SE", stroke: "rgba(29,34,40,0.25)", value: (u, v) => fmt(v)}],
    bands: [{series: [2, 3], fill: "rgba(29,34,40,0.10)"}],
    hooks: {drawClear: [zonesHook(p)]},
    legend: {show: true},
  };
  plots.set(p, new uPlot(opts, columns(p), div));
}

function drawPlots() {
  if (!data || typeof uPlot === "undefined") return;
  // graded: the parameters the rig's ranges grade (or, without its ranges, those its verdict grades)
  const isGraded = (p) => (ranges ? !!ranges[p] : gradedNames.indexOf(p) >= 0);
  const graded = params.filter(isGraded);
  const others = params.filter((p) => !isGraded(p));
  for (const [p, box] of graded.map((p) => [p, "graded"]).concat(others.map((p) => [p, "others"]))) {
    const u = plots.get(p);
    if (!u) makePlot(p, document.getElementById(box));
    else u.setData(columns(p));
  }
}

function drawTimeline() {
  const c = document.getElementById("timeline");
  const w = c.clientWidth || 1200;
  c.width = w * devicePixelRatio; c.height = 34 * devicePixelRatio;
  const ctx = c.getContext("2d");
  ctx.clearRect(0, 0, c.width, c.height);
  if (!data || !data.wall.length) return;
  const t0 = data.wall[0], t1 = Math.max(pageNow(), data.wall[data.wall.length - 1]);
  const x = (t) => (t - t0) / Math.max(t1 - t0, 1e-9) * c.width;
  for (let i = 0; i < data.wall.length; i++) {
    const g = data.level[i] >= 0 ? GRADES[data.level[i]] : "unknown";
    const xa = x(data.wall[i]), xb = i + 1 < data.wall.length ? x(data.wall[i + 1]) : c.width;
    ctx.fillStyle = GRADE_COLOURS[g];
    ctx.fillRect(xa, 0, Math.max(1, xb - xa), c.height * 0.7);
    if (STATUS_BAD[data.status[i]]) { ctx.fillStyle = "#6a1b9a"; ctx.fillRect(xa, c.height * 0.75, Math.max(1, xb - xa), c.height * 0.25); }
  }
  ctx.fillStyle = "#1d2228";
  ctx.font = Math.round(11 * devicePixelRatio) + "px system-ui, sans-serif";
  ctx.fillText(clock(t0), 4, c.height * 0.55);
  const last = clock(t1), tw = ctx.measureText(last).width;
  ctx.fillText(last, c.width - tw - 4, c.height * 0.55);
}

function drawHeader() {
  setText(document.getElementById("rig"), RIG);
  document.title = "hydromon - " + RIG;
  const g = document.getElementById("grade");
  g.replaceChildren();
  if (!row) { setText(document.getElementById("status"), "no verdict yet"); return; }
  g.append(gradeChip(row.grade));
  const st = document.getElementById("status");
  st.replaceChildren(el("span", row.status === "bad-input" ? "bad" : null, row.status));
  if (row.flag) st.append(el("span", "flag", row.flag));
  setText(document.getElementById("conf"), "confidence " + row.confidence.toFixed(2));
  const now = pageNow();
  setText(document.getElementById("since"), "since " + duration(now - row.since) + "; verdict " + duration(now - row.arrived) + " old");
  setText(document.getElementById("node"), row.node ? "monitor " + row.node : "");
  setText(document.getElementById("why"), row.why.length ? "why: " + row.why.join("; ") : "");
}

function drawEvents() {
  const tbody = document.querySelector("#events tbody");
  tbody.replaceChildren(...evs.map((ev) => {
    const tr = el("tr");
    const ack = el("td");
    ackCell(ack, ev);
    tr.append(el("td", null, clock(ev.wall)), el("td", null, ev.kind), el("td", null, eventChange(ev)),
      el("td", null, ev.reason || ""), ack);
    return tr;
  }));
}

function drawLegend() {
  const lg = document.getElementById("legend");
  lg.replaceChildren();
  for (const g of GRADES.concat(["unknown"])) {
    const s = el("span", null, g);
    const i = el("i"); i.style.background = GRADE_COLOURS[g];
    s.prepend(i); lg.append(s);
  }
  const s = el("span", null, "stale or bad input (lower strip)");
  const i = el("i"); i.style.background = "#6a1b9a"; s.prepend(i); lg.append(s);
}

function append(points) {
  if (!data) { data = points; return; }
  // points already held (a snapshot and the first push may overlap) are skipped
  const last = data.wall.length ? data.wall[data.wall.length - 1] : -Infinity;
  let k = 0;
  while (k < points.wall.length && points.wall[k] <= last) k++;
  if (k === points.wall.length) return;
  if (k > 0) {
    for (const c of ["wall", "t", "level", "status", "conf"]) points[c] = points[c].slice(k);
    for (const p of params) { points.value[p] = points.value[p].slice(k); points.se[p] = points.se[p].slice(k); }
  }
  for (const k of ["wall", "t", "level", "status", "conf"]) data[k].push(...points[k]);
  for (const p of params) { data.value[p].push(...points.value[p]); data.se[p].push(...points.se[p]); }
  const limit = 1200;
  if (data.wall.length > limit) {
    const cut = data.wall.length - limit;
    for (const k of ["wall", "t", "level", "status", "conf"]) data[k].splice(0, cut);
    for (const p of params) { data.value[p].splice(0, cut); data.se[p].splice(0, cut); }
  }
}

drawLegend();
connect({view: "rig", rig: RIG}, (msg) => {
  if (msg.type === "rig") {
    params = msg.params; units = msg.units; words = msg.words; ranges = msg.ranges; row = msg.row;
    gradedNames = msg.health ? Object.keys(msg.health.param_grades) : [];
    data = msg.points;
    evs.length = 0; evs.push(...msg.events);
    for (const u of plots.values()) u.destroy();
    plots.clear();
    for (const id of ["graded", "others"]) document.getElementById(id).replaceChildren();
    setText(document.getElementById("rangesnote"), !ranges ? (msg.live === false ?
      "Health ranges: a recording holds none (give the dashboard --ranges FILE): no bands drawn." :
      "Health ranges: not known yet (the rig's monitor has not answered the ranges query): no bands drawn.") :
      (msg.ranges_from === "fallback" ? "Health ranges: the dashboard's --ranges (the monitor did not answer the ranges query)." :
        "Health ranges: as the rig's monitor grades it; dashed line: the rig's baseline."));
    drawEvents();
  } else if (msg.type === "rig-delta") {
    if (msg.row) row = msg.row;
    if (msg.points) append(msg.points);
    if (msg.events && msg.events.length) { evs.unshift(...msg.events.reverse()); drawEvents(); }
  } else if (msg.type === "ack") {
    const e = evs.find((x) => x.id === msg.event.id);
    if (e) { e.ack = msg.event.ack; drawEvents(); }
    return;
  }
  drawHeader();
  drawPlots();
  drawTimeline();
}, () => { drawHeader(); drawTimeline(); });
