// The structure: the run's machines and trees, built once from /api/structure; a frame only
// touches the attributes and classes of the rows whose status changed (looked up in a Map
// path -> row elements). A row's click selects it and fills the operator's forms with it.

import { control } from "./control.js";
import { dirty, model } from "./model.js";
import { $, el, lastSegment, prefixes } from "./util.js";

const STATUS_CLASSES = ["running", "success", "failure", "invalid"];
const KIND_LABEL = {
  group: "group", machine: "machine", state: "state", outcome: "outcome", skill: "skill",
  condition: "cond", sequence: "seq", selector: "sel", parallel: "par", decorator: "deco",
};

const rowsByPath = new Map();   // path -> [row elements] (a nested machine may share its state's path)
const machineRows = new Map();  // machine path -> [row] (to show its current state)
const machineParent = new Map(); // machine path -> the state it runs in (null: top level)
let activeSet = new Set();      // active state paths and all their ancestors
let leafSet = new Set();        // innermost active states
let bpMarked = [];              // rows marked as having a breakpoint
let selectedRow = null;

export function buildTree(structure) {
  const tree = $("#tree");
  tree.textContent = "";
  const items = Array.isArray(structure) ? structure : structure ? [structure] : [];
  const ul = el("ul");
  const frag = document.createDocumentFragment();
  for (const item of items) frag.appendChild(buildItem(item, null, null));
  ul.appendChild(frag);
  tree.appendChild(ul);

  // node paths for the breakpoint / force inputs
  const list = $("#paths");
  list.textContent = "";
  const opts = document.createDocumentFragment();
  for (const path of rowsByPath.keys()) {
    const o = el("option");
    o.value = path;
    opts.appendChild(o);
  }
  list.appendChild(opts);
  if (!items.length) tree.appendChild(el("div", "list-empty", "no structure"));
}

// machine: the machine item this item is in; state: the path of the state it runs in.
function buildItem(item, machine, state) {
  const li = el("li");
  const row = el("div", "row");
  const path = String(item.path || "");
  const kind = String(item.kind || "");
  const children = Array.isArray(item.children) ? item.children : [];
  row.dataset.path = path;
  row.dataset.kind = kind;
  row.dataset.status = kind === "state" ? "" : "INVALID";
  if (kind !== "state") row.classList.add("invalid");
  row.title = path;

  const twisty = el("button", "twisty" + (children.length ? "" : " leaf"), "▼");
  twisty.type = "button";
  twisty.tabIndex = -1;
  row.appendChild(twisty);
  row.appendChild(el("span", "status-dot"));
  row.appendChild(el("span", "kind", KIND_LABEL[kind] || kind));
  if (kind === "state" && machine && machine.initial &&
      (machine.initial === path || machine.initial === lastSegment(path))) {
    const mark = el("span", "initial-mark", "●");
    mark.title = "initial state";
    row.appendChild(mark);
  }
  row.appendChild(el("span", "title", item.title || lastSegment(path) || path));
  if (Array.isArray(item.details) && item.details.length) {
    row.appendChild(el("span", "details", item.details.join(" · ")));
  }
  if (kind === "machine") {
    row.appendChild(el("span", "current"));
    addIndex(machineRows, path, row);
    if (!machineParent.has(path)) machineParent.set(path, state);
  }
  if (kind !== "group" && kind !== "outcome") {
    const bp = el("button", "bp-btn", "⏸");
    bp.type = "button";
    bp.setAttribute("aria-label", "add a breakpoint");
    bp.title = `break on this ${kind === "state" ? "state" : "node"}`;
    row.appendChild(bp);
  }
  if (kind === "state" && Array.isArray(item.transitions) && item.transitions.length) {
    // compact: outcome → target's last segment, one chip each
    row.classList.add("has-trans"); // a taller row: its placeholder size (CSS)
    const tr = el("div", "trans");
    for (const t of item.transitions) {
      const chip = el("span", "t");
      chip.appendChild(document.createTextNode(`${t.outcome}`));
      if (t.if) {
        chip.appendChild(document.createTextNode(" "));
        chip.appendChild(el("span", "cond", `[${t.if}]`));
      }
      chip.appendChild(document.createTextNode(` → ${lastSegment(t.to)}`));
      chip.title = `${t.outcome}${t.if ? " if " + t.if : ""} → ${t.to}`;
      tr.appendChild(chip);
    }
    row.appendChild(tr);
  }

  addIndex(rowsByPath, path, row);
  li.appendChild(row);

  if (children.length) {
    const ul = el("ul");
    const nextMachine = kind === "machine" ? item : machine;
    const nextState = kind === "state" ? path : state;
    for (const child of children) ul.appendChild(buildItem(child, nextMachine, nextState));
    li.appendChild(ul);
  }
  return li;
}

function addIndex(map, key, value) {
  const list = map.get(key);
  if (list) list.push(value);
  else map.set(key, [value]);
}

