// The model: what the page knows, independent of the DOM. Snapshots, deltas and replay ticks
// (apply.js) write it and mark what is dirty; the next frame (frame.js) brings the DOM in line.

export const MAX_ENTRIES = 2000;        // timeline and log rows kept in the DOM
export const MAX_DISPLAY = 2000;        // display-list rows kept in the DOM
export const MAX_SAID = 500;            // transcript lines kept in the DOM (as many as the hub keeps)
export const MAX_PHOTOS = 200;          // photo thumbnails kept in the DOM (as many as the hub keeps)
export const RETRY_MS = 3000;

export const model = {
  info: null,
  replay: false,
  version: null,
  applied: 0,
  tick: 0,
  t: 0,
  paused: false,
  pause_reason: "",
  estopped: false,
  ended: false,
  outcome: "",
  statuses: new Map(),    // node path -> RUNNING/SUCCESS/FAILURE/INVALID
  states: new Map(),      // machine path -> active state path (full)
  blackboard: new Map(),  // key -> {value, type, writer, tick}
  breakpoints: [],
  robot: null,            // the run's robot (live only; see renderRobot)
};

window.monitor = { version: null, applied: 0, ready: false, mode: null, robot: null, teleop: { v: 0, w: 0 } };

// What the next frame has to bring into the DOM.
export const dirty = {
  all: false,              // statuses/states/blackboard replaced wholesale
  statuses: new Set(),
  states: false,
  machines: new Set(),
  bb: new Set(),
  status: false,           // the header
  breakpoints: false,
  entriesReset: false,     // timeline + logs replaced by pending.entries
  displayReset: false,
  saidReset: false,        // transcript replaced by pending.said
  photosReset: false,      // photos replaced by pending.photos
  robot: false,            // the map, data-pose and the teleop panel
  flash: false,            // changed blackboard rows to unmark
  teleop: false,           // the teleop panel only (a key or button held or let go)
};

// Rows that came since the last frame, drawn by it.
export const pending = { entries: [], display: [], said: [], photos: [] };
