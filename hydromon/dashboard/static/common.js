// hydromon dashboard: what the three pages share. Every text from the server is put in the page
// with textContent (never as markup), so a rig id, a reason or a parameter name cannot inject.
"use strict";

const GRADES = ["health", "sub-health", "average", "deterioration", "fault"];
const GRADE_COLOURS = {health: "#2e7d32", "sub-health": "#9ccc65", average: "#fdd835",
  deterioration: "#fb8c00", fault: "#c62828", unknown: "#bdbdbd"};  // as hydromon.report.zones

function el(tag, cls, text) {
  const e = document.createElement(tag);
  if (cls) e.className = cls;
  if (text !== undefined && text !== null) e.textContent = String(text);
  return e;
}

function setText(e, text) {
  const s = text === undefined || text === null ? "" : String(text);
  if (e.textContent !== s) e.textContent = s;
}

function gradeChip(grade) {
  const g = GRADE_COLOURS[grade] ? grade : "unknown";
  return el("span", "chip g-" + g, grade);
}

function duration(s) {
  if (s === null || s === undefined || !isFinite(s)) return "-";
  s = Math.max(0, s);
  if (s < 10) return s.toFixed(1) + " s";
  if (s < 120) return Math.round(s) + " s";
  if (s < 7200) return Math.round(s / 60) + " min";
  if (s < 172800) return (s / 3600).toFixed(1) + " h";
  return (s / 86400).toFixed(1) + " d";
}

function clock(wall) {
  if (wall === null || wall === undefined) return "-";
  const d = new Date(wall * 1000);
  return d.toLocaleString(undefined, {hour12: false, timeZoneName: "short"});  // whose clock: say so
}

// a rig pattern: '*' matches any run of characters; without '*' a substring
function rigMatcher(text) {
  text = (text || "").trim();
  if (!text) return () => true;
  if (text.indexOf("*") < 0) return (rig) => rig.indexOf(text) >= 0;
  const re = new RegExp("^" + text.split("*").map((p) => p.replace(/[.+?^${}()|[\]\\]/g, "\\$&")).join(".*") + "$");
  return (rig) => re.test(rig);
}

function rigLink(rig) {
  const a = el("a", null, rig);
  a.href = "/rig/" + encodeURIComponent(rig);
  return a;
}

function showSource(info) {
  const e = document.getElementById("source");
  if (!e || !info) return;
  if (info.source === "recording") setText(e, "recording " + info.recording + (info.verdicts === 0 ?
    ": it holds no health verdicts (recorded without a monitor on the bus); grade it with hydromon evaluate" : ""));
  else if (info.source === "bus") setText(e, "live: " + info.namespace + "/rig/" + info.rigs);
}

// the server's clock as last heard [s since the epoch]: a live source's clock runs on with the
// browser's while no message comes (so ages keep counting when the server is gone); a
// recording's stands at its end
const heard = {now: 0, at: 0, live: false};
function pageNow() {
  return heard.live ? heard.now + Math.max(0, Date.now() / 1000 - heard.at) : heard.now;
}

// the push channel: a snapshot first, then what changed; reconnects (and gets a new snapshot).
// While it is down the page says since when, greys what it shows (the grades are as they were
// then, not live) and calls onOffline every second so that ages keep counting.
function connect(params, onMessage, onOffline) {
  const conn = document.getElementById("conn");
  let delay = 500, downSince = null, ticker = null;
  function open() {
    const url = (location.protocol === "https:" ? "wss://" : "ws://") + location.host + "/ws?" + new URLSearchParams(params);
    const ws = new WebSocket(url);
    ws.onopen = () => { delay = 500; };
    ws.onmessage = (ev) => {
      const msg = JSON.parse(ev.data);
      if (msg.info) { showSource(msg.info); heard.live = msg.info.source === "bus"; }
      if (typeof msg.now === "number") { heard.now = msg.now; heard.at = Date.now() / 1000; }
      if (downSince !== null || conn.className !== "") {  // back: the snapshot that came first is current
        downSince = null;
        clearInterval(ticker);
        document.body.classList.remove("offline");
        conn.className = "";
      }
      setText(conn, heard.live ? "live" : "recording");
      onMessage(msg);
    };
    ws.onclose = () => {
      if (downSince === null) {
        downSince = Date.now() / 1000;
        document.body.classList.add("offline");
        if (onOffline) ticker = setInterval(onOffline, 1000);
      }
      conn.className = "down";
      setText(conn, "disconnected from the dashboard server since " + clock(downSince) +
        ": what is shown is as it was then, not live; retrying");
      setTimeout(open, delay);
      delay = Math.min(delay * 2, 8000);
    };
  }
  open();
}

function postAck(id, comment, by) {
  return fetch("/api/events/" + encodeURIComponent(id) + "/ack", {
    method: "POST", headers: {"content-type": "application/json"},
    body: JSON.stringify({comment: comment, by: by}),
  }).then((r) => { if (!r.ok) return r.text().then((t) => { throw new Error(t); }); return r.json(); });
}

// one event's acknowledgement cell: the comment, or a form to write one
function ackCell(td, ev) {
  td.replaceChildren();
  if (ev.ack) {
    const a = ev.ack;
    td.append(el("span", "ack", "acknowledged"), el("span", null, " " + clock(a.wall) + (a.by ? " by " + a.by : "")));
    if (a.comment) td.append(el("div", "muted", a.comment));
    return;
  }
  const b = el("button", null, "acknowledge");
  b.type = "button";
  b.addEventListener("click", () => {
    const f = el("form", "ackform");
    const c = el("input"); c.type = "text"; c.placeholder = "comment"; c.maxLength = 500; c.name = "comment";
    const by = el("input"); by.type = "text"; by.placeholder = "name"; by.maxLength = 64; by.size = 10; by.name = "by";
    const ok = el("button", null, "save"); ok.type = "submit";
    f.append(c, by, ok);
    f.addEventListener("submit", (e) => {
      e.preventDefault();
      postAck(ev.id, c.value, by.value).then((done) => ackCell(td, done)).catch((err) => {
        td.append(el("div", "bad", String(err.message || err)));
      });
    });
    td.replaceChildren(f);
    c.focus();
  });
  td.append(b);
}

function eventChange(ev) {
  return (ev.from === undefined ? "" : ev.from) + " \u2192 " + (ev.to === undefined ? "" : ev.to);
}
