// The operator's controls: the header's buttons (pause, resume, step, e-stop, release), the
// breakpoints & overrides panel (its list, and the break, force and write forms) and the token
// every control request carries (POST /api/control; the teleop's requests carry it too).

import { showMessage } from "./header.js";
import { model } from "./model.js";
import { $, detailText, el } from "./util.js";

const TOKEN_KEY = "botstage.monitor.token";

// The list only: the tree marks its rows itself (tree.js: markBreakpointRows).
export function renderBreakpoints() {
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
}

export function token() {
  return ($("#token").value || "").trim();
}

export async function control(body) {
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

export function wireControls() {
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
