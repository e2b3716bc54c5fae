// Replay of a finished run: the scrubber, the tick field, play and ← →; the picture at the
// tick wanted comes from /api/at, one request at a time.

import { applyAt, applySnapshot } from "./apply.js";
import { setConn, showMessage } from "./header.js";
import { model } from "./model.js";
import { $, clamp, getJSON } from "./util.js";

let range = { first: 0, last: 0 };
let atWanted = null;
let atBusy = false;
let playTimer = null;

export function requestAt(n) {
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

export async function startReplay() {
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

export function wireReplay() {
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
