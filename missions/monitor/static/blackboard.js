// The blackboard: one row per key in alphabetical order, a changed row marked a while; a click
// opens the key's history (/api/history, followed while live) and fills the write form.

import { schedule } from "./frame.js";
import { dirty, model } from "./model.js";
import { $, el, fmtT, getJSON, toJSON, truncate } from "./util.js";

const VALUE_CHARS = 120;         // blackboard values longer than this are cut (full in title)

const bbRows = new Map();       // key -> <tr>
let selectedKey = null;

function makeBbRow(key) {
  const tr = el("tr");
  tr.dataset.key = key;
  for (let i = 0; i < 5; i++) tr.appendChild(el("td"));
  tr.cells[0].textContent = key;
  tr.cells[0].title = key;
  return tr;
}

// Returns whether anything changed.
function fillBbRow(tr, entry) {
  const json = toJSON(entry.value);
  const sig = `${entry.tick}|${entry.type}|${entry.writer}|${json}`;
  if (tr._sig === sig) return false;
  tr._sig = sig;
  const c = tr.cells;
  c[1].textContent = truncate(json, VALUE_CHARS);
  c[1].title = json;
  c[2].textContent = entry.type ?? "";
  c[3].textContent = entry.writer ?? "";
  c[3].title = entry.writer ?? "";
  c[4].textContent = entry.tick ?? "";
  return true;
}

function insertSorted(tbody, tr, key) {
  // keys stay in alphabetical order; a new key goes in its place
  for (const other of tbody.rows) {
    if (other.dataset.key.localeCompare(key) > 0) {
      tbody.insertBefore(tr, other);
      return;
    }
  }
  tbody.appendChild(tr);
}

// A changed row is marked for FLASH_MS, unmarked by a later frame: a static highlight is
// painted only in the frames the page draws anyway. (A fading animation repainted the table
// every frame while a fast run changed keys at every push: a third of the browser's CPU.)
const FLASH_MS = 1000;
const flashed = new Map(); // <tr> -> when it was marked (performance.now())
let unflashTimer = 0;
function flashRow(tr) {
  tr.classList.add("flash");
  flashed.set(tr, performance.now());
}

function unflashRows() {
  if (!flashed.size) return;
  const now = performance.now();
  let next = Infinity;
  for (const [tr, at] of flashed) {
    if (now - at >= FLASH_MS) {
      tr.classList.remove("flash");
      flashed.delete(tr);
    } else {
      next = Math.min(next, at + FLASH_MS - now);
    }
  }
  clearTimeout(unflashTimer);
  if (flashed.size) unflashTimer = setTimeout(() => { dirty.flash = true; schedule(); }, next + 5);
}

function renderBlackboardAll() {
  const tbody = $("#blackboard tbody");
  tbody.textContent = "";
  bbRows.clear();
  const keys = [...model.blackboard.keys()].sort((a, b) => a.localeCompare(b));
  const frag = document.createDocumentFragment();
  for (const key of keys) {
    const tr = makeBbRow(key);
    fillBbRow(tr, model.blackboard.get(key));
    if (key === selectedKey) tr.classList.add("selected");
    bbRows.set(key, tr);
    frag.appendChild(tr);
  }
  tbody.appendChild(frag);
  refreshKeyList();
}

function renderBlackboardKeys(keys) {
  const tbody = $("#blackboard tbody");
  let added = false;
  for (const key of keys) {
    const entry = model.blackboard.get(key);
    let tr = bbRows.get(key);
    if (!entry) {
      if (tr) { tr.remove(); bbRows.delete(key); }
      continue;
    }
    if (!tr) {
      tr = makeBbRow(key);
      bbRows.set(key, tr);
      insertSorted(tbody, tr, key);
      added = true;
    }
    if (fillBbRow(tr, entry) && !model.replay) flashRow(tr);
  }
  if (added) refreshKeyList();
}

