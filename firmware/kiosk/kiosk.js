// The kiosk page: renders the daemon's status (Server-Sent Events from /api/events) and sends
// the page's buttons to the API. Everything the screen shows comes from the status JSON.
"use strict";
const $ = (id) => document.getElementById(id);
let current = null;
let guideIndex = -1;

async function post(path, body) {
  const r = await fetch(path, {method: "POST", headers: {"Content-Type": "application/json"},
                               body: JSON.stringify(body || {})});
  if (!r.ok) console.warn(path, r.status, await r.text());
  return r.ok;
}

function renderProgress(s) {
  const p = $("progress");
  if (p.childElementCount !== s.capture_count) {
    p.innerHTML = "";
    for (let i = 0; i < s.capture_count; i++) p.appendChild(document.createElement("span"));
  }
  [...p.children].forEach((el, i) => {
    el.className = i < s.done_count ? "done" : (i === s.capture_index ? "current" : "");
  });
  p.dataset.done = s.done_count;
}

function render(s) {
  current = s;
  document.body.dataset.state = s.state;
  $("state").textContent = s.state;
  $("led").className = "led " + s.led;
  $("message").textContent = s.message || "";
  $("expression").textContent = s.expression ? s.expression.label : "";
  if (s.expression && s.capture_index !== guideIndex) {
    guideIndex = s.capture_index;
    $("guide-img").src = "/api/guide/" + s.capture_index + ".bmp";
  }
  if (!s.expression) { guideIndex = -1; $("guide-img").removeAttribute("src"); }
  renderProgress(s);
  $("take-bar").style.width =
      (s.state === "recording" ? 100 * s.take_frames / Math.max(1, s.take_length) : 0) + "%";
  const qa = $("qa");
  if (s.qa) {
    qa.hidden = false;
    qa.className = s.qa.passed ? "pass" : "fail";
    qa.textContent = (s.qa.passed ? "QA passed" : "QA failed: " + s.qa.reason) +
        ` (coverage ${s.qa.coverage.toFixed(2)}, residual ${s.qa.residual_mm.toFixed(2)} mm,` +
        ` landmarks ${s.qa.landmarks}, fit ${s.qa.fit})`;
    if (s.qa.fit_rms_mm) qa.textContent += ` fit RMS ${s.qa.fit_rms_mm.toFixed(2)} mm,` +
        ` landmark error ${s.qa.landmark_error_mm.toFixed(1)} mm`;
    renderQaCapture(s.qa.capture);
  } else {
    qa.hidden = true;
    renderQaCapture(null);
  }
  renderTracking(s);
  renderRegistration(s);
  const inSession = ["enrolled", "guide", "recording", "processing", "retry"].includes(s.state);
  $("start").disabled = !(s.state === "idle" || s.state === "complete");
  $("next").disabled = s.state !== "guide";
  $("retry").disabled = s.state !== "retry";
  $("cancel").disabled = !inSession;
  $("mode").textContent = s.state === "tracking" ? "Capture mode" : "Tracking mode";
  $("mode").disabled = inSession;
}

// QA screen: the capture's colour frame (640x480 shown at half size) with its 68 landmarks;
// dragging one posts a correction, the daemon refits and the status brings the new QA.
// The outcome of the last correction is kept in #qa-view's data-correction for the operator
// (and the browser test): "posting", "refitting" or "rejected: <why>".
let qaKey = "";
let dragging = null;
const SVG = "http://www.w3.org/2000/svg";
function renderQaCapture(c) {
  const view = $("qa-view");
  if (!c || !c.points || c.points.length !== 68) { view.hidden = true; qaKey = ""; return; }
  view.hidden = false;
  const key = `${c.session}/${c.index}/${c.revision}`;
  if (key === qaKey || dragging) return;
  qaKey = key;
  view.dataset.key = key;
  $("qa-img").src = c.image;
  const svg = $("qa-points");
  svg.setAttribute("viewBox", "0 0 640 480");
  svg.dataset.session = c.session;
  svg.dataset.capture = c.index;
  svg.innerHTML = "";
  c.points.forEach(([u, v], i) => {
    const dot = document.createElementNS(SVG, "circle");
    dot.setAttribute("cx", u); dot.setAttribute("cy", v); dot.setAttribute("r", 4);
    dot.dataset.index = i;
    if (c.corrected[i]) dot.classList.add("corrected");
    svg.appendChild(dot);
  });
}
function svgPoint(e) {
  const r = $("qa-points").getBoundingClientRect();
  return [(e.clientX - r.left) * 640 / r.width, (e.clientY - r.top) * 480 / r.height];
}
// Delegated on the svg, and move/up on window: a redraw of the points or a pointer leaving the
// picture mid-drag must not lose the drag.
$("qa-points").addEventListener("pointerdown", (e) => {
  const dot = e.target.closest("circle");
  if (!dot) return;
  e.preventDefault();
  const svg = $("qa-points");
  dragging = {dot, session: svg.dataset.session, capture: svg.dataset.capture};
});
window.addEventListener("pointermove", (e) => {
  if (!dragging) return;
  const [u, v] = svgPoint(e);
  dragging.dot.setAttribute("cx", u);
  dragging.dot.setAttribute("cy", v);
});
window.addEventListener("pointerup", async (e) => {
  if (!dragging) return;
  const d = dragging;
  const [u, v] = svgPoint(e);
  d.dot.classList.add("corrected");
  const view = $("qa-view");
  view.dataset.correction = "posting";
  const r = await fetch(`/api/sessions/${d.session}/captures/${d.capture}/landmarks`, {
    method: "POST", headers: {"Content-Type": "application/json"},
    body: JSON.stringify({corrections: [{index: Number(d.dot.dataset.index), u, v}]})});
  view.dataset.correction = r.ok ? "refitting" : "rejected: " + (await r.text());
  dragging = null;
  qaKey = "";  // redraw from the next status
});

