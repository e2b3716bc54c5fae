// Helpers the monitor's pages share (monitor.js and the modules it imports, overview.js): DOM
// building, formatting, and fetching JSON with FastAPI's error detail.

export const $ = (sel) => document.querySelector(sel);

export function el(tag, className, text) {
  const e = document.createElement(tag);
  if (className) e.className = className;
  if (text !== undefined && text !== null) e.textContent = String(text);
  return e;
}

export function lastSegment(path) {
  const s = String(path || "");
  const i = s.lastIndexOf("/");
  return i >= 0 ? s.slice(i + 1) : s;
}

// "/a/b/c" -> ["/a", "/a/b", "/a/b/c"]; works without the leading slash too.
export function prefixes(path) {
  const parts = String(path).split("/");
  const out = [];
  for (let i = 0; i < parts.length; i++) {
    const p = parts.slice(0, i + 1).join("/");
    if (p && p !== "/") out.push(p);
  }
  return out;
}

export function fmtT(t) {
  return typeof t === "number" && isFinite(t) ? t.toFixed(1) : "";
}

export function toJSON(value) {
  if (value === undefined) return "";
  try {
    return JSON.stringify(value);
  } catch (e) {
    return String(value);
  }
}

export function truncate(s, n) {
  return s.length > n ? s.slice(0, n - 1) + "…" : s;
}

export function clamp(n, lo, hi) {
  return Math.min(hi, Math.max(lo, n));
}

// FastAPI answers errors as {"detail": str} or, for validation errors, {"detail": [{msg, loc}]}.
export function detailText(data) {
  if (!data) return "";
  const d = data.detail !== undefined ? data.detail : data.message;
  if (typeof d === "string") return d;
  if (Array.isArray(d)) {
    return d.map((x) => (x && x.msg ? (x.loc ? x.loc.join(".") + ": " : "") + x.msg : toJSON(x))).join("; ");
  }
  return d === undefined ? "" : toJSON(d);
}

export async function getJSON(url) {
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

export function finite(n) {
  return typeof n === "number" && Number.isFinite(n);
}
