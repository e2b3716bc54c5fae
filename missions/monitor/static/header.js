// The header: what the run is doing (#status-line), the connection dot, and the message line
// every part of the page reports to.

import { model } from "./model.js";
import { $, el, fmtT } from "./util.js";

export function showMessage(text, kind) {
  const m = $("#message");
  m.textContent = text;
  m.className = kind || "";
  m.title = new Date().toLocaleTimeString() + "  " + text;
}

export function renderStatus() {
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

export function setConn(state) {
  const c = $("#conn");
  c.className = "conn " + state;
  c.title = { up: "connected (live updates)", down: "disconnected, reconnecting…", "": "" }[state] || state;
}
