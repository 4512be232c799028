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
  } else {
    qa.hidden = true;
  }
  const inSession = ["enrolled", "guide", "recording", "processing", "retry"].includes(s.state);
  $("start").disabled = !(s.state === "idle" || s.state === "complete");
  $("next").disabled = s.state !== "guide";
  $("retry").disabled = s.state !== "retry";
  $("cancel").disabled = !inSession;
  $("mode").textContent = s.state === "tracking" ? "Capture mode" : "Tracking mode";
  $("mode").disabled = inSession;
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
