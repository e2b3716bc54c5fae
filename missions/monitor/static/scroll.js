// Scrolling lists (timeline, logs, display list, transcript, photo strip): each follows its end
// while the reader is there, and is trimmed to a bounded length.

export function atBottom(box) {
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

export function stickToEnd(box, forced) {
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

// Rows are dropped from the top in batches: removing the first rows moves every row left, which
// costs a layout and paint invalidation of the whole list, so do it once per max/8 rows added
// rather than every frame (the list holds at most max + max/8 rows).
export function trim(box, max) {
  const n = box.childElementCount;
  if (n <= max + (max >> 3)) return;
  const range = document.createRange();
  range.setStartBefore(box.firstElementChild);
  range.setEndBefore(box.children[n - max]);
  range.deleteContents();
}

function atRight(box) {
  return box.scrollWidth - box.scrollLeft - box.clientWidth < 24;
}

// A list follows its end (the newest rows) until the reader scrolls away from it, and goes back
// to following once scrolled to the end again. Kept in box._follow from the reader's scrolling
// (a hidden box fires no scroll event and forgets its position: box._scroll brings it back), so
// a list whose box shrinks (the photo strip appearing above the transcript) keeps following.
function isStrip(box) {
  return box.classList.contains("photo-strip");
}

export function trackScroll(box) {
  box.addEventListener("scroll", () => {
    if (!box.clientHeight) return; // hidden
    box._follow = isStrip(box) ? atRight(box) : atBottom(box);
    box._scroll = isStrip(box) ? box.scrollLeft : box.scrollTop;
  }, { passive: true });
  // shown again, or resized: keep the end in view when following
  new ResizeObserver(() => { if (box.clientHeight) restoreScroll(box); }).observe(box);
}

export function restoreScroll(box) {
  const strip = isStrip(box);
  if (box._follow === false) {
    if (strip) box.scrollLeft = box._scroll || 0;
    else box.scrollTop = box._scroll || 0;
  } else if (strip) box.scrollLeft = box.scrollWidth;
  else box.scrollTop = box.scrollHeight;
}
