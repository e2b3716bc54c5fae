// The photos & transcript tab: what the robot said and heard, the photos it took (a thumbnail
// opens the photo large in #photo-overlay). Photos are only ever requested by the names the
// server listed. In a replay, what came after the scrubbed tick is dimmed.

import { MAX_PHOTOS, MAX_SAID, model } from "./model.js";
import { requestAt } from "./replay.js";
import { stickToEnd, trim } from "./scroll.js";
import { noteUnread, onTabShown } from "./tabs.js";
import { $, el, fmtT, lastSegment } from "./util.js";

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

export function renderSaid(items, reset) {
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

// Oldest on the left, newest on the right; a reset keeps the thumbnails it already has (no
// image is fetched twice).
export function renderPhotos(items, reset) {
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

export function wirePhotos() {
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
  onTabShown((name) => {
    if (name === "people" && model.replay) { laterTick = null; markLater(model.tick); }
  });
}

// Replay: what was said and taken after the scrubbed tick is dimmed, and the transcript keeps
// its last line at or before the tick in view.
let laterTick = null;
export function markLater(tick) {
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
