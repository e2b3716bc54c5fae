// Live: the snapshot, then the event stream from its version.
//
// Every (re)connection fetches /api/snapshot, applies it, then opens /api/events?since=<its
// version>, so the stream carries exactly what came after the snapshot: no gap, no entry twice.
// (A backend that ignores `since` is fine too: deltas not newer than what we hold are dropped.)
// On a stream error we close it ourselves, rather than let the browser retry with a stale
// `since`, and start over from a fresh snapshot.

import { applyDelta, applySnapshot } from "./apply.js";
import { setConn, showMessage } from "./header.js";
import { RETRY_MS, model } from "./model.js";
import { getJSON } from "./util.js";

let es = null;
let generation = 0;         // bumps on every reconnect: callbacks of an older stream are ignored
let retryTimer = 0;
let lostShown = false;      // the "connection lost" message is up

function onDelta(d) {
  if (!d || typeof d !== "object") return;
  // the snapshot (or an earlier delta) already holds this one
  if (typeof d.version === "number" && typeof model.version === "number" && d.version <= model.version) return;
  applyDelta(d);
  // an ended run changes no more, and its server goes away with it: stop listening
  if (model.ended && es) {
    es.close();
    es = null;
    setConn("down");
  }
}

function lost(why) {
  setConn("down");
  // an ended run's server may go away: not worth an alarm then
  if (!model.ended && !lostShown) {
    showMessage(`connection to the backend lost (${why}); reconnecting…`, "error");
    lostShown = true;
  }
}

export async function connect() {
  clearTimeout(retryTimer);
  const gen = ++generation;
  if (es) {
    es.close();
    es = null;
  }
  let snap;
  try {
    snap = await getJSON("api/snapshot");
  } catch (e) {
    if (gen === generation) {
      lost(e.message);
      retryTimer = setTimeout(connect, RETRY_MS);
    }
    return;
  }
  if (gen !== generation) return;
  // an unchanged snapshot (a reconnect with nothing new) is not worth re-rendering
  if (snap.version === undefined || snap.version !== model.version || !window.monitor.ready) applySnapshot(snap);

  const since = typeof snap.version === "number" ? `?since=${snap.version}` : "";
  const source = new EventSource("api/events" + since);
  es = source;
  source.onmessage = (msg) => {
    if (gen !== generation) return;
    let d;
    try {
      d = JSON.parse(msg.data);
    } catch (e) {
      return; // not a delta
    }
    onDelta(d);
  };
  source.onopen = () => {
    if (gen !== generation) return;
    if (lostShown) showMessage("reconnected", "ok");
    lostShown = false;
    setConn("up");
  };
  source.onerror = () => {
    if (gen !== generation) return;
    source.close();
    if (model.ended) return; // nothing more to hear
    lost("the event stream broke");
    retryTimer = setTimeout(connect, 1000);
  };
}
