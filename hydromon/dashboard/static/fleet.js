// hydromon dashboard, fleet page: every rig, worst first, updated as the server pushes changes.
"use strict";

const MAX_ROWS = 500;  // rows drawn; the filter finds the others
const rows = new Map();   // rig -> row from the server
const trs = new Map();    // rig -> <tr>
let counts = null;
let match = rigMatcher("");

function orderKey(r) {
  return [r.flag !== null ? 1 : 0, r.status === "bad-input" ? 0 : 1, -(r.level === null ? -1 : r.level),
    r.status === "stale" ? 1 : 0, r.rig];
}
function compare(a, b) {
  const x = orderKey(a), y = orderKey(b);
  for (let i = 0; i < x.length; i++) { if (x[i] < y[i]) return -1; if (x[i] > y[i]) return 1; }
  return 0;
}

function makeTr(rig) {
  const tr = el("tr");
  tr.dataset.rig = rig;
  const cells = ["rig", "grade", "num", "status", "why", "num", "num", "node"].map((c) => el("td", c));
  cells[0].append(rigLink(rig));
  tr.append(...cells);
  tr._cells = cells;
  return tr;
}

function fillTr(tr, r, now) {
  const c = tr._cells;
  const chip = c[1].firstChild;
  if (!chip || chip.textContent !== r.grade) c[1].replaceChildren(gradeChip(r.grade));
  setText(c[2], r.confidence.toFixed(2));
  const status = r.status + (r.flag ? "" : "");
  if (c[3]._status !== status + "|" + r.flag) {
    c[3]._status = status + "|" + r.flag;
    c[3].replaceChildren(el("span", r.status === "bad-input" ? "bad" : null, r.status));
    if (r.flag) c[3].append(el("span", "flag", r.flag));
  }
  setText(c[4], r.why.length ? r.why.join("; ") : (r.level === 0 ? "every graded parameter in its health band" : ""));
  setText(c[5], duration(now - r.since));
  setText(c[6], duration(now - r.arrived));
  setText(c[7], r.node || "");
  tr.className = (r.flag ? "flagged " : "") + (r.status === "stale" ? "stale" : "");
}

function drawCounts() {
  const box = document.getElementById("counts");
  box.replaceChildren();
  if (!counts) return;
  box.append(el("span", "chip plain", counts.rigs + " rig(s)"));
  for (const g of [...GRADES].reverse().concat(["unknown"])) {
    const n = counts.grades[g];
    if (n) box.append(el("span", "chip g-" + g, n + " " + g));
  }
  if (counts.bad_input) box.append(el("span", "chip g-fault", counts.bad_input + " bad input"));
  if (counts.stale) box.append(el("span", "chip plain", counts.stale + " stale"));
  for (const [flag, n] of Object.entries(counts.flags || {})) box.append(el("span", "chip plain", n + " " + flag));
  if (counts.invalid) box.append(el("span", "chip plain", counts.invalid + " invalid payload(s) ignored"));
  box.append(el("span", "note", "monitors up: " + (counts.monitors.length ? counts.monitors.join(", ") : "none")));
}

function draw() {
  const tbody = document.querySelector("#fleet tbody");
  const all = [...rows.values()].filter((r) => match(r.rig)).sort(compare);
  const shown = all.slice(0, MAX_ROWS);
  const want = [], now = pageNow();
  for (const r of shown) {
    let tr = trs.get(r.rig);
    if (!tr) { tr = makeTr(r.rig); trs.set(r.rig, tr); }
    fillTr(tr, r, now);
    want.push(tr);
  }
  // put the rows in order, moving only those out of place
  let i = 0;
  for (const tr of want) {
    if (tbody.children[i] !== tr) tbody.insertBefore(tr, tbody.children[i] || null);
    i++;
  }
  while (tbody.children.length > want.length) tbody.lastChild.remove();
  setText(document.getElementById("shown"), all.length > shown.length ? "showing the first " + shown.length +
    " of " + all.length + " matching rigs" : all.length + " rig(s) shown");
  drawCounts();
}

let pending = false;
function schedule() {
  if (pending) return;
  pending = true;
  requestAnimationFrame(() => { pending = false; draw(); });
}

document.getElementById("filter").addEventListener("input", (e) => { match = rigMatcher(e.target.value); schedule(); });

connect({view: "fleet"}, (msg) => {
  if (msg.type === "fleet") { rows.clear(); }
  for (const r of msg.rows || []) rows.set(r.rig, r);
  if (msg.counts) counts = msg.counts;
  schedule();
}, schedule);
