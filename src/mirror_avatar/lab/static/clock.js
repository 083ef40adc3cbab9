// The page's clock against the server's, and its pointer read at the device's rate (METHODS
// section 18). Every time is the page's own, in ms: performance.timeOrigin + performance.now().
// The page asks the server's time BURST times every BURST_MS once connected, then every
// REQUEST_MS (an NTP-style exchange: the server answers with its receipt and send times, the
// page reports when the answer came); the server estimates
// the offset and maps every sample's time onto its clock. The pointer is read from the coalesced
// pointer events (every one the device delivered since the last event dispatched), batched into
// one message per animation frame.
window.mirrorClock = (() => {
  "use strict";
  const BURST = 100;            // exchanges at the start, BURST_MS apart: a first estimate in 2 s
  const BURST_MS = 20;
  const REQUEST_MS = 100;       // then one exchange every 100 ms, waiting and playing
  const MAX_BATCH = 20;         // samples per message (the server's bound)
  const now = () => performance.timeOrigin + performance.now();
  let nextId = 0;
  let timer = null;
  let unsent = [];              // [page time (ms), position (units)] read since the last batch

  // Start exchanging with a new connection's `send`; its exchanges are numbered from 1.
  function start(send) {
    stop();
    nextId = 0;
    const request = () => {
      send({ type: "clock", id: ++nextId, t0: now() });
      if (nextId === BURST) { clearInterval(timer); timer = setInterval(request, REQUEST_MS); }
    };
    request();
    timer = setInterval(request, BURST_MS);
  }

  function stop() {
    if (timer !== null) clearInterval(timer);
    timer = null;
  }

  // Report when the server's answer arrived: the message event's own time stamp.
  function answered(message, event, send) {
    send({ type: "clocked", id: message.id, t3: performance.timeOrigin + event.timeStamp });
  }

  // Read a pointer event and those coalesced into it; return the newest position.
  function read(event, position) {
    const events = event.getCoalescedEvents ? event.getCoalescedEvents() : [];
    for (const e of events.length ? events : [event]) {
      unsent.push([performance.timeOrigin + e.timeStamp, position(e.clientX)]);
    }
    return unsent[unsent.length - 1][1];
  }

  // The messages of one animation frame: the samples read since the last, or the position `x`
  // now when the pointer did not move; `next()` numbers each (with the page's other positions).
  function batches(x, next) {
    const sent = now();
    const samples = unsent.length ? unsent : [[sent, x]];
    unsent = [];
    const messages = [];
    for (let i = 0; i < samples.length; i += MAX_BATCH) {
      const part = samples.slice(i, i + MAX_BATCH);
      messages.push({
        type: "pointer", seq: next(), sent,
        ago: part.map(([t]) => Math.max(0, Math.round((sent - t) * 10) / 10)),
        x: part.map(([, value]) => Number(value.toFixed(5))),
      });
    }
    return messages;
  }

  return { now, start, stop, answered, read, batches };
})();
