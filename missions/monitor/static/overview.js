// botstage monitor: the overview of several runs (sources.py serves it).
//
// GET api/sources once: the runs, each served under s/<name>/ by its own monitor; then every
// POLL_MS each run's s/<name>/api/summary (where it is, its active states, the skills running, its
// newest events) and, for a deployment, api/processes (each process's state and what it hosts).
// A run whose monitor does not answer stays on the page, marked, and is asked again. "Side by
// side" shows each run's full monitor in a frame of its own under the cards.

import { getJSON } from "./util.js";

const POLL_MS = 500;
const $ = (id) => document.getElementById(id);
const runs = new Map(); // name -> {source, card, summary, down}
let processes = null; // the last api/processes answer, or null when there is none

function el(tag, attrs = {}, ...children) {
  const node = document.createElement(tag);
  for (const [name, value] of Object.entries(attrs)) {
    if (name === "class") node.className = value;
    else node.setAttribute(name, value);
  }
  for (const child of children) node.append(child);
  return node;
}

// The server's own words (getJSON's detail), or the network's.
function why(err) {
  return err.detail || err.message;
}

function runState(s) {
  if (s.ended) return ["ended", `ended: ${s.outcome || "?"}`];
  if (s.estopped) return ["held", "e-stopped"];
  if (s.paused) return ["held", "paused"];
  return ["running", s.tick < 0 ? "starting" : "running"];
}

function list(items) {
  return items.length ? el("ul", {}, ...items.map((text) => el("li", {}, text))) : el("div", { class: "muted" }, "none");
}

function drawCard(run) {
  const { source, summary: s } = run;
  const card = el("article", { class: "card" + (run.down ? " down" : ""), "data-source": source.name });
  const open = el("a", { href: source.url, target: "_blank" }, "open ↗");
  const heading = el("h3", {}, source.name, el("span", { class: "badge" }, source.kind));
  if (run.down) heading.append(el("span", { class: "badge down" }, "not answering"));
  else if (s) {
    const [cls, text] = runState(s);
    heading.append(el("span", { class: `badge ${cls}`, "data-role": "state" }, text));
  }
  heading.append(open);
  card.append(heading, el("div", { class: "where" }, source.where || ""));
  if (run.down) card.append(el("div", { class: "line muted" }, run.down));
  if (s) {
    const info = s.info || {};
    const what = [info.mission, info.robot && `on ${info.robot}`, info.world && `in ${info.world}`].filter(Boolean);
    card.append(el("div", { class: "line" }, what.join(" ")));
    card.append(el("div", { class: "line", "data-role": "tick" }, `tick ${s.tick}, ${Number(s.t).toFixed(1)} s`));
    card.append(el("div", { class: "muted" }, "active states"));
    card.append(list(Object.values(s.states)));
    card.append(el("div", { class: "muted" }, "skills running"));
    card.append(list(s.running.map((r) => `${r.skill} (${r.path})`)));
    const events = el("div", { class: "events" });
    for (const entry of s.timeline.slice().reverse()) events.append(el("div", {}, `${entry.tick}: ${entry.text}`));
    card.append(el("div", { class: "muted" }, "newest events"), events);
  }
  if (run.card) run.card.replaceWith(card);
  else $("cards").append(card);
  run.card = card;
}

function drawProcesses() {
  const body = $("processes").querySelector("tbody");
  body.replaceChildren();
  const runningSkills = new Set();
  for (const run of runs.values()) for (const r of (run.summary?.running || [])) runningSkills.add(r.skill);
  for (const p of processes) {
    const now = (p.skills || []).filter((skill) => runningSkills.has(skill));
    const state = el("td", { class: `state-${String(p.state).split(" ")[0]}` }, p.state);
    const name = p.mission ? `${p.name} (the mission)` : p.name;
    body.append(el("tr", { "data-process": p.name },
      el("td", {}, name), state, el("td", {}, now.join(", ")),
      el("td", {}, (p.skills || []).join(", ")), el("td", {}, (p.interfaces || []).join(", ")),
      el("td", { class: "muted" }, p.description || "")));
  }
}

async function pollRun(run) {
  try {
    run.summary = await getJSON(`${run.source.url}api/summary`);
    run.down = "";
  } catch (err) {
    run.down = `its monitor does not answer: ${why(err)}`;
  }
  drawCard(run);
}

async function poll(hasProcesses) {
  await Promise.all([...runs.values()].map(pollRun));
  if (hasProcesses) {
    try {
      processes = await getJSON("api/processes");
      $("processes-box").hidden = false;
      drawProcesses();
    } catch (err) {
      $("message").textContent = `processes: ${why(err)}`;
    }
  }
  setTimeout(() => poll(hasProcesses), POLL_MS);
}

function sideBySide(on) {
  const frames = $("frames");
  frames.hidden = !on;
  if (!on) { frames.replaceChildren(); return; } // a hidden monitor costs nothing
  for (const run of runs.values()) {
    frames.append(el("iframe", { src: run.source.url, title: `the monitor of ${run.source.name}` }));
  }
}

async function start() {
  let listed;
  try {
    listed = await getJSON("api/sources");
  } catch (err) {
    $("message").textContent = `cannot list the runs: ${why(err)}`;
    setTimeout(start, 2000);
    return;
  }
  $("title").textContent = listed.title || "";
  $("count").textContent = `${listed.sources.length} run${listed.sources.length === 1 ? "" : "s"}`;
  if (listed.title) document.title = `botstage monitor: ${listed.title}`;
  for (const source of listed.sources) {
    const run = { source, card: null, summary: null, down: "" };
    runs.set(source.name, run);
    drawCard(run); // in the order listed, whatever order their answers come in
  }
  $("side-by-side").addEventListener("change", (e) => sideBySide(e.target.checked));
  poll(listed.processes);
}

start();
