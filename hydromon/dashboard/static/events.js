// hydromon dashboard, events page: grade and status changes and monitors leaving, newest first.
"use strict";

const MAX_ROWS = 1000;
const MAX_HELD = 5000;    // events the page keeps (the server's snapshot holds the newest 1000)
let events = [];          // newest first
let pointerOn = false, due = false;  // the table stands still under the pointer: rows must not move under a click
const byId = new Map();
let match = rigMatcher("");
let openOnly = false;

function eventRow(ev) {
  const tr = el("tr");
  tr.dataset.id = ev.id;
  tr.dataset.kind = ev.kind;
  const rig = el("td");
  if (ev.rig) rig.append(rigLink(ev.rig));
  const to = el("td");
  if (ev.kind === "grade") to.append(el("span", null, (ev.from || "") + " \u2192 "), gradeChip(ev.to));
  else to.textContent = eventChange(ev);
  const ack = el("td");
  ackCell(ack, ev);
  tr.append(el("td", null, clock(ev.wall)), rig, el("td", null, ev.kind), to, el("td", null, ev.reason || ""),
    el("td", null, ev.node || ""), ack);
  return tr;
}

function draw() {
  const tbody = document.querySelector("#events tbody");
  const shown = events.filter((e) => (e.rig ? match(e.rig) : true) && !(openOnly && e.ack)).slice(0, MAX_ROWS);
  tbody.replaceChildren(...shown.map(eventRow));
  const open = events.filter((e) => !e.ack).length;
  setText(document.getElementById("shown"), shown.length + " shown of " + events.length + "; " + open + " not acknowledged");
}

const table = document.getElementById("events");
table.addEventListener("mouseenter", () => { pointerOn = true; });
table.addEventListener("mouseleave", () => { pointerOn = false; if (due) { due = false; draw(); } });
document.getElementById("filter").addEventListener("input", (e) => { match = rigMatcher(e.target.value); draw(); });
document.getElementById("open-only").addEventListener("change", (e) => { openOnly = e.target.checked; draw(); });

connect({view: "events"}, (msg) => {
  if (msg.type === "events") {
    events = msg.events.slice();
    byId.clear();
    for (const e of events) byId.set(e.id, e);
  } else if (msg.type === "events-delta") {
    for (const e of msg.events) { events.unshift(e); byId.set(e.id, e); }
    for (const e of events.splice(MAX_HELD)) byId.delete(e.id);
  } else if (msg.type === "ack") {
    const old = byId.get(msg.event.id);
    if (old) old.ack = msg.event.ack;
  } else return;
  // an acknowledgement form being typed in is not redrawn away
  if (document.activeElement && document.activeElement.closest && document.activeElement.closest("form.ackform")) return;
  if (pointerOn && msg.type !== "events") { due = true; return; }  // drawn when the pointer leaves
  draw();
});
