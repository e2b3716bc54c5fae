// Batching: one DOM update per animation frame. Whatever changes the model calls schedule();
// the page's draw function (monitor.js registers it with onDraw) runs at most once per frame,
// so a burst of deltas costs one repaint.

import { model } from "./model.js";

let draw = () => {};
let scheduled = false;
let rafId = 0;
let timerId = 0;

let hiddenDirty = false;   // the model changed while the tab was hidden

// A run much faster than real time (a simulation at full speed changes everything at every
// push) is drawn at most every FAST_FRAME_MS: nobody reads 75 ticks a second, and each frame
// costs the browser CPU the run itself needs on a small machine. Nothing is dropped: the model
// keeps every delta and the next frame draws all of it. At real time every push is drawn.
const FAST_FRAME_MS = 500;
const FAST_SPEED = 2;      // mission seconds per wall second above which a run counts as fast
let lastFlushAt = 0;       // performance.now() of the last flush
let lastFlushT = 0;        // the run's time then
let fastRun = false;

export function onDraw(fn) {
  draw = fn;
}

export function schedule() {
  if (scheduled) return;
  if (document.hidden) {
    // a hidden tab draws nothing: the model keeps up (pending lists are capped, so memory
    // stays flat) and one flush brings the DOM up to date when the tab is shown again
    hiddenDirty = true;
    return;
  }
  scheduled = true;
  const wait = fastRun && !model.paused && !model.ended ? lastFlushAt + FAST_FRAME_MS - performance.now() : 0;
  if (wait > 0) timerId = setTimeout(frame, wait);
  else frame();
}

function frame() {
  rafId = requestAnimationFrame(flush);
  // a fallback should rAF stall while the tab still counts as visible
  clearTimeout(timerId);
  timerId = setTimeout(flush, 250);
}

function measureSpeed() {
  const now = performance.now();
  if (lastFlushAt && now > lastFlushAt) fastRun = (model.t - lastFlushT) / ((now - lastFlushAt) / 1000) > FAST_SPEED;
  lastFlushAt = now;
  lastFlushT = model.t;
}

document.addEventListener("visibilitychange", () => {
  if (!document.hidden && hiddenDirty) {
    hiddenDirty = false;
    schedule();
  }
});

function flush() {
  cancelAnimationFrame(rafId);
  clearTimeout(timerId);
  scheduled = false;
  if (document.hidden) {
    hiddenDirty = true;
    return;
  }
  measureSpeed();
  draw();
}
