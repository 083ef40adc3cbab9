// Mirror game page: reads the pointer (mouse, touch or keyboard), sends its latest position once per
// animation frame while a trial runs, draws both dots, and shows the trial's results.
// Positions are in normalised units: the track spans [-0.5, 0.5].
"use strict";

(() => {
  const KEY_SPEED = 0.8; // units/s while an arrow key is held
  const $ = (id) => document.getElementById(id);
  const ui = {
    status: $("status"), form: $("setup"), participant: $("participant"), mode: $("mode"),
    duration: $("duration"), start: $("start"), stop: $("stop"), track: $("track"),
    person: $("person-dot"), avatar: $("avatar-dot"), countdown: $("countdown"),
    progress: $("progress"), results: $("results"), metrics: $("metrics"), plot: $("plot"),
    positions: $("positions"), phase: $("phase"), phaseFigure: $("phase-figure"),
    saved: $("saved"), avatarLegend: $("avatar-legend"), build: $("build"),
    buildHint: $("build-hint"),
    verdict: $("avatar-verdict"), verdictText: $("verdict-text"), cardLink: $("card-link"),
  };
  const game = {
    phase: "connecting", // connecting | idle | asleep | countdown | running | building | closed
    x: 0, avatarX: null, seq: 0, sent: new Map(), rtt: null, keys: new Set(), lastFrame: null,
    summary: null, personalAvatar: null, cardUrl: null,
  };
  window.mirrorGame = game; // inspected by the browser tests

  const token = new URLSearchParams(location.search).get("token");
  const wsUrl = new URL("ws", location.href);
  wsUrl.protocol = location.protocol === "https:" ? "wss:" : "ws:";
  wsUrl.search = token ? `?token=${encodeURIComponent(token)}` : "";
  const CLOSE_IDLE = 4000; // the server closed an idle connection: reconnect on Start
  let socket = null;
  let pendingStart = null; // a start request waiting for the reconnection's "ready"

  const clip = (x) => Math.max(-0.5, Math.min(0.5, x));
  const toPixels = (x) => (x + 0.5) * ui.track.clientWidth;
  const setStatus = (text) => { ui.status.textContent = text; };

  function pointerTo(clientX) {
    const rect = ui.track.getBoundingClientRect();
    game.x = clip((clientX - rect.left) / rect.width - 0.5);
  }

  function send(message) {
    if (socket && socket.readyState === WebSocket.OPEN) socket.send(JSON.stringify(message));
  }

  function active() { return game.phase === "countdown" || game.phase === "running"; }

  function frame(now) {
    if (game.lastFrame !== null && game.keys.size) {
      const dt = Math.min(0.1, (now - game.lastFrame) / 1000);
      const direction = (game.keys.has("right") ? 1 : 0) - (game.keys.has("left") ? 1 : 0);
      game.x = clip(game.x + direction * KEY_SPEED * dt);
    }
    game.lastFrame = now;
    if (active()) {
      game.seq += 1;
      game.sent.set(game.seq, performance.now());
      send({ type: "position", seq: game.seq, x: game.x, rtt: game.rtt });
    }
    ui.person.style.left = `${toPixels(game.x)}px`;
    if (game.avatarX !== null) ui.avatar.style.left = `${toPixels(game.avatarX)}px`;
    requestAnimationFrame(frame);
  }

  function onAvatar(message) {
    const sentAt = game.sent.get(message.seq);
    if (sentAt !== undefined) {
      game.rtt = Math.round((performance.now() - sentAt) * 100) / 100;
      for (const seq of game.sent.keys()) { if (seq <= message.seq) game.sent.delete(seq); }
    }
    if (message.x !== null) {
      game.avatarX = message.x;
      ui.avatar.hidden = false;
    }
    ui.progress.style.width = `${(100 * message.progress).toFixed(1)}%`;
  }

  function setPhase(phase) {
    game.phase = phase;
    const busy = active() || phase === "building";
    ui.start.disabled = busy || phase === "connecting" || phase === "closed";
    ui.build.disabled = busy || phase !== "idle";
    ui.stop.disabled = !active();
    for (const input of [ui.participant, ui.mode, ui.duration]) input.disabled = busy;
  }

  function enableModes(modes) {
    for (const option of ui.mode.options) option.disabled = !modes.includes(option.value);
    if (ui.mode.selectedOptions[0].disabled) ui.mode.value = "solo";
  }

  function row(label, value) {
    const tr = document.createElement("tr");
    const th = document.createElement("th");
    const td = document.createElement("td");
    th.textContent = label;
    td.textContent = value;
    tr.append(th, td);
    return tr;
  }

  const fixed = (value, digits, unit = "") =>
    value === undefined || value === null ? "–" : `${value.toFixed(digits)}${unit}`;

  function showResults(summary) {
    const m = summary.metrics || {};
    const rtt = summary.round_trip_ms || {};
    const body = ui.metrics.tBodies[0];
    body.replaceChildren(
      row("Mode", summary.mode.replace("_", " ")),
      row("Samples", `${summary.n_samples} at ${summary.sampling_rate_hz.toFixed(1)} Hz`),
      row("Your mean speed", fixed(m.person_speed, 3, " units/s")),
    );
    if (m.rmse !== undefined) {
      body.append(
        row("Avatar mean speed", fixed(m.avatar_speed, 3, " units/s")),
        row("RMSE", fixed(m.rmse, 3, " units")),
        row("CV (phase locking)", fixed(m.phase_locking, 3)),
        row("Relative phase (you − avatar)", fixed(m.mean_relative_phase, 3, " rad")),
        row("EMD between velocity profiles", fixed(m.emd_players, 4)),
      );
      if (m.emd_target_1 !== undefined) {
        body.append(row("EMD avatar to its target's profile", fixed(m.emd_target_1, 4)));
      }
    }
    body.append(row("Round trip (median)", fixed(rtt.median, 1, " ms")));
    const complete = summary.complete ? "complete" : `incomplete (${summary.end_reason})`;
    ui.saved.textContent = `Saved ${summary.files.person}` +
      (summary.files.session ? ` and ${summary.files.session}` : "") + ` – ${complete}`;
    ui.saved.classList.toggle("incomplete", !summary.complete);
    ui.results.hidden = false;
    const withAvatar = m.rmse !== undefined;
    document.querySelectorAll(".avatar-key").forEach((key) => { key.hidden = !withAvatar; });
    drawDistributions(m);
    drawTraces(summary.traces);
  }

  const PERSON_COLOUR = "#2563eb";
  const AVATAR_COLOUR = "#ea7a12";
  const PAD = { left: 34, right: 12, top: 10, bottom: 24 };

  // A canvas sized to its box at the screen's pixel density, cleared.
  function prepare(canvas) {
    const scale = window.devicePixelRatio || 1;
    const width = canvas.clientWidth, height = canvas.clientHeight;
    canvas.width = width * scale;
    canvas.height = height * scale;
    const ctx = canvas.getContext("2d");
    ctx.scale(scale, scale);
    ctx.clearRect(0, 0, width, height);
    return { ctx, width, height };
  }

  // Axes of a plot: a baseline with x ticks, y tick labels; returns the data-to-pixel maps.
  function axes({ ctx, width, height }, [x0, x1], [y0, y1], xTicks, yTicks) {
    const px = (x) => PAD.left + ((x - x0) / (x1 - x0)) * (width - PAD.left - PAD.right);
    const py = (y) =>
      height - PAD.bottom - ((y - y0) / (y1 - y0)) * (height - PAD.top - PAD.bottom);
    ctx.strokeStyle = "#d8dde6";
    ctx.fillStyle = "#667085";
    ctx.font = "11px system-ui, sans-serif";
    ctx.beginPath();
    ctx.moveTo(PAD.left, height - PAD.bottom);
    ctx.lineTo(width - PAD.right, height - PAD.bottom);
    ctx.stroke();
    ctx.textAlign = "center";
    for (const x of xTicks) ctx.fillText(String(x), px(x), height - 8);
    ctx.textAlign = "right";
    for (const y of yTicks) ctx.fillText(String(y), PAD.left - 6, py(y) + 4);
    return { px, py };
  }

  // At most about six round ticks from 0 to xmax.
  function ticksTo(xmax) {
    const step = [1, 2, 5, 10, 20, 30, 60, 120].find((s) => xmax / s <= 6) || 300;
    const ticks = [];
    for (let x = 0; x <= xmax + 1e-9; x += step) ticks.push(x);
    return ticks;
  }

  function stroke(ctx, xs, ys, px, py, colour) {
    ctx.beginPath();
    xs.forEach((x, i) => (i ? ctx.lineTo(px(x), py(ys[i])) : ctx.moveTo(px(x), py(ys[i]))));
    ctx.strokeStyle = colour;
    ctx.lineWidth = 1.5;
    ctx.stroke();
  }

  function drawDistributions(m) {
    const plot = prepare(ui.plot);
    if (!m.velocity_bins) return;
    // four neighbouring bins merged: a short trial's 200-bin histogram is too ragged to read
    const merge = (values, mean) => values.reduce((out, value, i) => {
      out[Math.floor(i / 4)] = (out[Math.floor(i / 4)] || 0) + (mean ? value / 4 : value);
      return out;
    }, []);
    const bins = merge(m.velocity_bins, true);
    const series = [[m.person_ims, PERSON_COLOUR], [m.avatar_ims, AVATAR_COLOUR]]
      .filter((s) => s[0])
      .map(([p, colour]) => [merge(p, false), colour]);
    const vmax = 2;
    const peak = Math.max(...series.flatMap(([p]) => p)) || 1;
    const { px, py } = axes(plot, [-vmax, vmax], [0, peak], [-2, -1, 0, 1, 2], []);
    const ctx = plot.ctx;
    for (const [p, colour] of series) {
      const keep = bins.map((v, i) => [v, p[i]]).filter(([v]) => Math.abs(v) <= vmax);
      stroke(ctx, keep.map(([v]) => v), keep.map(([, q]) => q), px, py, colour);
      ctx.lineTo(px(vmax), py(0));
      ctx.lineTo(px(-vmax), py(0));
      ctx.globalAlpha = 0.18;
      ctx.fillStyle = colour;
      ctx.fill();
      ctx.globalAlpha = 1;
    }
  }

  // Positions over time (both players) and the relative phase, from the summary's traces.
  function drawTraces(traces) {
    // shown before it is sized: a hidden canvas measures 0 x 0 and would stay blank
    ui.phaseFigure.hidden = !(traces && traces.relative_phase);
    const positions = prepare(ui.positions);
    const phase = prepare(ui.phase);
    if (!traces || !traces.times) return;
    const t = traces.times;
    const span = [t[0], t[t.length - 1]];
    const ticks = ticksTo(span[1]);
    const colours = [PERSON_COLOUR, AVATAR_COLOUR];
    const onTrack = axes(positions, span, [-0.5, 0.5], ticks, [-0.5, 0, 0.5]);
    traces.positions.forEach((x, k) => stroke(positions.ctx, t, x, onTrack.px, onTrack.py, colours[k]));
    if (!traces.relative_phase) return;
    const onCircle = axes(phase, span, [-Math.PI, Math.PI], ticks, [-3, 0, 3]);
    phase.ctx.setLineDash([3, 3]);
    stroke(phase.ctx, span, [0, 0], onCircle.px, onCircle.py, "#d8dde6");
    phase.ctx.setLineDash([]);
    stroke(phase.ctx, t, traces.relative_phase, onCircle.px, onCircle.py, "#4b5563");
  }

  // The built avatar's card: its verdict in words and a link to the whole card.
  function showVerdict(message) {
    if (!message.verdict) return;
    ui.verdictText.textContent = message.verdict;
    if (game.cardUrl) URL.revokeObjectURL(game.cardUrl);
    game.cardUrl = URL.createObjectURL(new Blob([message.card], { type: "text/html" }));
    ui.cardLink.href = game.cardUrl;
    ui.cardLink.download = message.avatar.replace(/\.npz$/, ".html");
    ui.verdict.hidden = false;
  }

  function onMessage(event) {
    const message = JSON.parse(event.data);
    switch (message.type) {
      case "ready": {
        enableModes(message.modes);
        setPhase("idle");
        setStatus(message.avatar ? `Avatar: ${message.avatar}` : "Solo recording only");
        if (pendingStart) {
          setPhase("countdown");
          send(pendingStart);
          pendingStart = null;
        }
        break;
      }
      case "avatar": onAvatar(message); break;
      case "countdown":
        setPhase("countdown");
        ui.countdown.hidden = false;
        ui.countdown.textContent = message.remaining;
        setStatus("Get ready…");
        break;
      case "go":
        setPhase("running");
        ui.countdown.hidden = true;
        game.avatarX = message.avatar;
        ui.avatar.hidden = message.avatar === null;
        setStatus("Playing");
        break;
      case "done":
        setPhase("idle");
        ui.countdown.hidden = true;
        game.summary = message.summary;
        if (message.summary.complete) ui.progress.style.width = "100%";
        showResults(message.summary);
        if (message.build) ui.buildHint.textContent = message.build.hint;
        setStatus(message.summary.complete ? "Trial saved" : "Trial stopped and saved");
        break;
      case "building":
        setStatus(`Building your avatar: ${message.stage}…`);
        break;
      case "built":
        game.personalAvatar = message.avatar;
        enableModes(message.modes);
        setPhase("idle");
        setStatus(`Your avatar is ready (${message.avatar}): choose a mode and press Start`);
        showVerdict(message);
        break;
      case "error":
        setStatus(`Server: ${message.message}`);
        if (game.phase === "building" || (game.phase === "countdown" && ui.countdown.hidden)) {
          setPhase("idle");
        }
        break;
      default:
        break;
    }
  }

  function onClose(event) {
    pendingStart = null;
    if (event.code === CLOSE_IDLE && !active()) {
      setPhase("asleep");
      setStatus("Disconnected while idle; press Start to reconnect.");
      return;
    }
    setPhase("closed");
    setStatus("Disconnected from the server; reload the page to play again.");
  }

  function connect() {
    socket = new WebSocket(wsUrl);
    socket.addEventListener("message", onMessage);
    socket.addEventListener("close", onClose);
  }

  ui.form.addEventListener("submit", (event) => {
    event.preventDefault();
    if (!ui.form.reportValidity()) return;
    ui.results.hidden = true;
    ui.progress.style.width = "0%";
    ui.avatar.hidden = true;
    ui.avatarLegend.hidden = ui.mode.value === "solo";
    game.sent.clear();
    game.rtt = null;
    const start = {
      type: "start", mode: ui.mode.value, participant: ui.participant.value,
      duration: Number(ui.duration.value),
    };
    if (game.phase === "asleep") {
      pendingStart = start;
      setPhase("connecting");
      setStatus("Reconnecting…");
      connect();
      return;
    }
    setPhase("countdown");
    send(start);
  });
  ui.stop.addEventListener("click", () => send({ type: "stop" }));
  ui.build.addEventListener("click", () => {
    if (!ui.participant.reportValidity()) return;
    setPhase("building");
    setStatus("Building your avatar from your solo trials…");
    send({ type: "build", participant: ui.participant.value });
  });

  window.addEventListener("pointermove", (event) => pointerTo(event.clientX));
  ui.track.addEventListener("pointerdown", (event) => pointerTo(event.clientX));
  const KEYS = { ArrowLeft: "left", ArrowRight: "right", a: "left", d: "right" };
  window.addEventListener("keydown", (event) => {
    if (KEYS[event.key] && event.target.tagName !== "INPUT") {
      game.keys.add(KEYS[event.key]);
      event.preventDefault();
    }
  });
  window.addEventListener("keyup", (event) => game.keys.delete(KEYS[event.key]));
  window.addEventListener("blur", () => game.keys.clear());
  connect();
  requestAnimationFrame(frame);
})();
