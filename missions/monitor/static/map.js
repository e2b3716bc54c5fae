// The robot on the run's map (the map panel).
//
// `model.robot` is the snapshot's (then the deltas') "robot" object, replaced whole each time.
// /api/map and its PNG are asked for once the run shows a robot (a run without one has no map,
// and a 404 would be a console error for nothing); a 404 leaves the panel hidden. The canvas
// keeps the map's aspect inside #map-box; the grid, places and scale bar are drawn once per size
// into an offscreen canvas, and each frame redraws the robot over it.

import { schedule } from "./frame.js";
import { showMessage } from "./header.js";
import { RETRY_MS, dirty, model } from "./model.js";
import { $, clamp, finite } from "./util.js";

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
export function renderRobot() {
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

export function wireMap() {
  if (typeof ResizeObserver === "function") {
    new ResizeObserver(() => fitMap()).observe($("#map-box"));
  } else {
    window.addEventListener("resize", fitMap);
  }
}
