"""report.html: one self-contained page about a run.

Summary table, a timeline of states and skills (drawn as inline SVG, plus the table behind it),
the transcript when anyone spoke, the photos taken (thumbnails, with their metadata and upload
state) and the layouts the display showed, the map with the trajectory, and the pictures of the
mission's machine or tree. The map marks where the robot bumped into walls and people. Everything
is inline (no scripts, no external files), so the page opens anywhere, offline, and can be
attached to a bug report.
"""

from __future__ import annotations

import base64
import contextlib
import hashlib
import html
import json
import sqlite3
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from botstage.behaviors.render import GraphvizMissing, graphviz, to_dot, to_text
from botstage.missions.check import Checked, describe_part
from botstage.missions.transcript import read_transcript
from botstage.skills.display import LAYOUTS

MAX_ROWS = 2000
MAX_PHOTOS = 60
MAX_LANES = 60


@dataclass
class Span:
    lane: str  # machine path for states, node path for skills
    kind: str  # state or skill
    name: str
    start: float
    end: float
    outcome: str
    reason: str
    count: int = 1


def collapse(spans: list[Span], period: float) -> list[Span]:
    """Merge runs of instant, identical skill runs one tick apart (a condition checked every tick)."""
    merged: list[Span] = []
    group: dict[str, Span] = {}  # per lane, the open group of instant runs
    for span in spans:
        instant = span.kind == "skill" and span.start == span.end
        current = group.get(span.lane)
        if (
            instant
            and current is not None
            and (current.name, current.outcome, current.reason) == (span.name, span.outcome, span.reason)
            and span.start - current.end <= period + 1e-9
        ):
            current.end = span.end
            current.count += 1
            continue
        copy = Span(**vars(span))
        merged.append(copy)
        if instant:
            group[span.lane] = copy
        else:
            group.pop(span.lane, None)
    return merged


def timeline(trace_path: Path) -> list[Span]:
    spans: list[Span] = []
    open_states: dict[str, tuple[str, float]] = {}
    open_skills: dict[str, tuple[str, float]] = {}
    last_t = 0.0
    with trace_path.open(encoding="utf-8") as trace:
        for line in trace:
            event = json.loads(line)
            t = last_t = event["t"]
            kind = event["ev"]
            if kind == "transition":
                machine = event["machine"]
                if machine in open_states:
                    state, start = open_states.pop(machine)
                    trigger = event["trigger"]
                    outcome = trigger.split(" > ")[0].rsplit(":", 1)[-1] if ":" in trigger else trigger
                    spans.append(Span(machine, "state", state, start, t, outcome, event["reason"]))
                if event["dest"]:
                    open_states[machine] = (event["dest"], t)
            elif kind == "skill_start":
                open_skills[event["node"]] = (event["skill"], t)
            elif kind in ("skill_outcome", "skill_cancel"):
                started = open_skills.pop(event["node"], None)
                if started is not None:
                    outcome = event["outcome"] if kind == "skill_outcome" else "cancelled"
                    spans.append(Span(event["node"], "skill", started[0], started[1], t, outcome, event["reason"]))
    for machine, (state, start) in open_states.items():
        spans.append(Span(machine, "state", state, start, last_t, "active", ""))
    for node, (skill, start) in open_skills.items():
        spans.append(Span(node, "skill", skill, start, last_t, "running", ""))
    spans.sort(key=lambda s: (s.start, s.kind != "state", s.lane))
    return spans


_OUTCOME_COLOURS = {
    "success": "#5cb85c",
    "failure": "#d9534f",
    "cancelled": "#999999",
    "active": "#f0ad4e",
    "running": "#f0ad4e",
    "timeout": "#e67e22",
}


def _colour(outcome: str) -> str:
    return _OUTCOME_COLOURS.get(outcome, "#5bc0de")


