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
    w.values.forEach((v, i) => html += `<th title="${esc(w.tips[i])}">${w.start + i}<br><span class="name">${esc(w.names[i])}</span></th>`);
    html += "</tr><tr>";
    w.values.forEach((v, i) => {
      const key = w.start + ":" + i + ":" + w.title;
      let cls = "";
      if (w.changed.includes(i)) { recent[key] = now; cls = "changed"; }
      else if (recent[key] && now - recent[key] < RECENT_MS) cls = "recent";
      html += `<td class="${cls}" data-addr="${w.start + i}" data-value="${v}" title="${esc(w.tips[i])}">${esc(w.shown[i])}</td>`;
    });
    html += "</tr></table>";
  }
  $("registers").innerHTML = html || `<div class="caption">not in a trace: the modems' registers are read in a live run</div>`;
}

function drawBlocks(st) {
  let html = "";
  for (const b of st.blocks) {
    html += `<table class="block${b.off ? " off" : ""}" id="block-${b.side}"><tr><th colspan="2">` +
            `${esc(b.head || b.side + " PLC")}: ${esc(b.block)}${b.off ? " (off)" : ""}</th></tr>`;
    for (const v of b.vars) {
      const cls = v.name === "eState" ? "state" : "";
      html += `<tr><td title="${esc(v.tip || "")}">${esc(v.name)}</td><td class="${cls}" data-var="${esc(v.name)}">${esc(v.value)}</td></tr>`;
    }
    html += "</table>";
  }
  $("blocks").innerHTML = html || `<div class="caption">not in a trace: the blocks' states are shown in a live run</div>`;
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
  document.body.className = st.mode + (st.chain ? " chain" : "");
  fillOptions(st);
  $("title").textContent = st.title;
  $("time").textContent = st.t_ms;
  $("status").textContent = st.paused ? "paused" : (st.done ? "transfer complete" : "running");
  $("pause").textContent = st.paused ? "Resume" : "Pause";
  drawDiagram(st);
  drawBlocks(st);
  drawRadio(st);
  drawRegisters(st);
  $("note").textContent = st.note || "";
  if (st.error) $("message").textContent = st.error;
  drawBad(st);
  if (st.mode === "live") {
    // the lists follow the run only when it changed them: a choice being made stays
    if (!before || before.preset !== st.preset) $("preset").value = st.preset;
    if (!before || before.speed !== st.speed) $("speed").value = st.speed;
    $("mipsim").textContent = st.chain ? st.mipsim : "mipsim " + st.mipsim;
    for (const d of ["up", "down"]) {
      if (document.activeElement !== $("loss-" + d)) $("loss-" + d).value = st.extra_loss[d];
      $("loss-" + d + "-val").textContent = st.extra_loss[d];
    }
    $("lose-record").classList.toggle("armed", st.lose_next.record);
    $("lose-ack").classList.toggle("armed", st.lose_next.ack);
    $("link").href = "?" + new URLSearchParams({preset: st.preset, t: st.t_ms, speed: st.speed});
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

// ---------------------------------------------------------------- the whole history
// The diagram is the run's whole history, CHUNK rows an SVG (the server's rows.History): the
// last chunk comes with each state, the others are fetched when their key changes. The box
// stays at the bottom while the run goes on, unless the user scrolled up.
const chunkKeys = {};           // chunk number -> key drawn
let stick = true;               // the box follows the end (until the user scrolls up)

function toEnd() {
  const box = $("diagram-box");
  if (stick && !searching) box.scrollTop = box.scrollHeight;
}

$("diagram-box").addEventListener("scroll", () => {
  const box = $("diagram-box");
  stick = box.scrollTop + box.clientHeight >= box.scrollHeight - 40;
  drawLanes();
});

// the lifelines' names stay on top while the diagram scrolls: the head of the last chunk's
// SVG (seqdiag draws its background, title and "time" first, then each lifeline's line,
// box and name), cut to the names' height
const HEAD_ELEMENTS = 15, HEAD_TOP = 44, HEAD_H = 30;

function drawLanes() {
  const box = $("diagram-box"), lanes = $("lanes");
  const svgs = document.querySelectorAll("#diagram .chunk svg");
  lanes.style.display = box.scrollTop > 60 && svgs.length ? "flex" : "none";
  if (lanes.style.display === "none") return;
  const src = svgs[svgs.length - 1];
  if (lanes.dataset.key === src.parentNode.dataset.key) return;
  const c = src.cloneNode(false);
  [...src.children].slice(0, HEAD_ELEMENTS).forEach((e) => c.appendChild(e.cloneNode(true)));
  const vb = src.getAttribute("viewBox").split(" ");
  c.setAttribute("viewBox", `${vb[0]} ${HEAD_TOP} ${vb[2]} ${HEAD_H}`);
  c.setAttribute("height", HEAD_H);
  lanes.replaceChildren(c);
  lanes.dataset.key = src.parentNode.dataset.key;
}

function chunkDiv(i) {
  let div = document.querySelector(`#diagram .chunk[data-i="${i}"]`);
  if (!div) {
    div = document.createElement("div");
    div.className = "chunk";
    div.dataset.i = i;
    $("diagram").appendChild(div);
  }
  return div;
}

async function fetchChunk(i, key) {
  try {
    const r = await fetch("/api/chunk?i=" + i);
    if (!r.ok) return;
    const k = r.headers.get("X-Chunk-Key"), svg = await r.text();
    if (chunkKeys[i] !== key || k !== key) return;      // a newer state asked for another
    chunkDiv(i).innerHTML = svg;
    chunkDiv(i).dataset.key = k;
    markHits();
    toEnd();
  } catch (e) { /* the next state asks again */ }
}

function drawDiagram(st) {
  const last = st.chunks.length - 1;
  document.querySelectorAll("#diagram .chunk").forEach((d) => {
    if (Number(d.dataset.i) > last) { d.remove(); delete chunkKeys[d.dataset.i]; }
  });
  for (const c of st.chunks) chunkDiv(c.i);     // in order, before any is filled
  for (const c of st.chunks) {
    if (chunkKeys[c.i] === c.key) continue;
    chunkKeys[c.i] = c.key;
    if (c.i === last) {
      chunkDiv(c.i).innerHTML = st.svg;
      chunkDiv(c.i).dataset.key = c.key;
    } else {
      fetchChunk(c.i, c.key);
    }
  }
  $("diagram").dataset.rows = st.nrows;
  markHits();
  toEnd();
}

// search: every label of the history that contains the text; Enter goes to the next one
let hits = [], hit = -1, searching = false;

function markHits() {
  const q = $("search").value.trim().toLowerCase();
  hits = [];
  document.querySelectorAll("#diagram svg text").forEach((t) => {
    const on = q !== "" && t.textContent.toLowerCase().includes(q);
    t.classList.toggle("hit", on);
    t.classList.remove("current");
    if (on) hits.push(t);
  });
  searching = q !== "";
  if (hit >= hits.length) hit = hits.length - 1;
  if (hit >= 0 && hits[hit]) hits[hit].classList.add("current");
  $("search-info").textContent = !searching ? "" :
    (hits.length ? `${hit + 1} of ${hits.length}` : "not found");
}

function nextHit(back) {
  markHits();
  if (!hits.length) return;
  hit = back ? (hit - 1 + hits.length) % hits.length : (hit + 1) % hits.length;
  markHits();
  hits[hit].scrollIntoView({block: "center"});
}

$("search").addEventListener("keydown", (e) => {
  if (e.key === "Enter") { e.preventDefault(); nextHit(e.shiftKey); }
});
$("search").addEventListener("input", () => { hit = -1; nextHit(false); });

function drawBad(st) {
  const lines = st.bad_lines || [];
  const more = (st.bad_count || 0) - lines.length;
  $("bad").innerHTML = lines.map((x) => `<li>${esc(x)}</li>`).join("") +
    (more > 0 ? `<li>and ${more} more lines skipped (the log has each)</li>` : "");
}

// ---------------------------------------------------------------- deep links
// ?preset=ex2&t=1500&speed=0.5 (&step=N radio slots, &paused=1): the page starts that preset
// anew, runs it to virtual time t (or N radio slots) and pauses there, at that speed.
async function deepLink(st) {
  const q = new URLSearchParams(location.search);
  const keys = ["preset", "t", "step", "speed", "paused"].filter((k) => q.has(k));
  if (!keys.length) return;
  if (st.mode !== "live") {
    $("message").textContent = `the link's ${keys.join(", ")}: a follow view has no runs to choose (read-only)`;
    return;
  }
  const run = async (body) => {
    const r = await fetch("/api/control", {method: "POST", headers: {"Content-Type": "application/json"},
                                           body: JSON.stringify(body)});
    const j = await r.json();
    if (!r.ok) throw new Error("the link: " + j.error);
    draw(j);
  };
  document.body.dataset.pending = ++pending;
  try {
    const t = q.has("t") ? Number(q.get("t")) : 0, step = q.has("step") ? Number(q.get("step")) : 0;
    if (q.has("t") && !(Number.isInteger(t) && t >= 0 && t <= 600000)) throw new Error("the link: t must be 0..600000 (ms)");
    if (q.has("step") && !(Number.isInteger(step) && step >= 0 && step <= 1000)) throw new Error("the link: step must be 0..1000 (radio slots)");
    if (q.has("preset") || t || step) {
      if (t || step || q.get("paused") === "1") await run({action: "pause"});
      await run({action: "preset", name: q.get("preset") || st.preset});
    }
    if (q.has("speed")) await run({action: "speed", value: Number(q.get("speed"))});
    if (t) await run({action: "advance", ms: t});
    for (let i = 0; i < step; i++) await run({action: "step_slot"});
    if (q.get("paused") === "1") await run({action: "pause"});
  } catch (e) {
    $("message").textContent = e.message;
  } finally {
    document.body.dataset.pending = --pending;
    document.body.dataset.linked = "1";
  }
}

let linked = false;
const events = new EventSource("/api/events");
events.onmessage = (e) => {
  const st = JSON.parse(e.data);
  draw(st);
  if (!linked) { linked = true; deepLink(st); }
};
events.onerror = () => { $("status").textContent = "disconnected"; };