// Bring one row's data-status and classes in line with the model.
function paintRow(row) {
  const path = row.dataset.path;
  const kind = row.dataset.kind;
  const active = activeSet.has(path);
  if (kind === "state") {
    const st = active ? "ACTIVE" : "";
    if (row.dataset.status !== st) row.dataset.status = st;
    row.classList.toggle("active", active);
    row.classList.toggle("active-leaf", leafSet.has(path));
    return;
  }
  const st = model.statuses.get(path) || "INVALID";
  if (row.dataset.status !== st) {
    row.dataset.status = st;
    const cls = st.toLowerCase();
    for (const c of STATUS_CLASSES) row.classList.toggle(c, c === cls);
  }
  // machines on the active path are highlighted too
  if (kind === "machine") row.classList.toggle("active", active);
}

function paintPath(path) {
  const rows = rowsByPath.get(path);
  if (rows) for (const r of rows) paintRow(r);
}

// A machine's state counts only while the state the machine runs in is active itself: a
// nested machine that was left keeps its last state in `states`, and that is not current.
// Machines the structure does not show are taken at their word.
function computeActive() {
  const set = new Set();
  const values = [];
  let pending = [...model.states.entries()].filter(([, v]) => v);
  for (let progress = true; progress && pending.length;) {
    progress = false;
    pending = pending.filter(([machine, state]) => {
      const parent = machineParent.get(machine);
      if (parent && !set.has(parent)) return true; // not (yet) known to be on the active path
      for (const p of prefixes(state)) set.add(p);
      values.push(String(state));
      progress = true;
      return false;
    });
  }
  // the innermost active states: no other active state lies below them
  const leaves = new Set(values.filter((v) => !values.some((w) => w.startsWith(v + "/"))));
  return [set, leaves];
}

function refreshActive() {
  const [set, leaves] = computeActive();
  const changed = new Set();
  for (const p of activeSet) if (!set.has(p)) changed.add(p);
  for (const p of set) if (!activeSet.has(p)) changed.add(p);
  for (const p of leafSet) if (!leaves.has(p)) changed.add(p);
  for (const p of leaves) if (!leafSet.has(p)) changed.add(p);
  activeSet = set;
  leafSet = leaves;
  for (const p of changed) paintPath(p);
}

function paintMachineCurrent(machinePath) {
  const rows = machineRows.get(machinePath);
  if (!rows) return;
  const state = model.states.get(machinePath);
  for (const r of rows) {
    const span = r.querySelector(".current");
    const text = state ? "→ " + lastSegment(state) : "";
    if (span && span.textContent !== text) span.textContent = text;
  }
}

export function markBreakpointRows() {
  for (const r of bpMarked) r.classList.remove("has-bp");
  bpMarked = [];
  for (const bp of model.breakpoints) {
    if (bp.kind !== "state" && bp.kind !== "node") continue;
    const rows = rowsByPath.get(bp.target);
    if (!rows) continue;
    for (const r of rows) {
      r.classList.add("has-bp");
      bpMarked.push(r);
    }
  }
}

export function revealRow(path) {
  const rows = rowsByPath.get(path);
  if (!rows) return false;
  const row = rows[0];
  for (let li = row.parentElement; li && li.id !== "tree"; li = li.parentElement) {
    if (li.tagName === "LI") li.classList.remove("collapsed");
  }
  row.scrollIntoView({ block: "center", behavior: "smooth" });
  row.classList.remove("flash");
  void row.offsetWidth; // restart the animation
  row.classList.add("flash");
  return true;
}

function selectRow(row) {
  if (selectedRow) selectedRow.classList.remove("selected");
  selectedRow = row;
  row.classList.add("selected");
  // prefill the operator forms with the node clicked
  const path = row.dataset.path;
  const kind = row.dataset.kind;
  if (kind === "group" || kind === "outcome") return;
  $("#break-kind").value = kind === "state" ? "state" : "node";
  $("#break-target").value = path;
  if (kind !== "state") $("#force-node").value = path;
}

function onTreeClick(ev) {
  const row = ev.target.closest(".row");
  if (!row) return;
  if (ev.target.closest(".twisty")) {
    row.parentElement.classList.toggle("collapsed");
    return;
  }
  if (ev.target.closest(".bp-btn")) {
    ev.stopPropagation();
    const kind = row.dataset.kind === "state" ? "state" : "node";
    control({ action: "break", kind, target: row.dataset.path });
    return;
  }
  selectRow(row);
}

function setAllCollapsed(collapsed) {
  for (const li of $("#tree").querySelectorAll("li")) {
    if (li.querySelector(":scope > ul")) li.classList.toggle("collapsed", collapsed);
  }
  // keep the top level open so something remains visible
  if (collapsed) for (const li of $("#tree").querySelectorAll(":scope > ul > li")) li.classList.remove("collapsed");
}

// Bring the rows in line with what the model marked dirty (all of them after a snapshot).
export function paintTree() {
  if (dirty.all) {
    const [set, leaves] = computeActive();
    activeSet = set;
    leafSet = leaves;
    for (const rows of rowsByPath.values()) for (const r of rows) paintRow(r);
    for (const m of machineRows.keys()) paintMachineCurrent(m);
    return;
  }
  for (const path of dirty.statuses) paintPath(path);
  if (dirty.states) refreshActive();
  for (const m of dirty.machines) paintMachineCurrent(m);
}

export function wireTree() {
  $("#tree").addEventListener("click", onTreeClick);
  $("#expand-all").addEventListener("click", () => setAllCollapsed(false));
  $("#collapse-all").addEventListener("click", () => setAllCollapsed(true));
}
