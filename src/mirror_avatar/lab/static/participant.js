// A participant's page: their own point follows the pointer (mouse, touch) or the arrow keys;
// the points of the players they are coupled to come from the server's clock, one frame per tick,
// but for an avatar the page steps itself (runs = "browser"): built from the server's message
// (avatars.js), stepped on each frame from the person's position as the page shows it, its state
// sent with that position (mirror_avatar.lab.running.page_avatar). A frame is drawn on the first
// animation frame after it arrives, or after its `due` time (an equalised view); the page reports
// each frame it drew and the animation frame's time (mirror_avatar.lab.running.views).
(() => {
  "use strict";
  const RANGE = 0.5;            // positions lie in [-RANGE, RANGE] (playing range units)
  const KEY_SPEED = 0.6;        // units per second while an arrow key is held
  const LATE_FRAME_MS = 50;     // an animation frame drawn later than this counts as late
  const ENDED_CODES = new Set([4001, 4002, 4003, 4004, 1008]);
  const SHOWN_BATCH = 10;       // frames drawn reported per message
  const canvas = document.getElementById("field");
  const ctx = canvas.getContext("2d");
  const ui = {
    who: document.getElementById("who"),
    trial: document.getElementById("trial"),
    task: document.getElementById("task"),
    overlay: document.getElementById("overlay"),
    message: document.getElementById("message"),
    bar: document.getElementById("progress-bar"),
    notice: document.getElementById("notice"),
  };
  const key = location.pathname.split("/").pop();
  const me = { x: 0, seq: 0, keys: new Set(), lastFrame: null, lateFrames: 0 };
  let socket = null;
  let welcome = null;
  let others = new Map();      // player index -> latest position from the server
  let pageAvatar = null;       // the avatar this page steps: index, player, tick, seen, state
  let pending = [];            // frames received, not drawn yet, oldest first
  let shown = { k: [], t: [] };  // frames drawn and when (ms, the page's clock), not reported yet
  let ended = false;
  let refused = false;         // screened out: the page shows why and the refusal code, only
  let lastNumbers = [];        // the last trial's numbers, each with its words
  window.mirrorLab = { get welcome() { return welcome; }, get others() { return others; }, me };

  function resize() {
    const ratio = window.devicePixelRatio || 1;
    canvas.width = canvas.clientWidth * ratio;
    canvas.height = canvas.clientHeight * ratio;
    sayWindow();
  }

  // The window's size (CSS pixels), as the server screens it at entry.
  function sayWindow() {
    send({ type: "window", width: Math.max(1, window.innerWidth), height: Math.max(1, window.innerHeight) });
  }

  function toPixels(x) { return ((x + RANGE) / (2 * RANGE)) * canvas.width * 0.9 + canvas.width * 0.05; }
  function fromClient(clientX) {
    const rect = canvas.getBoundingClientRect();
    const fraction = ((clientX - rect.left) / rect.width - 0.05) / 0.9;
    return Math.max(-RANGE, Math.min(RANGE, (fraction - 0.5) * 2 * RANGE));
  }

  // Show a message: one text, or lines where a [number, words] pair puts the words in small
  // type under its number.
  function say(text) {
    const lines = Array.isArray(text) ? text : text ? [text] : [];
    ui.message.replaceChildren(...lines.flatMap((line, i) => {
      const nodes = i ? ["\n"] : [];
      if (!Array.isArray(line)) return [...nodes, line];
      const words = Object.assign(document.createElement("small"), { className: "words", textContent: line[1] });
      return [...nodes, line[0], "\n", words];
    }));
    ui.overlay.hidden = lines.length === 0;
  }

  function send(message) {
    if (socket && socket.readyState === WebSocket.OPEN) socket.send(JSON.stringify(message));
  }

  function draw() {
    const { width, height } = canvas;
    ctx.clearRect(0, 0, width, height);
    ctx.strokeStyle = "#c5ccd8";
    ctx.lineWidth = Math.max(2, height * 0.01);
    ctx.beginPath();
    ctx.moveTo(toPixels(-RANGE), height / 2);
    ctx.lineTo(toPixels(RANGE), height / 2);
    ctx.stroke();
    if (!welcome || ended) return;  // after the session: the line alone
    const radius = Math.max(10, Math.min(width, height) * 0.04);
    welcome.visible.forEach((player, i) => {
      const own = i === 0;
      const x = own ? me.x : others.get(player.index);
      if (x === undefined || x === null) return;
      const y = height / 2 - (own ? 0 : radius * 2.2 * i);  // the others stacked above the line
      ctx.fillStyle = player.colour;
      ctx.globalAlpha = own ? 1 : 0.85;
      ctx.beginPath();
      ctx.arc(toPixels(x), y, own ? radius * 1.2 : radius, 0, 2 * Math.PI);
      ctx.fill();
      ctx.globalAlpha = 1;
      ctx.font = `${Math.round(radius)}px system-ui, sans-serif`;
      ctx.textAlign = "center";
      ctx.fillText(own ? "you" : player.label, toPixels(x), own ? y + radius * 2.6 : y - radius * 1.5);
    });
  }

  // Take the frames due by page time `t` (ms): the newest one's partners are drawn now.
  function takeFrames(t) {
    let newest = null;
    while (pending.length && !(pending[0].due > t)) newest = pending.shift();
    if (newest === null) return;
    welcome.visible.forEach((player, i) => {
      if (i > 0 && !(pageAvatar && player.index === pageAvatar.index)) others.set(player.index, newest.x[i]);
    });
    if (!newest.x.slice(1).some((x) => x !== null)) return;
    shown.k.push(newest.k);
    shown.t.push(Math.round(t * 10) / 10);
    if (shown.k.length >= SHOWN_BATCH) reportShown();
  }

  function reportShown() {
    if (shown.k.length) send({ type: "shown", k: shown.k, t: shown.t });
    shown = { k: [], t: [] };
  }

  function animate(now) {
    if (welcome && !ended) takeFrames(performance.timeOrigin + now);
    if (me.lastFrame !== null) {
      const dt = (now - me.lastFrame) / 1000;
      if (dt * 1000 > LATE_FRAME_MS) me.lateFrames += 1;
      const direction = (me.keys.has("right") ? 1 : 0) - (me.keys.has("left") ? 1 : 0);
      if (direction) me.x = Math.max(-RANGE, Math.min(RANGE, me.x + direction * KEY_SPEED * dt));
    }
    me.lastFrame = now;
    if (welcome && welcome.device === "pointer") mirrorClock.batches(me.x, () => me.seq++).forEach(send);
    draw();
    requestAnimationFrame(animate);
  }

  // What a player is asked to do in each role, in words a participant understands.
  const TASK_WORDS = {
    solo: "Move your point freely, on your own.",
    joint: "Move together with your partner: neither of you leads.",
    leader: "You lead: move freely, your partner follows you.",
    follower: "Follow your partner as closely as you can.",
    group: "Move in step with the others.",
    group_leader: "You lead: move freely, the others follow you.",
  };

  // Each number of the end screen with what it means in plain words.
  const METRIC_WORDS = {
    phase_locking: ["Coordination",
      "how steadily your timing kept pace with the others': 0 no relation, 1 always in step"],
    rmse: ["Distance",
      "how far apart your points were on average, as a share of the line: 0 always together"],
    group_synchronisation: ["Group synchronisation",
      "how much the whole group moved in step: 0 not at all, 1 perfectly"],
    synchronisation: ["Your synchronisation",
      "how much you moved in step with the group: 0 not at all, 1 perfectly"],
  };

  function metricLines(metrics) {
    return Object.entries(metrics || {})
      .filter(([name, value]) => METRIC_WORDS[name] && value !== null)
      .map(([name, value]) => [`${METRIC_WORDS[name][0]}: ${Number(value).toFixed(2)}`, METRIC_WORDS[name][1]]);
  }

  // Who led and how long the players moved together smoothly, in plain words.
  const LED_WORDS = {
    you: "You led.",
    partner: "Your partner led.",
    none: "Neither of you led for most of the trial.",
  };

  function measureLines(metrics) {
    const lines = [];
    const led = LED_WORDS[(metrics || {}).led_by];
    if (led) lines.push([led, "the one whose movements the other followed, in most stretches of the trial"]);
    if (typeof (metrics || {}).co_confidence_rate === "number") {
      lines.push([`Moving together smoothly: ${Math.round(100 * metrics.co_confidence_rate)} % of the time`,
        "stretches of over 2 s in which you both moved smoothly and together"]);
    }
    return lines;
  }

  // A code to copy and a link back to the panel, as the protocol gives them (either may be null).
  function showEnding(ending, words) {
    const box = document.getElementById("ending");
    box.replaceChildren();
    if (!ending || (!ending.code && !ending.url)) { box.hidden = true; return; }
    if (ending.code) {
      const code = Object.assign(document.createElement("code"), { id: "ending-code", textContent: ending.code });
      box.append(Object.assign(document.createElement("p"), { textContent: words.code }), code);
    }
    if (ending.url) {
      const link = Object.assign(document.createElement("a"), { id: "ending-link", href: ending.url, textContent: words.link });
      box.append(link);
    }
    box.hidden = false;
  }

  function finish(state) {
    ended = true;
    if (refused) return;
    ui.task.textContent = "";
    const numbers = lastNumbers.length ? ["Your last trial:", ...lastNumbers] : [];
    say(["The session has ended. Thank you!", ...numbers]);
    if (state === "finished" && welcome) {
      showEnding(welcome.completion, { code: "Your completion code:", link: "Return to the study's site to complete" });
    }
  }

  // One line the server tells the participant (their tab came back during a trial, or their page
  // drew fewer frames or its window was smaller than the study needs), kept until the next trial
  // starts.
  function notify(text) {
    ui.notice.textContent = text;
    ui.notice.hidden = !text;
  }

  function refuse(message) {
    refused = ended = true;
    ui.task.textContent = ui.who.textContent = "";
    canvas.hidden = true;  // no playing field behind the reason and the code
    say(message.message);
    showEnding(message, { code: "Your code:", link: "Return to the study's site" });
  }

  // Build the avatar the server sends, at its tick 0, and report that tick: the page is ready.
  async function buildAvatar(message) {
    const { makePlayer } = await import("/static/avatars.js");
    const player = makePlayer(message.player);
    pageAvatar = { index: message.index, player, tick: 0, seen: null, state: player.reset() };
    others.set(message.index, pageAvatar.state[0]);
    reportAvatar();
  }

  function reportAvatar() {
    const [x, v] = pageAvatar.state;
    send({ type: "position", seq: me.seq++, x: me.x, avatar: { tick: pageAvatar.tick, x, v } });
  }

  // Step the avatar to tick k + 1 (each tick a late frame skipped too) from the person's position
  // as the page shows it now, its velocity (x_k - x_{k-1}) / T as the server's, reporting each.
  function stepAvatar(k) {
    const avatar = pageAvatar;
    while (avatar.tick < k + 1) {
      const seen = me.x;
      const velocity = avatar.seen === null ? 0 : (seen - avatar.seen) / avatar.player.period;
      avatar.seen = seen;
      avatar.state = avatar.player.step({ positions: [seen], velocities: [velocity] });
      avatar.tick += 1;
      reportAvatar();
    }
    others.set(avatar.index, avatar.state[0]);
  }

  function onMessage(event) {
    const message = JSON.parse(event.data);
    switch (message.type) {
      case "clock": mirrorClock.answered(message, event, send); break;
      case "welcome": {
        welcome = message;
        const colour = message.visible[0].colour;
        ui.who.innerHTML = "";
        const dot = document.createElement("span");
        dot.className = "dot";
        dot.style.background = colour;
        ui.who.append(dot, ` You are ${message.label}`);
        ui.task.textContent = TASK_WORDS[message.role] || "";
        if (message.role === "waiting") say("Not your turn: please wait while the others play.");
        else if (message.state === "waiting") say("Please wait: the researcher will start soon.");
        else say(message.state === "running" ? "" : "Please wait.");
        break;
      }
      case "ping": send({ type: "pong", id: message.id, late_frames: me.lateFrames }); break;
      case "countdown":
        ui.trial.textContent = `Trial ${message.trial} of ${welcome ? welcome.trials : "?"}`;
        others = new Map();
        pending = [];
        shown = { k: [], t: [] };
        pageAvatar = null;
        say(String(message.remaining));
        break;
      case "avatar": buildAvatar(message); break;
      case "go": say(""); notify(""); ui.bar.style.width = "0%"; break;
      case "frame":
        pending.push(message);
        if (pageAvatar) stepAvatar(message.k);
        ui.bar.style.width = `${(100 * message.progress).toFixed(1)}%`;
        break;
      case "end": {
        pageAvatar = null;
        lastNumbers = [...metricLines(message.metrics), ...measureLines(message.metrics)];
        const next = message.next_in === null ? "Please wait." : `Next trial in ${Math.round(message.next_in)} s.`;
        say([`Trial ${message.trial} done.`, ...lastNumbers, next]);
        break;
      }
      case "questions": ask(message); break;
      case "refused": refuse(message); break;
      case "notice": notify(message.message); break;
      case "state":
        if (message.state === "finished" || message.state === "aborted") finish(message.state);
        else say(message.message);
        break;
      case "error": console.warn(message.message); break;
      default: break;
    }
  }

  function ask(message) {
    const form = document.getElementById("questions");
    form.innerHTML = "";
    const open = new Set(message.questions.map((q) => q.id));
    const answered = (id) => {
      open.delete(id);
      if (open.size === 0) { form.hidden = true; document.body.classList.remove("asking"); say("Thank you. Please wait."); }
    };
    const answer = (q, value, button) => {
      send({ type: "answer", trial: message.trial, question: q.id, value });
      if (button) {
        button.parentElement.querySelectorAll("button").forEach((b) => b.classList.remove("chosen"));
        button.classList.add("chosen");
      }
      answered(q.id);
    };
    message.questions.forEach((q) => {
      const set = document.createElement("fieldset");
      set.dataset.question = q.id;
      const legend = document.createElement("legend");
      legend.textContent = q.text;
      const row = document.createElement("div");
      row.className = "choices";
      set.append(legend, row);
      const button = (text, value) => {
        const b = Object.assign(document.createElement("button"), { type: "button", textContent: text });
        b.dataset.value = String(value);
        b.addEventListener("click", () => answer(q, value, b));
        row.append(b);
      };
      if (q.kind === "choice") q.options.forEach((option) => button(option, option));
      if (q.kind === "likert") {  // the points in one row, the anchors under its two ends
        row.classList.add("likert");
        for (let point = 1; point <= q.points; point += 1) button(String(point), point);
        const anchors = Object.assign(document.createElement("div"), { className: "anchors" });
        q.anchors.forEach((text) => anchors.append(Object.assign(document.createElement("span"), { textContent: text || "" })));
        row.style.maxWidth = anchors.style.maxWidth = `${q.points * 70}px`;
        if (q.anchors.some(Boolean)) set.append(anchors);
      }
      if (q.kind === "text") {
        const text = Object.assign(document.createElement("textarea"), { maxLength: q.max_chars });
        const sendText = Object.assign(document.createElement("button"), { type: "button", textContent: "Send" });
        sendText.addEventListener("click", () => { answer(q, text.value, null); sendText.disabled = true; text.disabled = true; });
        row.append(text, sendText);
      }
      form.append(set);
    });
    say("");
    form.hidden = false;
    document.body.classList.add("asking");
  }

  function connect() {
    const scheme = location.protocol === "https:" ? "wss" : "ws";
    socket = new WebSocket(`${scheme}://${location.host}/ws/join/${key}`);
    me.seq = 0;
    socket.addEventListener("open", () => { sayWindow(); mirrorClock.start(send); });
    socket.addEventListener("message", onMessage);
    socket.addEventListener("close", (event) => {
      mirrorClock.stop();
      if (event.code === 4002) {
        say("This link was opened on another page.");
        ended = true;
      } else if (ended || ENDED_CODES.has(event.code)) finish();
      if (ended) return;
      say("Connection lost: reconnecting…");
      setTimeout(connect, 1000);
    });
  }

  // The pages before the game, as the protocol gives them: its instructions, and its consent,
  // which the participant answers; the game joins only once they agree, and one who does not is
  // shown the refusal (mirror_avatar.lab.running.consent).
  async function introduce() {
    let intro = {};
    try {
      const answer = await fetch(`/join/${key}/intro`, { cache: "no-store" });
      if (answer.ok) intro = await answer.json();
    } catch (error) {
      intro = {};
    }
    if (intro.refused) { refuse(intro.refused); return; }
    if (intro.consented || (!intro.consent && !intro.instructions)) { connect(); return; }
    const page = document.getElementById("intro");
    const section = (id, title, text) => {
      if (!text) return;
      const part = Object.assign(document.createElement("section"), { id });
      part.append(Object.assign(document.createElement("h2"), { textContent: title }),
        Object.assign(document.createElement("p"), { textContent: text }));
      page.append(part);
    };
    section("instructions", "Instructions", intro.instructions);
    section("consent", "Consent", intro.consent);
    const row = Object.assign(document.createElement("div"), { className: "choices" });
    const choice = (id, text, agree) => {
      const b = Object.assign(document.createElement("button"), { id, type: "button", textContent: text });
      b.addEventListener("click", () => answerIntro(agree));
      row.append(b);
    };
    if (intro.consent) {
      choice("agree", "I agree to take part", true);
      choice("decline", "I do not agree", false);
    } else choice("continue", "Continue", true);
    page.append(row);
    say("");
    page.hidden = false;
  }

  async function answerIntro(agree) {
    const page = document.getElementById("intro");
    page.querySelectorAll("button").forEach((b) => { b.disabled = true; });
    if (!page.querySelector("#consent")) { page.hidden = true; connect(); return; }
    const answer = await fetch(`/join/${key}/consent`, {
      method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify({ agree }),
    });
    const result = answer.ok ? await answer.json() : {};
    page.hidden = true;
    if (result.refused) refuse(result.refused);
    else connect();
  }

  const KEYS = { ArrowLeft: "left", ArrowRight: "right", a: "left", d: "right" };
  window.addEventListener("resize", resize);
  canvas.addEventListener("pointermove", (event) => { me.x = mirrorClock.read(event, fromClient); });
  canvas.addEventListener("pointerdown", (event) => { me.x = mirrorClock.read(event, fromClient); });
  window.addEventListener("keydown", (event) => { if (KEYS[event.key]) { me.keys.add(KEYS[event.key]); event.preventDefault(); } });
  window.addEventListener("keyup", (event) => me.keys.delete(KEYS[event.key]));
  // The tab hidden or shown, the window blurred or focused, each with the page's own time: the
  // server records them (mirror_avatar.realtime.interruptions).
  const focusChange = (name) => send({ type: "focus", event: name, t: mirrorClock.now() });
  document.addEventListener("visibilitychange", () => focusChange(document.visibilityState === "hidden" ? "hidden" : "visible"));
  window.addEventListener("blur", () => { me.keys.clear(); focusChange("blur"); });
  window.addEventListener("focus", () => focusChange("focus"));
  resize();
  introduce();
  requestAnimationFrame(animate);
})();
