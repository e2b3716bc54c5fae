// The PeopleBot's tablet: shows the layout the robot's Display interface shows now.
//
// Polls GET /api/display every 250 ms: {layout, content, count, shown}. A layout is drawn by
// cloning its <template id="tpl-NAME"> from display.html; the DOM changes only when the layout
// or its content does, so the CSS animations run undisturbed between polls.

"use strict";

(() => {
  const POLL_MS = 250;
  const OFFLINE_AFTER = 3; // failed polls in a row before the red dot shows

  const root = document.getElementById("layout");
  const stage = document.getElementById("stage");
  const caption = document.getElementById("caption");
  const shownList = document.getElementById("shown");
  const offline = document.getElementById("offline");

  let current = null;     // "layout|content" last drawn
  let shownSig = null;    // what #shown was last built from
  let failures = 0;

  function drawLayout(layout, content) {
    stage.textContent = "";
    const tpl = layout ? document.getElementById("tpl-" + layout) : null;
    if (tpl) {
      stage.appendChild(tpl.content.cloneNode(true));
    } else if (layout) {
      // a layout this page does not know: its name, plainly
      const p = document.createElement("p");
      p.className = "unknown";
      p.textContent = layout;
      stage.appendChild(p);
    } else {
      // nothing shown yet: the calm face, dimmed
      stage.appendChild(document.getElementById("tpl-Layout_0").content.cloneNode(true));
      stage.firstElementChild.classList.add("waiting");
    }
    // restart the entrance animation
    stage.style.animation = "none";
    void stage.offsetWidth;
    stage.style.animation = "";
    drawCaption(content);
  }

  // Content fields as caption text: a title larger, the layout's meaning smaller, the rest plain.
  function drawCaption(content) {
    caption.textContent = "";
    if (!content || typeof content !== "object") return;
    const order = Object.keys(content).sort((a, b) => rank(a) - rank(b));
    for (const key of order) {
      const value = content[key];
      if (value === null || value === undefined || value === "") continue;
      const div = document.createElement("div");
      div.className = "c-" + key.replace(/[^a-z0-9_-]/gi, "");
      div.textContent = typeof value === "string" ? value : JSON.stringify(value);
      caption.appendChild(div);
    }
  }

  function rank(key) {
    return key === "title" ? 0 : key === "meaning" ? 2 : 1;
  }

  function drawShown(shown, count) {
    const items = Array.isArray(shown) ? shown : [];
    const last = items.length ? items[items.length - 1] : null;
    const sig = `${count}|${items.length}|${last ? last.tick + ":" + last.layout : ""}`;
    if (sig === shownSig) return;
    shownSig = sig;
    const frag = document.createDocumentFragment();
    for (const item of items) {
      const li = document.createElement("li");
      li.textContent = item && item.layout != null ? item.layout : "";
      if (item && item.tick !== undefined) li.dataset.tick = item.tick;
      frag.appendChild(li);
    }
    shownList.textContent = "";
    shownList.appendChild(frag);
  }

  function apply(d) {
    const layout = d.layout == null ? "" : String(d.layout);
    const content = d.content && typeof d.content === "object" ? d.content : {};
    const key = layout + "|" + JSON.stringify(content);
    if (key !== current) {
      current = key;
      drawLayout(layout, content);
      root.dataset.layout = layout;
      document.title = layout ? `PeopleBot · ${layout}` : "PeopleBot display";
    }
    const count = Number.isFinite(d.count) ? d.count : 0;
    if (root.dataset.count !== String(count)) root.dataset.count = String(count);
    drawShown(d.shown, count);
  }

  async function poll() {
    try {
      const r = await fetch("api/display", { cache: "no-store" });
      if (!r.ok) throw new Error("HTTP " + r.status);
      apply(await r.json());
      failures = 0;
    } catch (e) {
      failures++;
    }
    offline.hidden = failures < OFFLINE_AFTER;
    // chained rather than setInterval: a slow answer never stacks requests
    setTimeout(poll, POLL_MS);
  }

  // A tap asks for full screen (tablets need a user gesture for it).
  document.addEventListener("click", () => {
    const el = document.documentElement;
    if (!document.fullscreenElement && el.requestFullscreen) el.requestFullscreen().catch(() => {});
  });

  drawLayout("", {});
  poll();
})();