def timeline_svg(spans: list[Span], duration: float) -> str:
    lanes: list[str] = []
    for span in spans:
        key = f"{span.kind}:{span.lane}"
        if key not in lanes:
            lanes.append(key)
    lanes.sort(key=lambda k: not k.startswith("state:"))
    shown = lanes[:MAX_LANES]
    index = {lane: i for i, lane in enumerate(shown)}
    label_w, width, lane_h = 260, 1100, 18
    scale = (width - label_w - 10) / max(duration, 1e-9)
    height = lane_h * len(shown) + 30
    parts = [
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" class="timeline" '
        f'role="img" aria-label="timeline of states and skills">'
    ]
    for lane, i in index.items():
        y = 20 + i * lane_h
        kind, _, name = lane.partition(":")
        label = (name if len(name) <= 40 else "…" + name[-39:]) + (" (states)" if kind == "state" else "")
        parts.append(f'<text x="4" y="{y + 13}" font-size="11">{html.escape(label)}</text>')
    for span in spans:
        lane = index.get(f"{span.kind}:{span.lane}")
        if lane is None:
            continue
        x = label_w + span.start * scale
        w = max((span.end - span.start) * scale, 1.5)
        y = 20 + lane * lane_h + 2
        tip = f"{span.name}: {span.start:g}–{span.end:g} s, {span.outcome}" + (
            f" ({span.reason})" if span.reason else ""
        )
        parts.append(
            f'<rect x="{x:.1f}" y="{y}" width="{w:.1f}" height="{lane_h - 4}" fill="{_colour(span.outcome)}">'
            f"<title>{html.escape(tip)}</title></rect>"
        )
        if span.kind == "state" and w > 40:
            parts.append(f'<text x="{x + 3:.1f}" y="{y + 11}" font-size="10">{html.escape(span.name)}</text>')
    for k in range(6):
        t = duration * k / 5
        x = label_w + t * scale
        parts.append(f'<text x="{x:.1f}" y="12" font-size="10">{t:.4g} s</text>')
    parts.append("</svg>")
    if len(lanes) > MAX_LANES:
        parts.append(f"<p>{len(lanes) - MAX_LANES} more lanes are in the table below.</p>")
    return "".join(parts)


def trajectory_map(folder: Path, checked: Checked) -> str:
    """The map with the robot's true path and its bumps (crosses: black for walls, orange for
    people), as an embedded PNG; empty for robot-less missions."""
    trajectory = folder / "trajectory.csv"
    mission = checked.mission
    if not trajectory.exists() or mission is None or mission.world is None:
        return ""
    import io

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    from botstage.robots.gridmap import FREE, OCCUPIED, load, map_path

    grid = checked.grid  # the run's, loaded when it was checked; read again for a report of a run folder
    if grid is None:
        found = map_path(mission.world, checked.path.parent)
        assert found is not None
        grid = load(found)
    points = np.loadtxt(trajectory, delimiter=",", skiprows=1, ndmin=2)
    shade = np.where(grid.data == OCCUPIED, 0.0, np.where(grid.data == FREE, 1.0, 0.75))
    ox, oy, _ = grid.origin
    extent = (ox, ox + grid.width * grid.resolution, oy, oy + grid.height * grid.resolution)
    figure, axes = plt.subplots(figsize=(8, 8 * grid.height / grid.width + 0.5))
    axes.imshow(shade, cmap="gray", origin="lower", extent=extent, vmin=0, vmax=1)
    for name, (x, y, _) in grid.places.items():
        axes.plot(x, y, "o", color="#5bc0de", markersize=3)
        axes.annotate(name, (x, y), fontsize=6, xytext=(3, 3), textcoords="offset points")
    axes.plot(points[:, 1], points[:, 2], "-", color="#d9534f", linewidth=1.5, label="trajectory")
    axes.plot(points[0, 1], points[0, 2], "o", color="#5cb85c", label="start")
    axes.plot(points[-1, 1], points[-1, 2], "s", color="#d9534f", label="end")
    bumps = read_bumps(folder / "bumps.csv")
    for what, colour in (("wall", "#000000"), ("person", "#f0ad4e")):
        spots = [(x, y) for _, x, y, kind in bumps if kind == what]
        if spots:
            xs, ys = zip(*spots, strict=True)
            label = f"bump into {'a wall' if what == 'wall' else 'a person'} ({len(spots)})"
            axes.plot(xs, ys, "X", color=colour, markeredgecolor="white", markersize=9, label=label)
    axes.set_xlabel("x (m)")
    axes.set_ylabel("y (m)")
    axes.legend(loc="upper right", fontsize=7)
    axes.set_title(f"{mission.world}: {len(points)} poses over {points[-1, 0]:g} s")
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=100, bbox_inches="tight")
    plt.close(figure)
    encoded = base64.b64encode(buffer.getvalue()).decode()
    image = f'<img class="map" alt="map with the trajectory" src="data:image/png;base64,{encoded}">'
    return f'<h2 id="map">Map and trajectory</h2>\n{image}\n{bumps_caption(bumps)}'


def read_bumps(path: Path) -> list[tuple[float, float, float, str]]:
    """The simulator's contact events (t, x, y, wall or person) from bumps.csv; none without it."""
    if not path.is_file():
        return []
    rows = []
    for line in path.read_text(encoding="utf-8").splitlines()[1:]:
        t, x, y, what = line.split(",")
        rows.append((float(t), float(x), float(y), what))
    return rows


