// Driving the robot by hand (the Drive panel, shown while the run allows it).
//
// While a direction is held (an arrow key, or an on-screen button pressed) the command goes at
// once and again every TELEOP_REPEAT_MS (the robot stops by itself when commands stop coming);
// when the last one is released, a stop goes at once. Commands go one at a time, the newest
// waiting replaces an older one; a stop also goes straight away beside one in flight, so the last
// command the robot hears is the stop. A refused command is not repeated until the next press.
// The camera's newest frame shows under the pad while the robot sends frames.

import { token } from "./control.js";
import { schedule } from "./frame.js";
import { showMessage } from "./header.js";
import { dirty, model } from "./model.js";
import { $, clamp, detailText, finite } from "./util.js";

const TELEOP_REPEAT_MS = 100;
const TURN_PER_SPEED = 2.5;       // rad/s of turn per m/s of the speed slider
const STOP = Object.freeze({ v: 0, w: 0 });
const KEY_DIRS = { ArrowUp: "forward", ArrowDown: "back", ArrowLeft: "left", ArrowRight: "right" };
const BUTTON_DIRS = { "teleop-forward": "forward", "teleop-back": "back", "teleop-left": "left", "teleop-right": "right" };
const NOT_TEXT = new Set(["range", "button", "checkbox", "radio", "submit", "reset", "color", "file", "image"]);

const tele = {
  keys: new Set(),     // directions held on the keyboard
  pointers: new Map(), // pointerId -> direction held with an on-screen button
  timer: 0,
  inflight: false,
  pending: null,
  refused: false,      // the server refused this press: no resends until the next press
  errorShown: false,   // #message shows a teleop refusal (the next success says it is over)
  sentMoving: false,   // the last command sent was not a stop
};
const camera = { shown: 0, wanted: 0, loading: false };

function teleopAvailable() {
  return !model.replay && !!model.info && model.info.control !== false && !model.ended &&
    !!model.robot && typeof model.robot === "object";
}

function heldDirs() {
  const dirs = new Set(tele.keys);
  for (const d of tele.pointers.values()) dirs.add(d);
  return dirs;
}

function teleopSpeed() {
  const s = Number($("#teleop-speed").value);
  return finite(s) ? clamp(s, 0.05, 1.0) : 0.3;
}

function round3(x) {
  return Math.round(x * 1000) / 1000 || 0; // || 0: no -0
}

function teleopCommand() {
  const d = heldDirs();
  const s = teleopSpeed();
  const ahead = (d.has("forward") ? 1 : 0) - (d.has("back") ? 1 : 0);
  const turn = (d.has("left") ? 1 : 0) - (d.has("right") ? 1 : 0);
  return { v: round3(s * ahead), w: round3(TURN_PER_SPEED * s * turn) };
}

function fmtDrive(v, w) {
  return `driving v=${(Number(v) || 0).toFixed(2)} m/s w=${(Number(w) || 0).toFixed(2)} rad/s`;
}

async function postTeleop(cmd, keepalive) {
  window.monitor.teleop = { v: cmd.v, w: cmd.w };
  tele.sentMoving = cmd.v !== 0 || cmd.w !== 0;
  const headers = { "Content-Type": "application/json" };
  const tok = token();
  if (tok) headers.Authorization = `Bearer ${tok}`;
  const opts = { method: "POST", headers, body: JSON.stringify({ v: cmd.v, w: cmd.w }), keepalive: !!keepalive };
  if (typeof AbortSignal.timeout === "function") opts.signal = AbortSignal.timeout(2000);
  let r;
  let data = null;
  try {
    r = await fetch("api/teleop", opts);
  } catch (e) {
    teleopRefused(cmd, `teleop: cannot reach the backend (${e.message})`);
    return false;
  }
  try { data = await r.json(); } catch (e) { /* no JSON body */ }
  if (r.ok && (!data || data.ok !== false)) {
    if (tele.errorShown) showMessage((data && data.message) || "teleop: ok", "ok");
    tele.errorShown = false;
    return true;
  }
  teleopRefused(cmd, detailText(data) || `teleop: HTTP ${r.status}`);
  return false;
}

