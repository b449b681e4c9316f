// mip-view's page: draws the server's state (Server-Sent Events from /api/events) and sends the
// controls (POST /api/control). Plain JS, no library: everything it draws comes from the server
// (the diagram is docs/tools/seqdiag.py's SVG).
"use strict";

const $ = (id) => document.getElementById(id);
let last = null;                 // the last state drawn
const recent = {};               // register cell key -> real time (ms) of its last change
const RECENT_MS = 2000;          // a changed register stays tinted this long

function esc(s) {
  return String(s).replace(/[&<>"]/g, (c) => ({"&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;"}[c]));
}

let pending = 0;                 // controls sent, not answered yet (data-pending: for tests)

async function control(body) {
  $("message").textContent = "";
  document.body.dataset.pending = ++pending;
  try {
    const r = await fetch("/api/control", {method: "POST", headers: {"Content-Type": "application/json"},
                                           body: JSON.stringify(body)});
    const j = await r.json();
    if (!r.ok) { $("message").textContent = j.error; return; }
    draw(j);
  } catch (e) {
    $("message").textContent = "the server does not answer (" + e + ")";
  } finally {
    document.body.dataset.pending = --pending;
  }
}

function drawRegisters(st) {
  const now = Date.now();
  let html = "";
  for (const w of st.registers) {
    html += `<div class="caption">${esc(w.title)}</div><table class="regs"><tr>`;
    w.values.forEach((v, i) => html += `<th>${w.start + i}</th>`);
    html += "</tr><tr>";
    w.values.forEach((v, i) => {
      const key = w.start + ":" + i + ":" + w.title;
      let cls = "";
      if (w.changed.includes(i)) { recent[key] = now; cls = "changed"; }
      else if (recent[key] && now - recent[key] < RECENT_MS) cls = "recent";
      html += `<td class="${cls}" data-addr="${w.start + i}">${v}</td>`;
    });
    html += "</tr></table>";
  }
  $("registers").innerHTML = html;
}

function drawBlocks(st) {
  let html = "";
  for (const b of st.blocks) {
    html += `<table class="block${b.off ? " off" : ""}" id="block-${b.side}"><tr><th colspan="2">` +
            `${esc(b.side)} PLC: ${esc(b.block)}${b.off ? " (off)" : ""}</th></tr>`;
    for (const v of b.vars) {
      const cls = v.name === "eState" ? "state" : "";
      html += `<tr><td>${esc(v.name)}</td><td class="${cls}" data-var="${esc(v.name)}">${esc(v.value)}</td></tr>`;
    }
    html += "</table>";
  }
  $("blocks").innerHTML = html;
}

function drawRadio(st) {
  const r = st.radio;
  $("radio").innerHTML = `<table id="radio-table"><tr><th></th><th>telegrams</th><th>lost</th></tr>` +
    `<tr><td>down (MDP &rarr; TRM)</td><td>${r.down}</td><td class="${r.lost_down ? "lost" : ""}">${r.lost_down}</td></tr>` +
    `<tr><td>up (TRM &rarr; MDP)</td><td>${r.up}</td><td class="${r.lost_up ? "lost" : ""}">${r.lost_up}</td></tr></table>` +
    (r.polls !== undefined ? `<div class="caption">${r.polls} polls</div>` : "") +
    (st.lines !== undefined ? `<div class="caption">${st.lines} trace lines</div>` : "");
}

function fillOptions(st) {
  if (st.mode !== "live" || $("preset").options.length) return;
  for (const [k, p] of Object.entries(st.presets)) {
    const o = document.createElement("option");
    o.value = k;
    o.textContent = (p.exercise ? "Exercise " + p.exercise + ": " : "") + p.title;
    $("preset").appendChild(o);
  }
  for (const s of st.speeds) {
    const o = document.createElement("option");
    o.value = s; o.textContent = s;
    $("speed").appendChild(o);
  }
}

function draw(st) {
  if (last && st.boot !== last.boot) last = null;     // another server (restarted): start over
  // the same state twice (a control's answer and its event) or an older one: nothing to draw
  if (last && st.version <= last.version) return;
  const before = last;
  last = st;
  document.body.className = st.mode;
  fillOptions(st);
  $("title").textContent = st.title;
  $("time").textContent = st.t_ms;
  $("status").textContent = st.paused ? "paused" : (st.done ? "transfer complete" : "running");
  $("pause").textContent = st.paused ? "Resume" : "Pause";
  $("diagram").innerHTML = st.svg;
  drawBlocks(st);
  drawRadio(st);
  drawRegisters(st);
  $("note").textContent = st.note || "";
  if (st.error) $("message").textContent = st.error;
  if (st.bad) $("message").textContent = st.bad;
  if (st.mode === "live") {
    // the lists follow the run only when it changed them: a choice being made stays
    if (!before || before.preset !== st.preset) $("preset").value = st.preset;
    if (!before || before.speed !== st.speed) $("speed").value = st.speed;
    $("mipsim").textContent = "mipsim " + st.mipsim;
    for (const d of ["up", "down"]) {
      if (document.activeElement !== $("loss-" + d)) $("loss-" + d).value = st.extra_loss[d];
      $("loss-" + d + "-val").textContent = st.extra_loss[d];
    }
    $("lose-record").classList.toggle("armed", st.lose_next.record);
    $("lose-ack").classList.toggle("armed", st.lose_next.ack);
  }
  document.body.dataset.version = st.version;
}

$("pause").onclick = () => control({action: last && last.paused ? "resume" : "pause"});
$("step-scan").onclick = () => control({action: "step_scan"});
$("step-slot").onclick = () => control({action: "step_slot"});
$("speed").onchange = (e) => control({action: "speed", value: Number(e.target.value)});
for (const d of ["up", "down"]) {
  $("loss-" + d).onchange = (e) => control({action: "loss", direction: d, value: Number(e.target.value)});
}
$("lose-record").onclick = () => control({action: "lose", what: "record"});
$("lose-ack").onclick = () => control({action: "lose", what: "ack"});
for (const plc of ["outstation", "central"]) {
  for (const kind of ["cold", "warm"]) {
    $(`restart-${plc}-${kind}`).onclick = () => control({action: "restart", plc, kind, outage_ms: 1000});
  }
}
$("start-preset").onclick = () => control({action: "preset", name: $("preset").value});

const events = new EventSource("/api/events");
events.onmessage = (e) => draw(JSON.parse(e.data));
events.onerror = () => { $("status").textContent = "disconnected"; };