def bumps_caption(bumps: list[tuple[float, float, float, str]]) -> str:
    """What the crosses on the map are, and when each bump happened."""
    if not bumps:
        return '<p class="bumps">No bumps.</p>'
    kinds = Counter(what for *_, what in bumps)
    where = "; ".join(f"{t:g} s at ({x:.2f}, {y:.2f}), {what}" for t, x, y, what in bumps[:20])
    more = f"; {len(bumps) - 20} more in bumps.csv" if len(bumps) > 20 else ""
    return (
        f'<p class="bumps">{len(bumps)} bump(s) marked ×: {kinds["wall"]} into walls, '
        f"{kinds['person']} into people ({html.escape(where)}{more}).</p>"
    )


def transcript_section(folder: Path) -> str:
    """Who said what, when (transcript.jsonl); empty for a run where nobody spoke."""
    lines = read_transcript(folder)
    if not lines:
        return ""
    e = html.escape
    rows = "".join(
        f'<tr class="{e(u.who)}"><td>{u.t:g}</td><td>{e(u.who)}</td><td>{e(u.text)}</td><td>{e(u.node)}</td></tr>'
        for u in lines[:MAX_ROWS]
    )
    more = f"<p>{len(lines) - MAX_ROWS} more lines are in transcript.jsonl.</p>" if len(lines) > MAX_ROWS else ""
    return (
        '<h2 id="transcript">Transcript</h2>\n'
        f'<table class="transcript"><tr><th>t s</th><th>who</th><th>said</th><th>where</th></tr>{rows}</table>{more}'
    )


def _upload_states(folder: Path) -> dict[str, str]:
    """Each recorded photo's state in the run's outbox (by SHA-256), read without changing it."""
    database = folder / "outbox" / "outbox.sqlite"
    if not database.is_file():
        return {}
    try:
        with contextlib.closing(sqlite3.connect(f"file:{database}?mode=ro", uri=True)) as db:
            return dict(db.execute("SELECT hash, state FROM photos").fetchall())
    except sqlite3.Error:
        return {}


def photos_section(folder: Path, subfolder: str = "photos", width: int = 200) -> str:
    """The photos the run took: a thumbnail each, when and where, and whether the gallery has it."""
    photos = sorted((folder / subfolder).glob("*.jpg"))
    if not photos:
        return ""
    import cv2  # loads only for a run that took photos
    import numpy as np

    states = _upload_states(folder)
    e = html.escape
    cells = []
    uploaded = 0
    for index, photo in enumerate(photos):
        data = photo.read_bytes()  # once a photo: its hash, and its thumbnail for the first ones
        state = states.get(hashlib.sha256(data).hexdigest(), "not queued")
        uploaded += state == "uploaded"
        if index >= MAX_PHOTOS:
            continue
        image = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
        if image is None:
            cells.append(f"<figure><figcaption>{e(photo.name)}: not a readable JPEG</figcaption></figure>")
            continue
        small = cv2.resize(image, (width, max(1, round(image.shape[0] * width / image.shape[1]))))
        thumbnail = base64.b64encode(cv2.imencode(".jpg", small, [cv2.IMWRITE_JPEG_QUALITY, 80])[1].tobytes()).decode()
        try:
            meta = json.loads(photo.with_suffix(".json").read_text(encoding="utf-8"))
        except (OSError, ValueError):
            meta = {}
        pose = meta.get("pose")
        where = f" at ({pose[0]:.1f}, {pose[1]:.1f})" if isinstance(pose, list) and len(pose) >= 2 else ""
        caption = f"{photo.name}: t {meta.get('t', '?')} s{where}, crowd {meta.get('crowd_id', '?')}; upload: {state}"
        cells.append(
            f'<figure><img alt="{e(photo.name)}" src="data:image/jpeg;base64,{thumbnail}">'
            f"<figcaption>{e(caption)}</figcaption></figure>"
        )
    more = f"<p>{len(photos) - MAX_PHOTOS} more photos are in {subfolder}/.</p>" if len(photos) > MAX_PHOTOS else ""
    return (
        f'<h2 id="photos">Photos</h2>\n<p>{len(photos)} taken, {uploaded} uploaded to the gallery.</p>'
        f'<div class="photos">{"".join(cells)}</div>{more}'
    )


def layouts(trace_path: Path, key: str = "layout") -> list[tuple[float, str]]:
    """When each layout was asked of the display: the writes of ``key`` (the display skill's)."""
    shown: list[tuple[float, str]] = []
    with trace_path.open(encoding="utf-8") as trace:
        for raw in trace:
            if '"bb_write"' not in raw:
                continue
            event = json.loads(raw)
            if event["ev"] == "bb_write" and event["key"] == key and event["new"] and event["new"] != event["old"]:
                shown.append((event["t"], str(event["new"])))
    return shown