function teleopRefused(cmd, text) {
  const moving = cmd.v !== 0 || cmd.w !== 0;
  if (moving) {
    tele.refused = true;
    dirty.teleop = true;
    schedule();
  }
  // a refused stop says nothing new after a refused command
  if (moving || !tele.errorShown) showMessage(text, "error");
  tele.errorShown = true;
}

function queueTeleop(cmd) {
  tele.pending = cmd;
  if (!tele.inflight) pumpTeleop();
}

async function pumpTeleop() {
  tele.inflight = true;
  while (tele.pending) {
    const cmd = tele.pending;
    tele.pending = null;
    await postTeleop(cmd);
  }
  tele.inflight = false;
}

function sendStop() {
  if (tele.inflight) {
    postTeleop(STOP);   // now, beside the one in flight
    tele.pending = STOP; // and once more after it
  } else {
    queueTeleop(STOP);
  }
}

function teleopTick() {
  if (!heldDirs().size) {
    clearInterval(tele.timer);
    tele.timer = 0;
    return;
  }
  const t = teleopStatus();
  if (t && t.allowed === false) tele.refused = true; // e.g. the run went on meanwhile: its reason shows
  if (!tele.refused) queueTeleop(teleopCommand());
}

// What the robot says of teleop now (null: nothing).
function teleopStatus() {
  const t = model.robot && model.robot.teleop;
  return t && typeof t === "object" ? t : null;
}

// The held directions changed (pressed: a new press, worth trying again after a refusal).
// A press while the robot says teleop is not allowed sends nothing: its reason is shown instead.
function heldChanged(pressed) {
  if (heldDirs().size) {
    if (pressed) {
      const t = teleopStatus();
      tele.refused = !!t && t.allowed === false;
      if (tele.refused) {
        showMessage(t.why || "teleop is not allowed now", "error");
        tele.errorShown = true;
      }
    }
    if (!tele.timer) tele.timer = setInterval(teleopTick, TELEOP_REPEAT_MS);
    if (!tele.refused) queueTeleop(teleopCommand());
  } else {
    clearInterval(tele.timer);
    tele.timer = 0;
    // nothing sent that moves (a press refused before it went out): no stop needed
    if (tele.sentMoving || tele.inflight) sendStop();
  }
  dirty.teleop = true;
  schedule();
}

// Let go of everything (the window lost the focus, the page is hidden or goes away).
function releaseAll(keepalive) {
  if (!heldDirs().size) return;
  tele.keys.clear();
  tele.pointers.clear();
  clearInterval(tele.timer);
  tele.timer = 0;
  if ((!tele.sentMoving && !tele.inflight) || model.ended) {
    // nothing to stop (an ended run has stopped its robot itself)
  } else if (keepalive) {
    postTeleop(STOP, true);
  } else {
    sendStop();
  }
  dirty.teleop = true;
  schedule();
}

function isTextField(target) {
  if (!target || !target.closest) return false;
  if (target.isContentEditable) return true;
  const field = target.closest("input, select, textarea");
  if (!field) return false;
  return field.tagName !== "INPUT" || !NOT_TEXT.has(field.type);
}

function onTeleopKey(ev) {
  const dir = KEY_DIRS[ev.key];
  if (!dir) return;
  if (ev.type === "keyup") {
    // always honoured, wherever the focus went meanwhile
    if (tele.keys.delete(dir)) {
      ev.preventDefault();
      heldChanged(false);
    }
    return;
  }
  if (model.replay || $("#teleop").hidden || !teleopAvailable()) return;
  if (ev.altKey || ev.ctrlKey || ev.metaKey || isTextField(ev.target)) return;
  ev.preventDefault(); // no scrolling, no slider nudging while driving
  if (tele.keys.has(dir)) return; // the key's auto-repeat: the timer repeats already
  tele.keys.add(dir);
  heldChanged(true);
}