// Registration health: a camera whose depth and colour are misregistered distorts every fit,
// so the daemon refuses sessions; the banner says so plainly, with the way out (self-calibrate).
function renderRegistration(s) {
  const r = s.registration || {};
  const box = $("calibration");
  const needs = r.needs_calibration === true;
  box.hidden = !(needs || r.calibrating);
  box.classList.toggle("busy", !!r.calibrating);
  box.dataset.state = r.state || "";
  if (typeof r.misregistration_px === "number") box.dataset.px = r.misregistration_px.toFixed(1);
  $("calibration-message").textContent = r.calibrating ? (s.message || "Calibrating...") :
                                                         (r.message || "");
  const busy = ["enrolled", "recording", "processing", "tracking"].includes(s.state);
  $("calibrate").disabled = !!r.calibrating || busy;
}
$("calibrate").onclick = async () => {
  $("calibrate").disabled = true;
  $("calibration-result").textContent = "calibrating...";
  const r = await fetch("/api/camera/self-calibrate", {method: "POST",
      headers: {"Content-Type": "application/json"}, body: "{}"});
  let text = "";
  try { const j = await r.json(); text = j.message || j.error || ""; } catch { text = r.statusText; }
  $("calibration-result").textContent = text;
};

// Tracking view: live weights from /api/tracking/events while in tracking mode.
let live = null;
function renderTracking(s) {
  const on = s.state === "tracking";
  $("tracking").hidden = !on;
  if (on) {
    const t = s.tracking || {};
    const hidden = typeof t.hidden_fraction === "number" ? Math.round(100 * t.hidden_fraction) : 0;
    const occlusion = t.occluded ? `, face occluded (${hidden} % hidden)` : "";
    const occludedFrames = t.occluded_frames ? `, occluded on ${t.occluded_frames} frames` : "";
    $("tracking-info").textContent = `tracker: ${t.state || "starting"}` +
        `${t.reason ? " (" + t.reason + ")" : ""}${occlusion}${occludedFrames}, identity: ` +
        `${t.identity || "-"}, VMC: ${t.vmc_target || "off"} (${t.vmc_datagrams || 0} datagrams)`;
  }
  if (on && !live) {
    live = new EventSource("/api/tracking/events");
    live.addEventListener("face", (e) => renderWeights(JSON.parse(e.data)));
  } else if (!on && live) {
    live.close();
    live = null;
  }
}
function renderWeights(f) {
  const box = $("weights");
  const top = Object.entries(f.weights).sort((a, b) => b[1] - a[1]).slice(0, 12);
  box.innerHTML = "";
  box.dataset.frame = f.frame;
  box.dataset.face = f.face;
  for (const [name, w] of top) {
    const label = document.createElement("span");
    label.textContent = name;
    const bar = document.createElement("div");
    bar.className = "bar";
    bar.style.width = (100 * w).toFixed(0) + "%";
    box.append(label, bar);
  }
}

function connect() {
  const es = new EventSource("/api/events");
  es.addEventListener("status", (e) => render(JSON.parse(e.data)));
  es.onerror = () => { $("state").textContent = "reconnecting"; };
}

setInterval(() => { $("preview").src = "/api/preview.bmp?t=" + Date.now(); }, 500);
$("preview").onerror = () => { $("preview").removeAttribute("src"); };
$("start").onclick = () => post("/api/session/start", {subject: $("subject").value});
$("next").onclick = () => post("/api/session/next");
$("retry").onclick = () => post("/api/session/retry");
$("cancel").onclick = () => post("/api/session/cancel");
$("mode").onclick = () =>
    post("/api/mode", {mode: current && current.state === "tracking" ? "capture" : "tracking"});
$("sim-main").onclick = () => post("/api/sim/button", {button: "main"});
$("sim-main-long").onclick = () => post("/api/sim/button", {button: "main", kind: "long"});
$("sim-mode").onclick = () => post("/api/sim/button", {button: "mode"});
fetch("/api/status").then((r) => r.json()).then(render);
connect();