def layouts_section(folder: Path) -> str:
    shown = layouts(folder / "trace.jsonl")
    if not shown:
        return ""
    e = html.escape
    rows = "".join(
        f"<tr><td>{t:g}</td><td>{e(name)}</td><td>{e(LAYOUTS.get(name, 'not a layout: not shown'))}</td></tr>"
        for t, name in shown[:MAX_ROWS]
    )
    counts = ", ".join(f"{name} ×{n}" for name, n in sorted(Counter(name for _, name in shown).items()))
    return (
        f'<h2 id="layouts">Layouts</h2>\n<p>What the display showed, and when ({e(counts)}).</p>'
        f'<table class="layouts"><tr><th>from t s</th><th>layout</th><th>meaning</th></tr>{rows}</table>'
    )


def pictures(checked: Checked) -> str:
    """The mission's picture, built with the skills and kinds it was checked with (a scenario's
    mocks, ones registered in code): the run's own, described before its first tick, if it has one."""
    item = checked.picture or describe_part(checked)
    try:
        svg = graphviz(to_dot(item), "svg").decode()
        svg = svg[svg.index("<svg") :]  # drop the XML prologue and doctype: inline in HTML
        return f'<div class="picture">{svg}</div>'
    except GraphvizMissing as exc:
        return f"<p>{html.escape(str(exc))}</p><pre>{html.escape(to_text(item))}</pre>"


_STYLE = """
body { font-family: system-ui, sans-serif; margin: 2em; color: #222; }
h1 { margin-bottom: 0.2em; } h2 { margin-top: 1.6em; border-bottom: 1px solid #ddd; }
table { border-collapse: collapse; font-size: 13px; }
td, th { border: 1px solid #ddd; padding: 3px 8px; text-align: left; vertical-align: top; }
th { background: #f5f5f5; }
.picture svg { max-width: 100%; height: auto; }
.outcome { font-weight: bold; }
.transcript tr.robot td { background: #eef6ff; }
.photos { display: flex; flex-wrap: wrap; gap: 10px; }
.photos figure { margin: 0; width: 200px; font-size: 12px; }
pre { background: #f8f8f8; padding: 1em; overflow-x: auto; }
"""


def write_report(folder: Path, checked: Checked, summary: dict[str, Any]) -> Path:
    mission = checked.mission
    assert mission is not None
    spans = collapse(timeline(folder / "trace.jsonl"), 1.0 / mission.rate_hz)
    e = html.escape
    rows = "".join(
        f"<tr><th>{e(k)}</th><td>{e(json.dumps(v) if not isinstance(v, str) else v)}</td></tr>"
        for k, v in summary.items()
        if k not in ("states_visited", "skill_outcomes")
    )
    outcomes = "".join(
        f"<tr><td>{e(skill)}</td><td>{e(outcome)}</td><td>{count}</td></tr>"
        for skill, counts in summary["skill_outcomes"].items()
        for outcome, count in counts.items()
    )
    timeline_rows = "".join(
        f"<tr><td>{s.kind}</td><td>{e(s.lane)}</td><td>{e(s.name)}{f' ×{s.count}' if s.count > 1 else ''}</td>"
        f"<td>{s.start:g}</td><td>{s.end:g}</td>"
        f'<td style="color:{_colour(s.outcome)}" class="outcome">{e(s.outcome)}</td><td>{e(s.reason)}</td></tr>'
        for s in spans[:MAX_ROWS]
    )
    more = f"<p>{len(spans) - MAX_ROWS} more rows are in trace.jsonl.</p>" if len(spans) > MAX_ROWS else ""
    page = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>{e(mission.name)}: botstage run report</title>
<style>{_STYLE}</style></head>
<body>
<h1>{e(mission.name)}</h1>
<p>{e(mission.description)}</p>
<p class="outcome">Outcome: {e(summary["outcome"])}{(" — " + e(summary["reason"])) if summary["reason"] else ""}</p>
<h2 id="summary">Summary</h2>
<table class="summary">{rows}</table>
<h2 id="timeline">Timeline</h2>
{timeline_svg(spans, max(summary["sim_time_s"], 1e-9))}
<h3>Skill outcomes</h3>
<table><tr><th>skill</th><th>outcome</th><th>count</th></tr>{outcomes}</table>
<h3>States and skills</h3>
<table class="timeline-table"><tr><th>kind</th><th>where</th><th>name</th><th>start s</th><th>end s</th>
<th>outcome</th><th>reason</th></tr>{timeline_rows}</table>{more}
{transcript_section(folder)}
{photos_section(folder)}
{layouts_section(folder)}
{trajectory_map(folder, checked)}
<h2 id="pictures">Mission</h2>
{pictures(checked)}
</body></html>
"""
    path = folder / "report.html"
    path.write_text(page, encoding="utf-8")
    return path