export function renderTeleop() {
  const panel = $("#teleop");
  const available = teleopAvailable();
  if (panel.hidden === available) panel.hidden = !available;
  document.body.classList.toggle("has-teleop", available);
  if (!available) releaseAll(false);

  const held = heldDirs();
  for (const [id, dir] of Object.entries(BUTTON_DIRS)) $("#" + id).classList.toggle("held", held.has(dir));

  const r = model.robot && typeof model.robot === "object" ? model.robot : null;
  const t = teleopStatus();
  const cmd = teleopCommand();
  let text = "idle";
  let state = "idle";
  if (t && t.allowed === false) {
    text = t.why || "teleop is not allowed now";
    state = "blocked";
  } else if (held.size && !tele.refused && (cmd.v || cmd.w)) {
    text = fmtDrive(cmd.v, cmd.w);
    state = "driving";
  } else if (t && t.active && (t.v || t.w)) {
    text = fmtDrive(t.v, t.w);
    state = "driving";
  }
  const box = $("#teleop-state");
  if (box.textContent !== text) box.textContent = text;
  if (box.dataset.state !== state) box.dataset.state = state;

  renderCamera(r, t);
}

// The newest camera frame, one request at a time (frames that came meanwhile are skipped).
function renderCamera(r, t) {
  const img = $("#camera");
  const n = r && finite(r.camera) ? r.camera : 0;
  if (n <= 0) {
    img.hidden = true;
    camera.wanted = 0;
    camera.shown = 0;
    return;
  }
  img.classList.toggle("stale", !(t && t.active));
  if (n !== camera.shown && n !== camera.wanted) {
    camera.wanted = n;
    if (!camera.loading) loadCamera();
  }
}

function loadCamera() {
  const img = $("#camera");
  const n = camera.wanted;
  camera.loading = true;
  const done = (ok) => {
    camera.loading = false;
    camera.shown = n;
    if (ok && camera.wanted > 0) img.hidden = false;
    if (camera.wanted > 0 && camera.wanted !== n) loadCamera();
  };
  img.onload = () => done(true);
  img.onerror = () => done(false); // keep the frame shown before
  img.src = `api/camera.jpg?n=${n}`;
}

export function wireTeleop() {
  document.addEventListener("keydown", onTeleopKey);
  document.addEventListener("keyup", onTeleopKey);
  window.addEventListener("blur", () => releaseAll(false));
  document.addEventListener("visibilitychange", () => document.hidden && releaseAll(false));
  window.addEventListener("pagehide", () => releaseAll(true));

  for (const [id, dir] of Object.entries(BUTTON_DIRS)) {
    const btn = $("#" + id);
    btn.addEventListener("pointerdown", (ev) => {
      if (ev.button !== 0 || !teleopAvailable()) return;
      ev.preventDefault();
      try { btn.setPointerCapture(ev.pointerId); } catch (e) { /* the pointer is gone already */ }
      tele.pointers.set(ev.pointerId, dir);
      heldChanged(true);
    });
    const up = (ev) => {
      if (tele.pointers.get(ev.pointerId) !== dir) return;
      tele.pointers.delete(ev.pointerId);
      heldChanged(false);
    };
    btn.addEventListener("pointerup", up);
    btn.addEventListener("pointercancel", up);
    btn.addEventListener("lostpointercapture", up);
    btn.addEventListener("contextmenu", (ev) => ev.preventDefault()); // a long touch is a hold
  }
  $("#teleop-stop").addEventListener("click", () => {
    tele.keys.clear();
    tele.pointers.clear();
    clearInterval(tele.timer);
    tele.timer = 0;
    tele.refused = false;
    sendStop();
    dirty.teleop = true;
    schedule();
  });

  const speed = $("#teleop-speed");
  const showSpeed = () => { $("#teleop-speed-value").textContent = `${teleopSpeed().toFixed(2)} m/s`; };
  showSpeed();
  speed.addEventListener("input", () => {
    showSpeed();
    if (heldDirs().size && !tele.refused) queueTeleop(teleopCommand());
    dirty.teleop = true;
    schedule();
  });
}
