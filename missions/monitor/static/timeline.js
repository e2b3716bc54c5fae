// The timeline (every event, filterable), the logs tab and the display tab's list of layouts
// shown. A timeline row's click shows its node in the tree and, in a replay, goes to its tick.

import { MAX_DISPLAY, MAX_ENTRIES, model } from "./model.js";
import { requestAt } from "./replay.js";
import { atBottom, stickToEnd, trim } from "./scroll.js";
import { noteUnread } from "./tabs.js";
import { revealRow } from "./tree.js";
import { $, el, fmtT, lastSegment } from "./util.js";

function timelineRow(e) {
  const ev = String(e.ev || "");
  const row = el("div", `entry ev-${ev}` + (e.level ? ` level-${String(e.level).toLowerCase()}` : ""));
  row.dataset.tick = e.tick;
  row.dataset.ev = ev;
  if (e.node) {
    row.dataset.node = e.node;
    row.title = e.node;
  }
  row.appendChild(el("span", "tick", e.tick));
  row.appendChild(el("span", "time", fmtT(e.t)));
  row.appendChild(el("span", "ev", ev.replace(/_/g, " ")));
  row.appendChild(el("span", "text", e.text ?? ""));
  row._q = `${ev} ${e.node || ""} ${e.text || ""}`.toLowerCase(); // what the filter searches
  return row;
}

function logRow(e) {
  const level = String(e.level || "info").toLowerCase();
  const row = el("div", `entry ev-log level-${level}`);
  row.dataset.tick = e.tick;
  row.appendChild(el("span", "tick", e.tick));
  row.appendChild(el("span", "ev", level));
  // the node's last segment before the text; its full path on hover
  const text = el("span", "text");
  const node = el("span", "node", e.node ? lastSegment(e.node) || e.node : "");
  node.title = e.node || "";
  text.appendChild(node);
  text.appendChild(document.createTextNode(e.text ?? ""));
  row.appendChild(text);
  return row;
}

function displayRow(d) {
  const row = el("div", "entry");
  row.dataset.tick = d.tick;
  row.appendChild(el("span", "tick", d.tick));
  row.appendChild(el("span", "time", fmtT(d.t)));
  const layout = el("span", "layout", d.layout ?? "—");
  const content = d.content && typeof d.content === "object" ? d.content : {};
  const extra = Object.values(content).filter((v) => v !== "" && v != null).map(String).join(" · ");
  if (extra) layout.appendChild(el("span", "meaning", extra));
  row.appendChild(layout);
  return row;
}

function filterMatches(row) {
  const q = $("#timeline-filter").value.trim().toLowerCase();
  return !q || (row._q || "").includes(q);
}

function applyFilter() {
  const tl = $("#timeline");
  const stick = atBottom(tl);
  for (const row of tl.children) row.hidden = !filterMatches(row);
  if (stick) tl.scrollTop = tl.scrollHeight; // stay with the newest entries
}

export function renderEntries(entries, reset) {
  const tl = $("#timeline");
  const logs = $("#logs");
  const stickTl = reset || tl._follow !== false;
  const stickLogs = reset || logs._follow !== false;
  const q = $("#timeline-filter").value.trim().toLowerCase();
  if (reset) {
    tl.textContent = "";
    logs.textContent = "";
  }
  const tlFrag = document.createDocumentFragment();
  const logFrag = document.createDocumentFragment();
  for (const e of entries) {
    if (!e || typeof e !== "object") continue;
    const row = timelineRow(e);
    if (q && !row._q.includes(q)) row.hidden = true;
    tlFrag.appendChild(row);
    if (e.ev === "log") logFrag.appendChild(logRow(e));
  }
  tl.appendChild(tlFrag);
  if (!reset && logFrag.childElementCount) {
    const alarm = !!logFrag.querySelector(".level-warning, .level-warn, .level-error, .level-critical");
    noteUnread("logs", logFrag.childElementCount, alarm);
  }
  const addedLogs = logFrag.childElementCount;
  logs.appendChild(logFrag);
  trim(tl, MAX_ENTRIES);
  trim(logs, MAX_ENTRIES);
  // auto-scroll only when the reader is already at the bottom (after layout: see stickToEnd)
  if (stickTl) stickToEnd(tl, reset);
  if (stickLogs && (reset || addedLogs)) stickToEnd(logs, reset);
}

export function renderDisplay(items, reset) {
  const box = $("#display-list");
  const stick = reset || box._follow !== false;
  if (reset) box.textContent = "";
  const frag = document.createDocumentFragment();
  for (const d of items) if (d && typeof d === "object") frag.appendChild(displayRow(d));
  if (!reset) noteUnread("display", frag.childElementCount, false);
  box.appendChild(frag);
  trim(box, MAX_DISPLAY);
  if (stick) stickToEnd(box, reset);
}

function onTimelineClick(ev) {
  const row = ev.target.closest(".entry");
  if (!row) return;
  if (model.replay) requestAt(Number(row.dataset.tick));
  if (row.dataset.node) revealRow(row.dataset.node);
}

// Replay: mark the last timeline entry at or before the scrubbed tick.
let cursorRow = null;
export function markTimelineCursor(tick) {
  const rows = $("#timeline").children;
  let lo = 0;
  let hi = rows.length - 1;
  let found = -1;
  while (lo <= hi) {
    const mid = (lo + hi) >> 1;
    if (Number(rows[mid].dataset.tick) <= tick) { found = mid; lo = mid + 1; } else hi = mid - 1;
  }
  if (cursorRow) cursorRow.classList.remove("at-cursor");
  cursorRow = found >= 0 ? rows[found] : null;
  if (cursorRow) {
    cursorRow.classList.add("at-cursor");
    const box = $("#timeline");
    const top = cursorRow.offsetTop - box.offsetTop;
    if (top < box.scrollTop || top > box.scrollTop + box.clientHeight - 20) {
      box.scrollTop = top - box.clientHeight / 2;
    }
  }
}

export function wireTimeline() {
  $("#timeline").addEventListener("click", onTimelineClick);
  $("#timeline").addEventListener("scroll", (ev) => {
    const tl = ev.currentTarget;
    if (tl.clientHeight) tl._follow = atBottom(tl);
  }, { passive: true });
  $("#timeline-filter").addEventListener("input", applyFilter);
}
