// The right column's lower panel (#panel-feed): photos & transcript (#panel-people), logs
// (#panel-logs) and the layouts shown (#panel-display), one tab at a time; a tab not shown
// counts what arrived meanwhile.

import { restoreScroll, trackScroll } from "./scroll.js";
import { $ } from "./util.js";

const TAB_KEY = "botstage.monitor.tab";

const TABS = ["people", "logs", "display"];
let activeTab = "people";
const unread = { people: 0, logs: 0, display: 0 };
const shownHooks = []; // called with a tab's name when it is selected

// The scrolling lists of a tab's pane, and whether each follows its end (vertical or not).
function paneLists(name) {
  return [...$("#panel-" + name).querySelectorAll(".panel-body, .photo-strip")];
}

function selectTab(name) {
  if (!TABS.includes(name)) name = "people";
  activeTab = name;
  for (const tab of TABS) {
    const on = tab === name;
    $("#tab-" + tab).setAttribute("aria-selected", on ? "true" : "false");
    $("#tab-" + tab).tabIndex = on ? 0 : -1;
    $("#panel-" + tab).hidden = !on;
  }
  for (const box of paneLists(name)) restoreScroll(box);
  unread[name] = 0;
  paintUnread(name, false);
  for (const hook of shownHooks) hook(name);
  try { localStorage.setItem(TAB_KEY, name); } catch (e) { /* storage off */ }
}

export function isShown(name) {
  return activeTab === name;
}

// A pane whose rows depend on where they are (the replay's later marks) hears when it is shown.
export function onTabShown(hook) {
  shownHooks.push(hook);
}

// New rows in a tab not shown: counted on it (red when a log warns or fails).
export function noteUnread(name, count, alarm) {
  if (!count || name === activeTab) return;
  unread[name] += count;
  paintUnread(name, alarm);
}

function paintUnread(name, alarm) {
  const badge = $("#tab-" + name + " .tab-count");
  const n = unread[name];
  badge.textContent = n ? (n > 99 ? "99+" : String(n)) : "";
  if (!n) badge.classList.remove("alarm");
  else if (alarm) badge.classList.add("alarm");
}

export function wireTabs() {
  for (const tab of TABS) for (const box of paneLists(tab)) trackScroll(box);
  for (const tab of TABS) $("#tab-" + tab).addEventListener("click", () => selectTab(tab));
  let saved = null;
  try { saved = localStorage.getItem(TAB_KEY); } catch (e) { /* storage off */ }
  selectTab(saved || "people");
}
