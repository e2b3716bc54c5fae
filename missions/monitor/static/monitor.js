// botstage live monitor: the browser side.
//
// Data flow: GET /api/info and /api/structure once; then, live, /api/snapshot followed by an
// EventSource on /api/events?since=<snapshot version> whose JSON deltas are applied onto it
// (both again on every reconnect), or, in replay, /api/at?tick=N for the scrubbed tick.
//
// The tree DOM is built once; deltas only touch the attributes and classes of the rows whose
// status changed (looked up in a Map path -> row elements). Incoming data goes into `model`
// at once and marks what is dirty; the DOM is brought up to date at most once per animation
// frame by flush(), so a burst of deltas costs one repaint.
//
// window.monitor = {version, applied} is published after each flush so tests can wait for it;
// with it `robot` (the last robot object) and `teleop` ({v, w} last sent to /api/teleop).
//
// The right column's lower panel (#panel-feed) has three tabs: photos & transcript
// (#panel-people: #photos, #transcript), logs (#panel-logs) and the layouts shown
// (#panel-display); a tab not shown counts what arrived meanwhile. A thumbnail opens the photo
// large in #photo-overlay. Photos are only ever requested by the names the server listed.

"use strict";

(() => {
  const MAX_ENTRIES = 2000;        // timeline and log rows kept in the DOM
  const MAX_DISPLAY = 2000;        // display-list rows kept in the DOM
  const MAX_SAID = 500;            // transcript lines kept in the DOM (as many as the hub keeps)
  const MAX_PHOTOS = 200;          // photo thumbnails kept in the DOM (as many as the hub keeps)
  const TAB_KEY = "botstage.monitor.tab";
  const TOKEN_KEY = "botstage.monitor.token";
  const VALUE_CHARS = 120;         // blackboard values longer than this are cut (full in title)
  const RETRY_MS = 3000;

  const STATUS_CLASSES = ["running", "success", "failure", "invalid"];
  const KIND_LABEL = {
    group: "group", machine: "machine", state: "state", outcome: "outcome", skill: "skill",
    condition: "cond", sequence: "seq", selector: "sel", parallel: "par", decorator: "deco",
  };

  // ---- small helpers ----------------------------------------------------------------------

  const $ = (sel) => document.querySelector(sel);

  function el(tag, className, text) {
    const e = document.createElement(tag);
    if (className) e.className = className;
    if (text !== undefined && text !== null) e.textContent = String(text);
    return e;
  }

  function lastSegment(path) {
    const s = String(path || "");
    const i = s.lastIndexOf("/");
    return i >= 0 ? s.slice(i + 1) : s;
  }

  // "/a/b/c" -> ["/a", "/a/b", "/a/b/c"]; works without the leading slash too.
  function prefixes(path) {
    const parts = String(path).split("/");
    const out = [];
    for (let i = 0; i < parts.length; i++) {
      const p = parts.slice(0, i + 1).join("/");
      if (p && p !== "/") out.push(p);
    }
    return out;
  }

  function fmtT(t) {
    return typeof t === "number" && isFinite(t) ? t.toFixed(1) : "";
  }

  function toJSON(value) {
    if (value === undefined) return "";
    try {
      return JSON.stringify(value);
    } catch (e) {
      return String(value);
    }
  }

  function truncate(s, n) {
    return s.length > n ? s.slice(0, n - 1) + "…" : s;
  }

  function clamp(n, lo, hi) {
    return Math.min(hi, Math.max(lo, n));
  }

  // FastAPI answers errors as {"detail": str} or, for validation errors, {"detail": [{msg, loc}]}.
  function detailText(data) {
    if (!data) return "";
    const d = data.detail !== undefined ? data.detail : data.message;
    if (typeof d === "string") return d;
    if (Array.isArray(d)) {
      return d.map((x) => (x && x.msg ? (x.loc ? x.loc.join(".") + ": " : "") + x.msg : toJSON(x))).join("; ");
    }
    return d === undefined ? "" : toJSON(d);
  }

  async function getJSON(url) {
    const r = await fetch(url, { cache: "no-store" });
    if (!r.ok) {
      let data = null;
      try { data = await r.json(); } catch (e) { /* not JSON */ }
      const err = new Error(`${url}: ${detailText(data) || "HTTP " + r.status}`);
      err.detail = detailText(data) || `HTTP ${r.status}`;
      throw err;
    }
    return r.json();
  }

  function showMessage(text, kind) {
    const m = $("#message");
    m.textContent = text;
    m.className = kind || "";
    m.title = new Date().toLocaleTimeString() + "  " + text;
  }

  // ---- the model: what the page knows, independent of the DOM --------------------------

  const model = {
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

  // What flush() has to bring into the DOM.
  const dirty = {
    all: false,              // statuses/states/blackboard replaced wholesale
    statuses: new Set(),
    states: false,
    machines: new Set(),
    bb: new Set(),
    status: false,           // the header
    breakpoints: false,
    entriesReset: false,     // timeline + logs replaced by pendingEntries
    displayReset: false,
    saidReset: false,        // transcript replaced by pendingSaid
    photosReset: false,      // photos replaced by pendingPhotos
    robot: false,            // the map, data-pose and the teleop panel
    flash: false,            // changed blackboard rows to unmark
    teleop: false,           // the teleop panel only (a key or button held or let go)
  };
  let pendingEntries = [];
  let pendingDisplay = [];
  let pendingSaid = [];
  let pendingPhotos = [];

  // ---- DOM indexes -------------------------------------------------------------------------

  const rowsByPath = new Map();   // path -> [row elements] (a nested machine may share its state's path)
  const stateRows = [];           // rows of kind "state"
  const machineRows = new Map();  // machine path -> [row] (to show its current state)
  const machineParent = new Map(); // machine path -> the state it runs in (null: top level)
  let activeSet = new Set();      // active state paths and all their ancestors
  let leafSet = new Set();        // innermost active states
  let bpMarked = [];              // rows marked as having a breakpoint
  const bbRows = new Map();       // key -> <tr>
  let selectedKey = null;
  let selectedRow = null;

  // ---- the structure tree ------------------------------------------------------------------

  function buildTree(structure) {
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
    if (kind === "state") stateRows.push(row);
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

  function markBreakpointRows() {
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

  function revealRow(path) {
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

  // ---- blackboard ---------------------------------------------------------------------------

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

  // A changed row is marked for FLASH_MS, unmarked by a later flush: a static highlight is
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

  // ---- timeline, logs, display list --------------------------------------------------------

  function atBottom(box) {
    return box.scrollHeight - box.scrollTop - box.clientHeight < 24;
  }

  // Keep a list's end in view after rows were added, without forcing a layout: the scroll is
  // written from a ResizeObserver callback, which runs after the frame's own layout (so reading
  // scrollHeight there is free). Whether a list follows its end is known from the reader's
  // scrolling (box._follow, kept by the scroll listeners), never read in the update path.
  const stickBoxes = new Map(); // box -> forced (a reset scrolls to the end regardless)
  const stickRO = typeof ResizeObserver === "function" ? new ResizeObserver(onStick) : null;

  function scrollToEnd(box) {
    if (box.classList.contains("photo-strip")) box.scrollLeft = box.scrollWidth;
    else box.scrollTop = box.scrollHeight;
  }

  function stickToEnd(box, forced) {
    if (!stickRO) { scrollToEnd(box); return; }
    stickBoxes.set(box, !!forced || !!stickBoxes.get(box));
    const target = box.lastElementChild || box;
    stickRO.unobserve(target); // observed anew: reported after the next layout
    stickRO.observe(target);
  }

  function onStick(entries) {
    for (const e of entries) stickRO.unobserve(e.target);
    for (const [box, forced] of stickBoxes) if (forced || box._follow !== false) scrollToEnd(box);
    stickBoxes.clear();
  }

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

  // Rows are dropped from the top in batches: removing the first rows moves every row left, which
  // costs a layout and paint invalidation of the whole list, so do it once per max/8 rows added
  // rather than every frame (the list holds at most max + max/8 rows).
  function trim(box, max) {
    const n = box.childElementCount;
    if (n <= max + (max >> 3)) return;
    const range = document.createRange();
    range.setStartBefore(box.firstElementChild);
    range.setEndBefore(box.children[n - max]);
    range.deleteContents();
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

  function renderEntries(entries, reset) {
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

  function renderDisplay(items, reset) {
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
  function markTimelineCursor(tick) {
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

  // ---- transcript ------------------------------------------------------------------------------

  // One line said: the robot's on the left, a visitor's on the right (CSS, by data-who); the
  // speaker's name only above the first of consecutive lines by the same speaker.
  function sayRow(s) {
    const who = String(s.who || "robot");
    const row = el("div", "say");
    row.dataset.who = who;
    row.dataset.tick = s.tick;
    row.title = `${who} · tick ${s.tick} · t ${fmtT(s.t)} s`;
    row.appendChild(el("span", "say-who", who));
    row.appendChild(el("span", "bubble", s.text ?? ""));
    row.appendChild(el("span", "say-t", fmtT(s.t)));
    return row;
  }

  function renderSaid(items, reset) {
    const box = $("#transcript");
    const stick = reset || box._follow !== false;
    if (reset) box.textContent = "";
    let last = box.lastElementChild ? box.lastElementChild.dataset.who : null;
    const frag = document.createDocumentFragment();
    for (const s of items) {
      if (!s || typeof s !== "object") continue;
      const row = sayRow(s);
      if (row.dataset.who === last) row.classList.add("cont");
      last = row.dataset.who;
      frag.appendChild(row);
    }
    if (!reset) noteUnread("people", frag.childElementCount, false);
    box.appendChild(frag);
    trim(box, MAX_SAID);
    if (box.firstElementChild) box.firstElementChild.classList.remove("cont"); // its speaker went
    if (stick) stickToEnd(box, reset);
    laterTick = null; // replay: mark the rows again
  }

  function onTranscriptClick(ev) {
    const row = ev.target.closest(".say");
    if (row && model.replay) requestAt(Number(row.dataset.tick));
  }

  // ---- photos -----------------------------------------------------------------------------------

  function photoURL(file) {
    return "api/photo?file=" + encodeURIComponent(file);
  }

  function photoThumb(p) {
    const btn = el("button", "thumb");
    btn.type = "button";
    btn.dataset.tick = p.tick;
    btn.title = `${lastSegment(p.file)} · tick ${p.tick} · t ${fmtT(p.t)} s (click: larger)`;
    btn._photo = p;
    const img = el("img");
    img.loading = "lazy";
    img.decoding = "async";
    img.width = 112;
    img.height = 84;
    img.alt = `photo at t ${fmtT(p.t)} s`;
    img.dataset.file = p.file;
    img.onerror = () => { btn.hidden = true; }; // gone from the server: no broken image
    img.src = photoURL(p.file);
    btn.appendChild(img);
    btn.appendChild(el("span", "thumb-t", fmtT(p.t) + " s"));
    return btn;
  }

  function atRight(box) {
    return box.scrollWidth - box.scrollLeft - box.clientWidth < 24;
  }

  // Oldest on the left, newest on the right; a reset keeps the thumbnails it already has (no
  // image is fetched twice).
  function renderPhotos(items, reset) {
    const box = $("#photos");
    const stick = reset || box._follow !== false;
    const had = new Map();
    if (reset) {
      for (const b of box.children) if (b._photo) had.set(b._photo.file, b);
      box.textContent = "";
    }
    const frag = document.createDocumentFragment();
    for (const p of items) {
      if (!p || typeof p !== "object" || typeof p.file !== "string" || !p.file) continue;
      const old = had.get(p.file);
      if (old && old._photo.tick === p.tick) {
        had.delete(p.file);
        frag.appendChild(old);
      } else {
        frag.appendChild(photoThumb(p));
      }
    }
    if (!reset) noteUnread("people", frag.childElementCount, false);
    box.appendChild(frag);
    trim(box, MAX_PHOTOS);
    if (stick) stickToEnd(box, reset);
    laterTick = null;
  }

  // The photo shown large (its thumbnail's data), or null.
  let largePhoto = null;
  let largeFrom = null; // what had the focus before

  function visibleThumbs() {
    return [...$("#photos").children].filter((b) => b._photo && !b.hidden);
  }

  function showPhoto(p) {
    largePhoto = p;
    const img = $("#photo-large");
    img.alt = `photo taken at t ${fmtT(p.t)} s`;
    img.src = photoURL(p.file);
    $("#photo-caption").textContent = `${lastSegment(p.file)} · tick ${p.tick} · t ${fmtT(p.t)} s`;
    const thumbs = visibleThumbs();
    const i = thumbs.findIndex((b) => b._photo.file === p.file);
    $("#photo-prev").disabled = i <= 0;
    $("#photo-next").disabled = i < 0 || i >= thumbs.length - 1;
  }

  function openPhoto(btn) {
    if (!btn || !btn._photo) return;
    largeFrom = document.activeElement;
    showPhoto(btn._photo);
    $("#photo-overlay").hidden = false;
    $("#photo-close").focus({ preventScroll: true });
  }

  function closePhoto() {
    const overlay = $("#photo-overlay");
    if (overlay.hidden) return;
    overlay.hidden = true;
    $("#photo-large").removeAttribute("src");
    largePhoto = null;
    if (largeFrom && largeFrom.isConnected && largeFrom.focus) largeFrom.focus({ preventScroll: true });
    largeFrom = null;
  }

  function stepPhoto(by) {
    if (!largePhoto) return;
    const thumbs = visibleThumbs();
    const i = thumbs.findIndex((b) => b._photo.file === largePhoto.file);
    const next = i >= 0 ? thumbs[i + by] : null;
    if (next) {
      showPhoto(next._photo);
      next.scrollIntoView({ block: "nearest", inline: "nearest" });
    }
  }

  // While the photo is up, the keys are its own: Escape closes, ← → step; no arrow reaches the
  // scrubber or the teleop (keydown only: a key let go always reaches the teleop).
  function onOverlayKey(ev) {
    if ($("#photo-overlay").hidden) return;
    const keys = { Escape: 0, ArrowLeft: -1, ArrowRight: 1, ArrowUp: 0, ArrowDown: 0 };
    if (!(ev.key in keys)) return;
    ev.preventDefault();
    ev.stopPropagation();
    if (ev.key === "Escape") closePhoto();
    else if (keys[ev.key]) stepPhoto(keys[ev.key]);
  }

  function wirePhotos() {
    $("#photos").addEventListener("click", (ev) => openPhoto(ev.target.closest(".thumb")));
    $("#transcript").addEventListener("click", onTranscriptClick);
    const overlay = $("#photo-overlay");
    overlay.addEventListener("click", (ev) => {
      if (ev.target.closest("#photo-prev")) stepPhoto(-1);
      else if (ev.target.closest("#photo-next")) stepPhoto(1);
      else closePhoto(); // anywhere else, the photo too
    });
    $("#photo-large").addEventListener("error", () => {
      if (largePhoto) $("#photo-caption").textContent = `${lastSegment(largePhoto.file)}: cannot load it`;
    });
    window.addEventListener("keydown", onOverlayKey, true);
  }

  // Replay: what was said and taken after the scrubbed tick is dimmed, and the transcript keeps
  // its last line at or before the tick in view.
  let laterTick = null;
  function markLater(tick) {
    if (tick === laterTick) return;
    laterTick = tick;
    let cursor = null;
    for (const row of $("#transcript").children) {
      const later = Number(row.dataset.tick) > tick;
      row.classList.toggle("later", later);
      if (!later) cursor = row;
    }
    const strip = $("#photos");
    let taken = null;
    for (const b of strip.children) {
      const later = Number(b.dataset.tick) > tick;
      b.classList.toggle("later", later);
      if (!later && !b.hidden) taken = b;
    }
    if (taken && strip.clientWidth) {
      const left = taken.offsetLeft; // the strip is positioned: offsets are its own
      if (left < strip.scrollLeft || left + taken.offsetWidth > strip.scrollLeft + strip.clientWidth) {
        strip.scrollLeft = left - strip.clientWidth + taken.offsetWidth + 8;
      }
    }
    const box = $("#transcript");
    if (cursor && box.clientHeight) {
      const top = cursor.offsetTop;
      if (top < box.scrollTop || top + cursor.offsetHeight > box.scrollTop + box.clientHeight) {
        box.scrollTop = top - box.clientHeight + cursor.offsetHeight + 8;
      }
    }
  }

  // ---- tabs: photos & transcript, logs, display ---------------------------------------------

  const TABS = ["people", "logs", "display"];
  let activeTab = "people";
  const unread = { people: 0, logs: 0, display: 0 };

  // The scrolling lists of a tab's pane, and whether each follows its end (vertical or not).
  function paneLists(name) {
    return [...$("#panel-" + name).querySelectorAll(".panel-body, .photo-strip")];
  }

  function selectTab(name) {
    if (!TABS.includes(name)) name = "people";
    activeTab = name;
    for (const tab of TABS) {
      const on = tab === name;
      $("#tab-" + tab).setAttribute("aria-selected", on ? "true" : "false");
      $("#tab-" + tab).tabIndex = on ? 0 : -1;
      $("#panel-" + tab).hidden = !on;
    }
    for (const box of paneLists(name)) restoreScroll(box);
    unread[name] = 0;
    paintUnread(name, false);
    if (name === "people" && model.replay) { laterTick = null; markLater(model.tick); }
    try { localStorage.setItem(TAB_KEY, name); } catch (e) { /* storage off */ }
  }

  // New rows in a tab not shown: counted on it (red when a log warns or fails).
  function noteUnread(name, count, alarm) {
    if (!count || name === activeTab) return;
    unread[name] += count;
    paintUnread(name, alarm);
  }

  function paintUnread(name, alarm) {
    const badge = $("#tab-" + name + " .tab-count");
    const n = unread[name];
    badge.textContent = n ? (n > 99 ? "99+" : String(n)) : "";
    if (!n) badge.classList.remove("alarm");
    else if (alarm) badge.classList.add("alarm");
  }

  // A list follows its end (the newest rows) until the reader scrolls away from it, and goes back
  // to following once scrolled to the end again. Kept in box._follow from the reader's scrolling
  // (a hidden box fires no scroll event and forgets its position: box._scroll brings it back), so
  // a list whose box shrinks (the photo strip appearing above the transcript) keeps following.
  function isStrip(box) {
    return box.classList.contains("photo-strip");
  }

  function trackScroll(box) {
    box.addEventListener("scroll", () => {
      if (!box.clientHeight) return; // hidden
      box._follow = isStrip(box) ? atRight(box) : atBottom(box);
      box._scroll = isStrip(box) ? box.scrollLeft : box.scrollTop;
    }, { passive: true });
    // shown again, or resized: keep the end in view when following
    new ResizeObserver(() => { if (box.clientHeight) restoreScroll(box); }).observe(box);
  }

  function restoreScroll(box) {
    const strip = isStrip(box);
    if (box._follow === false) {
      if (strip) box.scrollLeft = box._scroll || 0;
      else box.scrollTop = box._scroll || 0;
    } else if (strip) box.scrollLeft = box.scrollWidth;
    else box.scrollTop = box.scrollHeight;
  }

  function wireTabs() {
    for (const tab of TABS) for (const box of paneLists(tab)) trackScroll(box);
    for (const tab of TABS) $("#tab-" + tab).addEventListener("click", () => selectTab(tab));
    let saved = null;
    try { saved = localStorage.getItem(TAB_KEY); } catch (e) { /* storage off */ }
    selectTab(saved || "people");
  }

  // ---- breakpoints list ---------------------------------------------------------------------

  function renderBreakpoints() {
    const ul = $("#breakpoints");
    ul.textContent = "";
    if (!model.breakpoints.length) {
      ul.appendChild(el("li", "empty", "no breakpoints"));
    }
    for (const bp of model.breakpoints) {
      const li = el("li");
      li.dataset.id = bp.id;
      li.appendChild(el("span", "bp-kind", bp.kind));
      const target = el("span", "bp-target", bp.target);
      target.title = bp.target;
      li.appendChild(target);
      const rm = el("button", "small bp-remove", "✕");
      rm.type = "button";
      rm.title = "remove this breakpoint";
      rm.dataset.id = bp.id;
      li.appendChild(rm);
      ul.appendChild(li);
    }
    markBreakpointRows();
  }

  // ---- header ------------------------------------------------------------------------------

  function renderStatus() {
    let word;
    let state;
    if (model.ended) {
      word = "ENDED" + (model.outcome ? ` (${model.outcome})` : "");
      state = "ended";
    } else if (model.estopped) {
      word = "E-STOPPED";
      state = "estopped";
    } else if (model.paused) {
      word = "PAUSED" + (model.pause_reason ? ` (${model.pause_reason})` : "");
      state = "paused";
    } else {
      word = "RUNNING";
      state = "running";
    }
    const mission = model.info ? model.info.mission : "";
    const parts = [mission, `tick ${model.tick}`, `t ${fmtT(model.t)} s`];
    const line = $("#status-line");
    const text = parts.join("  ") + "  " + word;
    if (line._text !== text) {
      line._text = text;
      let parts = line._parts;
      if (!parts || parts[0].parentNode !== line) {
        parts = line._parts = [el("span", "sl-mission"), document.createTextNode(""), el("span", "sl-state")];
        line.textContent = "";
        for (const n of parts) line.appendChild(n);
      }
      const mid = `  tick ${model.tick}  t ${fmtT(model.t)} s  `;
      if (parts[0].textContent !== mission) parts[0].textContent = mission;
      if (parts[1].data !== mid) parts[1].data = mid;
      if (parts[2].textContent !== word) parts[2].textContent = word;
      line.title = text;
    }
    if (line.dataset.state !== state) line.dataset.state = state;
    const body = document.body.classList;
    body.toggle("is-paused", model.paused);
    body.toggle("is-estopped", model.estopped);
    body.toggle("is-ended", model.ended);
  }

  function setConn(state) {
    const c = $("#conn");
    c.className = "conn " + state;
    c.title = { up: "connected (live updates)", down: "disconnected, reconnecting…", "": "" }[state] || state;
  }

  // ---- applying snapshots, deltas and replay ticks ------------------------------------------

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

  function applySnapshot(s) {
    setScalars(s);
    replaceMaps(s);
    model.version = s.version ?? model.version;
    model.breakpoints = Array.isArray(s.breakpoints) ? s.breakpoints : [];
    dirty.breakpoints = true;
    pendingEntries = Array.isArray(s.timeline) ? s.timeline.slice(-MAX_ENTRIES) : [];
    dirty.entriesReset = true;
    pendingDisplay = Array.isArray(s.display) ? s.display.slice(-MAX_DISPLAY) : [];
    dirty.displayReset = true;
    pendingSaid = Array.isArray(s.said) ? s.said.slice(-MAX_SAID) : [];
    dirty.saidReset = true;
    pendingPhotos = Array.isArray(s.photos) ? s.photos.slice(-MAX_PHOTOS) : [];
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

  function applyDelta(d) {
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
      pendingEntries.push(...d.timeline);
      if (pendingEntries.length > MAX_ENTRIES) pendingEntries = pendingEntries.slice(-MAX_ENTRIES);
    }
    if (Array.isArray(d.display) && d.display.length) {
      pendingDisplay.push(...d.display);
      if (pendingDisplay.length > MAX_DISPLAY) pendingDisplay = pendingDisplay.slice(-MAX_DISPLAY);
    }
    if (Array.isArray(d.said) && d.said.length) {
      pendingSaid.push(...d.said);
      if (pendingSaid.length > MAX_SAID) pendingSaid = pendingSaid.slice(-MAX_SAID);
    }
    if (Array.isArray(d.photos) && d.photos.length) {
      pendingPhotos.push(...d.photos);
      if (pendingPhotos.length > MAX_PHOTOS) pendingPhotos = pendingPhotos.slice(-MAX_PHOTOS);
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
  function applyAt(a) {
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

  // ---- batching: one DOM update per animation frame ------------------------------------------

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

  function schedule() {
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

    if (dirty.all) {
      const [set, leaves] = computeActive();
      activeSet = set;
      leafSet = leaves;
      for (const rows of rowsByPath.values()) for (const r of rows) paintRow(r);
      for (const m of machineRows.keys()) paintMachineCurrent(m);
      renderBlackboardAll();
      if (selectedKey && !model.replay && model.blackboard.has(selectedKey)) historyChanged();
    } else {
      for (const path of dirty.statuses) paintPath(path);
      if (dirty.states) refreshActive();
      for (const m of dirty.machines) paintMachineCurrent(m);
      if (dirty.bb.size) {
        renderBlackboardKeys(dirty.bb);
        if (selectedKey && dirty.bb.has(selectedKey)) historyChanged();
      }
    }
    dirty.flash = false;
    unflashRows();
    dirty.all = false;
    dirty.statuses.clear();
    dirty.states = false;
    dirty.machines.clear();
    dirty.bb.clear();

    const statusChanged = dirty.status; // the run may have ended: the teleop panel goes
    if (dirty.status) renderStatus();
    dirty.status = false;

    if (dirty.entriesReset || pendingEntries.length) {
      renderEntries(pendingEntries, dirty.entriesReset);
      pendingEntries = [];
      dirty.entriesReset = false;
    }
    if (dirty.displayReset || pendingDisplay.length) {
      renderDisplay(pendingDisplay, dirty.displayReset);
      pendingDisplay = [];
      dirty.displayReset = false;
    }
    if (dirty.saidReset || pendingSaid.length) {
      renderSaid(pendingSaid, dirty.saidReset);
      pendingSaid = [];
      dirty.saidReset = false;
    }
    if (dirty.photosReset || pendingPhotos.length) {
      renderPhotos(pendingPhotos, dirty.photosReset);
      pendingPhotos = [];
      dirty.photosReset = false;
    }
    if (dirty.breakpoints) renderBreakpoints();
    dirty.breakpoints = false;

    if (model.replay) {
      markTimelineCursor(model.tick);
      if (activeTab === "people") markLater(model.tick);
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

  // ---- live: snapshot, then the event stream from its version --------------------------------
  //
  // Every (re)connection fetches /api/snapshot, applies it, then opens /api/events?since=<its
  // version>, so the stream carries exactly what came after the snapshot: no gap, no entry twice.
  // (A backend that ignores `since` is fine too: deltas not newer than what we hold are dropped.)
  // On a stream error we close it ourselves, rather than let the browser retry with a stale
  // `since`, and start over from a fresh snapshot.

  let es = null;
  let generation = 0;         // bumps on every reconnect: callbacks of an older stream are ignored
  let retryTimer = 0;
  let lostShown = false;      // the "connection lost" message is up

  function onDelta(d) {
    if (!d || typeof d !== "object") return;
    // the snapshot (or an earlier delta) already holds this one
    if (typeof d.version === "number" && typeof model.version === "number" && d.version <= model.version) return;
    applyDelta(d);
    // an ended run changes no more, and its server goes away with it: stop listening
    if (model.ended && es) {
      es.close();
      es = null;
      setConn("down");
    }
  }

  function lost(why) {
    setConn("down");
    // an ended run's server may go away: not worth an alarm then
    if (!model.ended && !lostShown) {
      showMessage(`connection to the backend lost (${why}); reconnecting…`, "error");
      lostShown = true;
    }
  }

  async function connect() {
    clearTimeout(retryTimer);
    const gen = ++generation;
    if (es) {
      es.close();
      es = null;
    }
    let snap;
    try {
      snap = await getJSON("api/snapshot");
    } catch (e) {
      if (gen === generation) {
        lost(e.message);
        retryTimer = setTimeout(connect, RETRY_MS);
      }
      return;
    }
    if (gen !== generation) return;
    // an unchanged snapshot (a reconnect with nothing new) is not worth re-rendering
    if (snap.version === undefined || snap.version !== model.version || !window.monitor.ready) applySnapshot(snap);

    const since = typeof snap.version === "number" ? `?since=${snap.version}` : "";
    const source = new EventSource("api/events" + since);
    es = source;
    source.onmessage = (msg) => {
      if (gen !== generation) return;
      let d;
      try {
        d = JSON.parse(msg.data);
      } catch (e) {
        return; // not a delta
      }
      onDelta(d);
    };
    source.onopen = () => {
      if (gen !== generation) return;
      if (lostShown) showMessage("reconnected", "ok");
      lostShown = false;
      setConn("up");
    };
    source.onerror = () => {
      if (gen !== generation) return;
      source.close();
      if (model.ended) return; // nothing more to hear
      lost("the event stream broke");
      retryTimer = setTimeout(connect, 1000);
    };
  }

  // ---- replay: scrubber -------------------------------------------------------------------

  let range = { first: 0, last: 0 };
  let atWanted = null;
  let atBusy = false;
  let playTimer = null;

  function requestAt(n) {
    if (!Number.isFinite(n)) return;
    n = clamp(Math.round(n), range.first, range.last);
    $("#scrubber").value = n;
    $("#tick").value = n;
    atWanted = n;
    if (!atBusy) pumpAt();
  }

  // One /api/at request at a time; while dragging, only the newest wanted tick is fetched.
  async function pumpAt() {
    atBusy = true;
    while (atWanted !== null) {
      const n = atWanted;
      atWanted = null;
      try {
        applyAt(await getJSON(`api/at?tick=${n}`));
      } catch (e) {
        showMessage(e.message, "error");
      }
    }
    atBusy = false;
  }

  function togglePlay() {
    const btn = $("#replay-play");
    if (playTimer) {
      clearInterval(playTimer);
      playTimer = null;
      btn.textContent = "play";
      return;
    }
    if (Number($("#scrubber").value) >= range.last) requestAt(range.first);
    btn.textContent = "stop";
    playTimer = setInterval(() => {
      if (atBusy) return; // do not queue faster than the server answers
      const n = Number($("#scrubber").value) + 1;
      if (n > range.last) {
        togglePlay();
        return;
      }
      requestAt(n);
    }, 100);
  }

  async function startReplay() {
    const [snap, r] = await Promise.all([getJSON("api/snapshot"), getJSON("api/range")]);
    range = { first: Number(r.first) || 0, last: Number(r.last) || 0 };
    for (const input of [$("#scrubber"), $("#tick")]) {
      input.min = range.first;
      input.max = range.last;
    }
    applySnapshot(snap);
    requestAt(range.last); // start at the end, as the snapshot shows it
    setConn("up");
  }

  function wireReplay() {
    const scrubber = $("#scrubber");
    const tick = $("#tick");
    scrubber.addEventListener("input", () => requestAt(Number(scrubber.value)));
    scrubber.addEventListener("change", () => requestAt(Number(scrubber.value)));
    let typing = null;
    tick.addEventListener("input", () => {
      // wait until the number is typed in full
      clearTimeout(typing);
      typing = setTimeout(() => tick.value !== "" && requestAt(Number(tick.value)), 300);
    });
    tick.addEventListener("change", () => {
      clearTimeout(typing);
      if (tick.value !== "") requestAt(Number(tick.value));
    });
    $("#replay-prev").addEventListener("click", () => requestAt(Number(scrubber.value) - 1));
    $("#replay-next").addEventListener("click", () => requestAt(Number(scrubber.value) + 1));
    $("#replay-play").addEventListener("click", togglePlay);
    document.addEventListener("keydown", (ev) => {
      if (!model.replay || ev.target.closest("input, select, textarea")) return;
      if (ev.key === "ArrowLeft") requestAt(Number(scrubber.value) - 1);
      else if (ev.key === "ArrowRight") requestAt(Number(scrubber.value) + 1);
    });
  }

  // ---- controls -------------------------------------------------------------------------------

  function token() {
    return ($("#token").value || "").trim();
  }

  async function control(body) {
    const headers = { "Content-Type": "application/json" };
    const tok = token();
    if (tok) headers.Authorization = `Bearer ${tok}`;
    let r;
    let data = null;
    try {
      r = await fetch("api/control", { method: "POST", headers, body: JSON.stringify(body) });
    } catch (e) {
      showMessage(`${body.action}: cannot reach the backend (${e.message})`, "error");
      return null;
    }
    try { data = await r.json(); } catch (e) { /* no JSON body */ }
    if (r.ok && (!data || data.ok !== false)) {
      showMessage((data && data.message) || `${body.action}: ok`, "ok");
    } else {
      showMessage(detailText(data) || `${body.action}: HTTP ${r.status}`, "error");
      if ((r.status === 401 || r.status === 403) && model.info && model.info.token_required) $("#token").focus();
    }
    return data;
  }

  function wireControls() {
    for (const action of ["pause", "resume", "step", "estop", "release"]) {
      $("#" + action).addEventListener("click", () => control({ action }));
    }

    $("#break-form").addEventListener("submit", (ev) => {
      ev.preventDefault();
      const target = $("#break-target").value.trim();
      if (!target) {
        showMessage("break: enter a target", "error");
        return;
      }
      control({ action: "break", kind: $("#break-kind").value, target });
    });
    $("#breakpoints").addEventListener("click", (ev) => {
      const btn = ev.target.closest(".bp-remove");
      if (btn) control({ action: "unbreak", id: Number(btn.dataset.id) });
    });

    $("#force-form").addEventListener("submit", (ev) => {
      ev.preventDefault();
      const node = $("#force-node").value.trim();
      const outcome = $("#force-outcome").value.trim();
      let outputs;
      try {
        outputs = JSON.parse($("#force-outputs").value.trim() || "{}");
      } catch (e) {
        showMessage(`force: outputs are not valid JSON (${e.message})`, "error");
        return;
      }
      if (!outputs || typeof outputs !== "object" || Array.isArray(outputs)) {
        showMessage("force: outputs must be a JSON object, e.g. {}", "error");
        return;
      }
      if (!node || !outcome) {
        showMessage("force: enter a node and an outcome", "error");
        return;
      }
      control({ action: "force", node, outcome, outputs });
    });

    $("#write-form").addEventListener("submit", (ev) => {
      ev.preventDefault();
      const key = $("#write-key").value.trim();
      if (!key) {
        showMessage("write: enter a key", "error");
        return;
      }
      const raw = $("#write-value").value;
      let value;
      try {
        value = JSON.parse(raw);
      } catch (e) {
        value = raw; // not JSON: the text itself
      }
      control({ action: "write", key, value });
    });

    const tok = $("#token");
    tok.value = sessionStorage.getItem(TOKEN_KEY) || "";
    tok.addEventListener("input", () => sessionStorage.setItem(TOKEN_KEY, tok.value));
  }

  // ---- the robot: the map panel ---------------------------------------------------------------
  //
  // `model.robot` is the snapshot's (then the deltas') "robot" object, replaced whole each time.
  // /api/map and its PNG are asked for once the run shows a robot (a run without one has no map,
  // and a 404 would be a console error for nothing); a 404 leaves the panel hidden. The canvas
  // keeps the map's aspect inside #map-box; the grid, places and scale bar are drawn once per size
  // into an offscreen canvas, and flush() redraws the robot over it at most once per frame.

  const ROBOT_LENGTH_M = 0.8;       // the pose arrows' length (at least ARROW_MIN_PX)
  const ARROW_MIN_PX = 20;
  const PERSON_M = 0.25;            // radius of a person's circle
  const MAP_COLORS = {
    pose: "#1c2230",
    estimate: "#1f6fd1",
    laser: "rgba(224, 40, 45, 0.9)",
    path: "rgba(122, 63, 191, 0.85)",
    person: "#1c9a3c",
    personFill: "rgba(28, 154, 60, 0.25)",
    crowd: "#f08a00",
    place: "#6b5b9a",
    placeText: "#4a5263",
  };

  const mapView = {
    state: "unknown",   // unknown | loading | ok | none (404)
    info: null,         // what /api/map answered
    image: null,        // the occupancy grid, or null if the PNG would not load
    bg: null,           // offscreen canvas: grid + places + scale bar at the current size
    scale: 1,           // CSS px per map pixel
    w: 0,               // canvas size in CSS px
    h: 0,
    dpr: 1,
    retry: 0,
  };

  function finite(n) {
    return typeof n === "number" && Number.isFinite(n);
  }

  // [x, y, ...] with finite x and y, else null
  function xy(a) {
    return Array.isArray(a) && finite(a[0]) && finite(a[1]) ? a : null;
  }

  async function loadMap() {
    if (mapView.state !== "unknown") return;
    if (model.info && model.info.map === false) {
      mapView.state = "none"; // a backend that says so in /api/info is not asked
      return;
    }
    mapView.state = "loading";
    let info;
    try {
      const r = await fetch("api/map", { cache: "no-store" });
      if (r.status === 404) {
        mapView.state = "none";
        return;
      }
      if (!r.ok) throw new Error(`HTTP ${r.status}`);
      info = await r.json();
    } catch (e) {
      mapView.state = "unknown"; // ask again a little later
      clearTimeout(mapView.retry);
      mapView.retry = setTimeout(() => model.robot && loadMap(), RETRY_MS);
      return;
    }
    if (!info || !(info.width > 0 && info.height > 0 && info.resolution > 0)) {
      mapView.state = "none";
      showMessage("map: /api/map answered no usable size or resolution", "error");
      return;
    }
    const image = new Image();
    const loaded = await new Promise((ok) => {
      image.onload = () => ok(true);
      image.onerror = () => ok(false);
      image.src = `api/map.png?v=${Date.now()}`; // a new run on the same port may have another map
    });
    if (!loaded) showMessage("map: the map image did not load; drawing the robot without it", "error");
    mapView.info = info;
    mapView.image = loaded ? image : null;
    mapView.state = "ok";
    const box = $("#map-box");
    box.style.aspectRatio = `${info.width} / ${info.height}`;
    box.classList.add("fitted");
    $("#panel-map").hidden = false;
    fitMap();
  }

  // Size the canvas to the largest rectangle of the map's aspect that fits #map-box.
  function fitMap() {
    const info = mapView.info;
    if (!info) return;
    const box = $("#map-box");
    const bw = box.clientWidth;
    const bh = box.clientHeight;
    if (!bw || !bh) return;
    const scale = Math.min(bw / info.width, bh / info.height);
    const w = Math.max(1, Math.floor(info.width * scale));
    const h = Math.max(1, Math.floor(info.height * scale));
    const dpr = window.devicePixelRatio || 1;
    if (w === mapView.w && h === mapView.h && dpr === mapView.dpr && mapView.bg) return;
    Object.assign(mapView, { scale, w, h, dpr });
    const canvas = $("#map");
    canvas.style.width = `${w}px`;
    canvas.style.height = `${h}px`;
    canvas.width = Math.round(w * dpr);
    canvas.height = Math.round(h * dpr);
    mapView.bg = drawBackground();
    dirty.robot = true;
    schedule();
  }

  // world (x, y) in metres -> canvas CSS px
  function toCanvas(x, y) {
    const info = mapView.info;
    const o = Array.isArray(info.origin) ? info.origin : [0, 0];
    const s = mapView.scale / info.resolution;
    return [(x - (Number(o[0]) || 0)) * s, mapView.h - (y - (Number(o[1]) || 0)) * s];
  }

  function metres(m) {
    return (m / mapView.info.resolution) * mapView.scale;
  }

  function drawBackground() {
    const { info, image, w, h, dpr } = mapView;
    const bg = document.createElement("canvas");
    bg.width = Math.round(w * dpr);
    bg.height = Math.round(h * dpr);
    const ctx = bg.getContext("2d");
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    if (image) {
      ctx.imageSmoothingEnabled = mapView.scale * dpr < 1; // shrunk: smooth; enlarged: crisp cells
      ctx.imageSmoothingQuality = "high";
      ctx.drawImage(image, 0, 0, w, h);
    } else {
      ctx.fillStyle = "#c8ccd2";
      ctx.fillRect(0, 0, w, h);
    }

    // places: a dot and the name, kept inside the canvas
    ctx.font = "10px system-ui, sans-serif";
    ctx.textBaseline = "middle";
    ctx.lineJoin = "round";
    const places = info.places && typeof info.places === "object" ? info.places : {};
    for (const [name, p] of Object.entries(places)) {
      if (!xy(p)) continue;
      const [px, py] = toCanvas(p[0], p[1]);
      if (px < 0 || py < 0 || px > w || py > h) continue;
      ctx.fillStyle = MAP_COLORS.place;
      ctx.beginPath();
      ctx.arc(px, py, 2.5, 0, 2 * Math.PI);
      ctx.fill();
      const tw = ctx.measureText(name).width;
      const tx = px + 5 + tw > w ? px - 5 - tw : px + 5;
      const ty = clamp(py, 6, h - 6);
      ctx.strokeStyle = "rgba(255, 255, 255, 0.85)";
      ctx.lineWidth = 3;
      ctx.strokeText(name, tx, ty);
      ctx.fillStyle = MAP_COLORS.placeText;
      ctx.fillText(name, tx, ty);
    }

    // a scale bar, bottom left, of a round length some 60-120 px long
    const perM = metres(1);
    const len = [0.5, 1, 2, 5, 10, 20, 50, 100, 200].find((m) => m * perM >= 60) || 200;
    const bx = 8;
    const by = h - 9;
    const bl = len * perM;
    if (bl < w - 16) {
      ctx.fillStyle = "rgba(255, 255, 255, 0.8)";
      ctx.fillRect(bx - 4, by - 15, bl + 8, 20);
      ctx.strokeStyle = MAP_COLORS.pose;
      ctx.lineWidth = 1.5;
      ctx.beginPath();
      ctx.moveTo(bx, by - 4);
      ctx.lineTo(bx, by);
      ctx.lineTo(bx + bl, by);
      ctx.lineTo(bx + bl, by - 4);
      ctx.stroke();
      ctx.fillStyle = MAP_COLORS.pose;
      ctx.textAlign = "center";
      ctx.fillText(`${len} m`, bx + bl / 2, by - 8);
    }
    return bg;
  }

  // An arrow along theta (counter-clockwise from +x; the canvas' y points down).
  function drawArrow(ctx, pose, solid) {
    const [px, py] = toCanvas(pose[0], pose[1]);
    const L = Math.max(ARROW_MIN_PX, metres(ROBOT_LENGTH_M));
    ctx.save();
    ctx.translate(px, py);
    ctx.rotate(-(finite(pose[2]) ? pose[2] : 0));
    ctx.beginPath();
    if (solid) {
      ctx.moveTo(0.6 * L, 0);
      ctx.lineTo(-0.4 * L, 0.38 * L);
      ctx.lineTo(-0.18 * L, 0);
      ctx.lineTo(-0.4 * L, -0.38 * L);
      ctx.closePath();
      ctx.fillStyle = MAP_COLORS.pose;
      ctx.strokeStyle = "#fff";
      ctx.lineWidth = 1.5;
      ctx.stroke();
      ctx.fill();
    } else {
      ctx.moveTo(0.6 * L, 0);
      ctx.lineTo(-0.4 * L, 0.42 * L);
      ctx.lineTo(-0.4 * L, -0.42 * L);
      ctx.closePath();
      ctx.fillStyle = "rgba(31, 111, 209, 0.12)";
      ctx.fill();
      ctx.strokeStyle = MAP_COLORS.estimate;
      ctx.lineWidth = 2;
      ctx.stroke();
    }
    ctx.restore();
  }

  function drawMap() {
    const canvas = $("#map");
    const ctx = canvas.getContext("2d");
    const { dpr, bg } = mapView;
    ctx.setTransform(1, 0, 0, 1, 0, 0);
    ctx.clearRect(0, 0, canvas.width, canvas.height);
    if (!bg) return;
    ctx.drawImage(bg, 0, 0);
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    const r = model.robot;
    if (!r || typeof r !== "object") return;

    // the path the robot is driving (its navigation stack's current plan), goal ringed
    const path = Array.isArray(r.path) ? r.path.filter(xy) : [];
    if (path.length > 1) {
      ctx.strokeStyle = MAP_COLORS.path;
      ctx.lineWidth = 2;
      ctx.lineJoin = "round";
      ctx.setLineDash([6, 4]);
      ctx.beginPath();
      for (const [i, p] of path.entries()) {
        const [px, py] = toCanvas(p[0], p[1]);
        if (i) ctx.lineTo(px, py);
        else ctx.moveTo(px, py);
      }
      ctx.stroke();
      ctx.setLineDash([]);
      const goal = path[path.length - 1];
      const [gx, gy] = toCanvas(goal[0], goal[1]);
      ctx.beginPath();
      ctx.arc(gx, gy, 4, 0, 2 * Math.PI);
      ctx.stroke();
    }

    if (Array.isArray(r.laser) && r.laser.length) {
      ctx.fillStyle = MAP_COLORS.laser;
      ctx.beginPath();
      for (const p of r.laser) {
        if (!xy(p)) continue;
        const [px, py] = toCanvas(p[0], p[1]);
        ctx.rect(px - 1.25, py - 1.25, 2.5, 2.5);
      }
      ctx.fill();
    }

    if (Array.isArray(r.people) && r.people.length) {
      const rad = Math.max(3, metres(PERSON_M));
      ctx.fillStyle = MAP_COLORS.personFill;
      ctx.strokeStyle = MAP_COLORS.person;
      ctx.lineWidth = 1.5;
      for (const p of r.people) {
        if (!xy(p)) continue;
        const [px, py] = toCanvas(p[0], p[1]);
        ctx.beginPath();
        ctx.arc(px, py, rad, 0, 2 * Math.PI);
        ctx.fill();
        ctx.stroke();
      }
    }

    const crowd = xy(r.crowd);
    if (crowd) {
      // size: how many people; the ring grows with it
      const size = finite(crowd[2]) ? Math.max(0, crowd[2]) : 0;
      const [px, py] = toCanvas(crowd[0], crowd[1]);
      const rad = Math.max(8, metres(0.5 + 0.2 * size));
      ctx.strokeStyle = MAP_COLORS.crowd;
      ctx.lineWidth = 3;
      ctx.beginPath();
      ctx.arc(px, py, rad, 0, 2 * Math.PI);
      ctx.stroke();
      if (size) {
        ctx.font = "bold 11px system-ui, sans-serif";
        ctx.textAlign = "left";
        ctx.textBaseline = "middle";
        ctx.lineJoin = "round";
        const label = String(Math.round(size));
        const lx = px + rad * 0.72 + 3;
        const ly = py - rad * 0.72 - 3;
        ctx.strokeStyle = "rgba(255, 255, 255, 0.9)";
        ctx.lineWidth = 3;
        ctx.strokeText(label, lx, ly);
        ctx.fillStyle = MAP_COLORS.crowd;
        ctx.fillText(label, lx, ly);
      }
    }

    // the true pose solid, the estimate outlined over it (both stay visible when they agree)
    if (xy(r.pose)) drawArrow(ctx, r.pose, true);
    if (xy(r.estimate)) drawArrow(ctx, r.estimate, false);
  }

  function fmtPose(p) {
    const deg = finite(p[2]) ? Math.round((p[2] * 180) / Math.PI) : 0;
    return `${p[0].toFixed(2)}, ${p[1].toFixed(2)}, ${deg}°`;
  }

  // data-pose on the canvas, the readout in the panel's head, and the drawing.
  function renderRobot() {
    const r = model.robot && typeof model.robot === "object" ? model.robot : null;
    if (r && mapView.state === "unknown") loadMap();
    const canvas = $("#map");
    const pose = r ? xy(r.pose) || xy(r.estimate) : null;
    if (pose) {
      const th = finite(pose[2]) ? pose[2] : 0;
      const text = `${pose[0].toFixed(3)},${pose[1].toFixed(3)},${th.toFixed(3)}`;
      if (canvas.dataset.pose !== text) canvas.dataset.pose = text;
    } else if (canvas.dataset.pose !== undefined) {
      delete canvas.dataset.pose;
    }
    const points = r && Array.isArray(r.path) ? String(r.path.length) : "0";
    if (canvas.dataset.path !== points) canvas.dataset.path = points; // for tests: the path's points
    const readout = [];
    if (r && xy(r.pose)) readout.push(`pose ${fmtPose(r.pose)}`);
    if (r && xy(r.estimate)) readout.push(`est ${fmtPose(r.estimate)}`);
    const text = readout.join("  ·  ");
    const head = $("#map-pose");
    if (head.textContent !== text) head.textContent = text;
    if (mapView.state === "ok") drawMap();
  }

  function wireMap() {
    if (typeof ResizeObserver === "function") {
      new ResizeObserver(() => fitMap()).observe($("#map-box"));
    } else {
      window.addEventListener("resize", fitMap);
    }
  }

  // ---- the robot: teleop ------------------------------------------------------------------------
  //
  // While a direction is held (an arrow key, or an on-screen button pressed) the command goes at
  // once and again every TELEOP_REPEAT_MS (the robot stops by itself when commands stop coming);
  // when the last one is released, a stop goes at once. Commands go one at a time, the newest
  // waiting replaces an older one; a stop also goes straight away beside one in flight, so the last
  // command the robot hears is the stop. A refused command is not repeated until the next press.

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

  function renderTeleop() {
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

  function wireTeleop() {
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

  // ---- start ---------------------------------------------------------------------------------

  async function start() {
    $("#tree").addEventListener("click", onTreeClick);
    $("#blackboard").addEventListener("click", onBlackboardClick);
    $("#timeline").addEventListener("click", onTimelineClick);
    $("#timeline").addEventListener("scroll", (ev) => {
      const tl = ev.currentTarget;
      if (tl.clientHeight) tl._follow = atBottom(tl);
    }, { passive: true });
    $("#timeline-filter").addEventListener("input", applyFilter);
    $("#history-close").addEventListener("click", () => {
      $("#history-box").hidden = true;
      selectedKey = null;
      for (const r of bbRows.values()) r.classList.remove("selected");
    });
    $("#expand-all").addEventListener("click", () => setAllCollapsed(false));
    $("#collapse-all").addEventListener("click", () => setAllCollapsed(true));
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
})();