function refreshKeyList() {
  const list = $("#keys");
  list.textContent = "";
  for (const key of bbRows.keys()) {
    const o = el("option");
    o.value = key;
    list.appendChild(o);
  }
  $("#bb-count").textContent = `${bbRows.size} keys`;
}

let historyTimer = null;
let historyLast = 0;

async function loadHistory(key) {
  historyLast = Date.now();
  const box = $("#history-box");
  const hist = $("#history");
  box.hidden = false;
  $("#history-title").textContent = `history of ${key}`;
  let items;
  try {
    items = await getJSON(`api/history?key=${encodeURIComponent(key)}`);
  } catch (e) {
    hist.textContent = "";
    hist.appendChild(el("div", "empty", e.detail || e.message));
    return;
  }
  if (key !== selectedKey) return; // another key was clicked meanwhile
  const stick = hist.scrollHeight - hist.scrollTop - hist.clientHeight < 20;
  hist.textContent = "";
  if (!Array.isArray(items) || !items.length) {
    hist.appendChild(el("div", "empty", "no writes recorded"));
    return;
  }
  const table = el("table", "grid-table");
  const head = el("tr");
  for (const h of ["tick", "t", "value", "writer"]) head.appendChild(el("th", "", h));
  const thead = el("thead");
  thead.appendChild(head);
  table.appendChild(thead);
  const tbody = el("tbody");
  for (const it of items) {
    const tr = el("tr");
    tr.dataset.tick = it.tick;
    const json = toJSON(it.value);
    tr.appendChild(el("td", "", it.tick));
    tr.appendChild(el("td", "", fmtT(it.t)));
    const v = el("td", "", truncate(json, VALUE_CHARS));
    v.title = json;
    tr.appendChild(v);
    tr.appendChild(el("td", "", it.writer ?? ""));
    tbody.appendChild(tr);
  }
  table.appendChild(tbody);
  table.querySelectorAll("th")[0].style.width = "15%";
  table.querySelectorAll("th")[1].style.width = "12%";
  table.querySelectorAll("th")[3].style.width = "25%";
  hist.appendChild(table);
  $("#history-title").textContent = `history of ${key} (${items.length})`;
  if (stick || hist.dataset.key !== key) hist.scrollTop = hist.scrollHeight; // latest last
  hist.dataset.key = key;
}

// Live: the open history follows its key, at most once a second.
function historyChanged() {
  if (historyTimer) return;
  const wait = Math.max(0, 1000 - (Date.now() - historyLast));
  historyTimer = setTimeout(() => {
    historyTimer = null;
    if (selectedKey) loadHistory(selectedKey);
  }, wait);
}

function onBlackboardClick(ev) {
  const tr = ev.target.closest("tbody tr");
  if (!tr) return;
  const key = tr.dataset.key;
  for (const r of bbRows.values()) r.classList.remove("selected");
  tr.classList.add("selected");
  selectedKey = key;
  // prefill the write form with the key and its current value
  const entry = model.blackboard.get(key);
  $("#write-key").value = key;
  if (entry) $("#write-value").value = toJSON(entry.value);
  loadHistory(key);
}

// Bring the table in line with what the model marked dirty; the open history follows its key.
export function paintBlackboard() {
  if (dirty.all) {
    renderBlackboardAll();
    if (selectedKey && !model.replay && model.blackboard.has(selectedKey)) historyChanged();
  } else if (dirty.bb.size) {
    renderBlackboardKeys(dirty.bb);
    if (selectedKey && dirty.bb.has(selectedKey)) historyChanged();
  }
  dirty.flash = false;
  unflashRows();
}

export function wireBlackboard() {
  $("#blackboard").addEventListener("click", onBlackboardClick);
  $("#history-close").addEventListener("click", () => {
    $("#history-box").hidden = true;
    selectedKey = null;
    for (const r of bbRows.values()) r.classList.remove("selected");
  });
}
