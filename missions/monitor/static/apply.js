// Applying what the server sends onto the model: a snapshot (/api/snapshot), a delta (a server-
// sent event) or, in a replay, the whole picture at one tick (/api/at); each marks what changed
// and schedules a frame.

import { schedule } from "./frame.js";
import { MAX_DISPLAY, MAX_ENTRIES, MAX_PHOTOS, MAX_SAID, dirty, model, pending } from "./model.js";
import { $ } from "./util.js";

function setScalars(d) {
  for (const k of ["tick", "t", "paused", "pause_reason", "estopped", "ended", "outcome"]) {
    if (d[k] !== undefined && d[k] !== null) model[k] = d[k];
  }
  dirty.status = true;
}

function replaceMaps(d) {
  model.statuses = new Map(Object.entries(d.statuses || {}));
  model.states = new Map(Object.entries(d.states || {}).filter(([, v]) => v));
  model.blackboard = new Map(Object.entries(d.blackboard || {}).filter(([, v]) => v));
  dirty.all = true;
}

export function applySnapshot(s) {
  setScalars(s);
  replaceMaps(s);
  model.version = s.version ?? model.version;
  model.breakpoints = Array.isArray(s.breakpoints) ? s.breakpoints : [];
  dirty.breakpoints = true;
  pending.entries = Array.isArray(s.timeline) ? s.timeline.slice(-MAX_ENTRIES) : [];
  dirty.entriesReset = true;
  pending.display = Array.isArray(s.display) ? s.display.slice(-MAX_DISPLAY) : [];
  dirty.displayReset = true;
  pending.said = Array.isArray(s.said) ? s.said.slice(-MAX_SAID) : [];
  dirty.saidReset = true;
  pending.photos = Array.isArray(s.photos) ? s.photos.slice(-MAX_PHOTOS) : [];
  dirty.photosReset = true;
  if (!model.replay) setRobot(s.robot);
  schedule();
}

// The robot object comes whole (null: the run has none). A replay's comes with each scrubbed
// tick (/api/at: the poses the run recorded), not with the snapshot.
function setRobot(robot) {
  model.robot = robot && typeof robot === "object" ? robot : null;
  dirty.robot = true;
}

export function applyDelta(d) {
  setScalars(d);
  if (d.statuses) {
    for (const [path, st] of Object.entries(d.statuses)) {
      if (model.statuses.get(path) === st) continue;
      model.statuses.set(path, st);
      dirty.statuses.add(path);
    }
  }
  if (d.states) {
    for (const [machine, state] of Object.entries(d.states)) {
      if ((model.states.get(machine) || null) === (state || null)) continue; // no change
      if (state) model.states.set(machine, state);
      else model.states.delete(machine); // a machine that stopped
      dirty.machines.add(machine);
      dirty.states = true;
    }
  }
  if (d.blackboard) {
    for (const [key, entry] of Object.entries(d.blackboard)) {
      if (entry) model.blackboard.set(key, entry);
      else model.blackboard.delete(key);
      dirty.bb.add(key);
    }
  }
  if (Array.isArray(d.timeline) && d.timeline.length) {
    pending.entries.push(...d.timeline);
    if (pending.entries.length > MAX_ENTRIES) pending.entries = pending.entries.slice(-MAX_ENTRIES);
  }
  if (Array.isArray(d.display) && d.display.length) {
    pending.display.push(...d.display);
    if (pending.display.length > MAX_DISPLAY) pending.display = pending.display.slice(-MAX_DISPLAY);
  }
  if (Array.isArray(d.said) && d.said.length) {
    pending.said.push(...d.said);
    if (pending.said.length > MAX_SAID) pending.said = pending.said.slice(-MAX_SAID);
  }
  if (Array.isArray(d.photos) && d.photos.length) {
    pending.photos.push(...d.photos);
    if (pending.photos.length > MAX_PHOTOS) pending.photos = pending.photos.slice(-MAX_PHOTOS);
  }
  if (Array.isArray(d.breakpoints)) {
    model.breakpoints = d.breakpoints;
    dirty.breakpoints = true;
  }
  if (d.robot !== undefined) setRobot(d.robot);
  if (typeof d.version === "number") model.version = d.version;
  model.applied++;
  schedule();
}

// Replay: /api/at gives the whole picture at one tick.
export function applyAt(a) {
  if (a.tick !== undefined) model.tick = a.tick;
  if (a.t !== undefined) model.t = a.t;
  dirty.status = true;
  replaceMaps(a);
  setRobot(a.robot);
  const pre = $("#tree-text");
  if (pre.textContent !== (a.text ?? "")) pre.textContent = a.text ?? "";
  model.applied++;
  schedule();
}
