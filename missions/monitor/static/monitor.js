// botstage live monitor: the browser side, one ES module per part of the page (no build step).
//
// Data flow: GET /api/info and /api/structure once; then, live, /api/snapshot followed by an
// EventSource on /api/events?since=<snapshot version> whose JSON deltas are applied onto it
// (both again on every reconnect: stream.js), or, in replay, /api/at?tick=N for the scrubbed
// tick (replay.js).
//
// Incoming data goes into the model (model.js, by apply.js) at once and marks what is dirty; the
// DOM is brought up to date at most once per animation frame by draw() below (frame.js
// schedules it), so a burst of deltas costs one repaint. Each part draws its own panel: the
// header, the structure (tree.js), the blackboard, the timeline, logs and display list
// (timeline.js), photos and transcript (people.js), breakpoints (control.js), the map (map.js)
// and the teleop panel (teleop.js).
//
// window.monitor = {version, applied} is published after each frame so tests can wait for it;
// with it `robot` (the last robot object) and `teleop` ({v, w} last sent to /api/teleop).

import { paintBlackboard, wireBlackboard } from "./blackboard.js";
import { renderBreakpoints, wireControls } from "./control.js";
import { onDraw } from "./frame.js";
import { renderStatus, setConn, showMessage } from "./header.js";
import { renderRobot, wireMap } from "./map.js";
import { RETRY_MS, dirty, model, pending } from "./model.js";
import { markLater, renderPhotos, renderSaid, wirePhotos } from "./people.js";
import { startReplay, wireReplay } from "./replay.js";
import { connect } from "./stream.js";
import { isShown, wireTabs } from "./tabs.js";
import { renderTeleop, wireTeleop } from "./teleop.js";
import { markTimelineCursor, renderDisplay, renderEntries, wireTimeline } from "./timeline.js";
import { buildTree, markBreakpointRows, paintTree, wireTree } from "./tree.js";
import { $, getJSON } from "./util.js";

onDraw(draw);

function draw() {
  paintTree();
  paintBlackboard();
  dirty.all = false;
  dirty.statuses.clear();
  dirty.states = false;
  dirty.machines.clear();
  dirty.bb.clear();

  const statusChanged = dirty.status; // the run may have ended: the teleop panel goes
  if (dirty.status) renderStatus();
  dirty.status = false;

  if (dirty.entriesReset || pending.entries.length) {
    renderEntries(pending.entries, dirty.entriesReset);
    pending.entries = [];
    dirty.entriesReset = false;
  }
  if (dirty.displayReset || pending.display.length) {
    renderDisplay(pending.display, dirty.displayReset);
    pending.display = [];
    dirty.displayReset = false;
  }
  if (dirty.saidReset || pending.said.length) {
    renderSaid(pending.said, dirty.saidReset);
    pending.said = [];
    dirty.saidReset = false;
  }
  if (dirty.photosReset || pending.photos.length) {
    renderPhotos(pending.photos, dirty.photosReset);
    pending.photos = [];
    dirty.photosReset = false;
  }
  if (dirty.breakpoints) {
    renderBreakpoints();
    markBreakpointRows();
  }
  dirty.breakpoints = false;

  if (model.replay) {
    markTimelineCursor(model.tick);
    if (isShown("people")) markLater(model.tick);
  }

  if (dirty.robot) renderRobot();
  if (dirty.robot || dirty.teleop || statusChanged) renderTeleop();
  dirty.robot = false;
  dirty.teleop = false;
  window.monitor.robot = model.robot;

  window.monitor.version = model.version;
  window.monitor.applied = model.applied;
  window.monitor.tick = model.tick;
}

async function start() {
  wireTree();
  wireBlackboard();
  wireTimeline();
  wireControls();
  wireReplay();
  wireMap();
  wireTeleop();
  wirePhotos();
  wireTabs();
  renderBreakpoints();

  let info;
  for (;;) {
    try {
      info = await getJSON("api/info");
      break;
    } catch (e) {
      showMessage(`cannot reach the backend: ${e.message}`, "error");
      setConn("down");
      await new Promise((ok) => setTimeout(ok, RETRY_MS));
    }
  }
  model.info = info;
  model.replay = info.mode === "replay";
  window.monitor.mode = info.mode;
  document.body.classList.remove("loading");
  document.body.classList.add(model.replay ? "replay" : "live");
  // a live view without control (the backend says so) hides the controls like a replay does
  if (info.control === false) document.body.classList.add("no-control");
  $("#mode-badge").textContent = model.replay ? "replay" : "live";
  const sub = [info.robot, info.simulated ? "simulated" : info.robot ? "real robot" : ""].filter(Boolean);
  $("#sub-line").textContent = sub.join(" · ");
  document.title = `${info.mission} · botstage monitor`;
  $("#token-box").hidden = !(info.token_required && !model.replay && info.control !== false);
  renderStatus();

  try {
    buildTree(await getJSON("api/structure"));
  } catch (e) {
    showMessage(`cannot load the structure: ${e.message}`, "error");
  }

  if (model.replay) {
    try {
      await startReplay();
    } catch (e) {
      showMessage(`cannot load the replay: ${e.message}`, "error");
    }
  } else {
    await connect();
  }
  window.monitor.ready = true;
}

if (document.readyState === "loading") document.addEventListener("DOMContentLoaded", start);
else start();
