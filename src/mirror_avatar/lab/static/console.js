// The researcher's console: a thin page over the lab server's HTTP/JSON API (see lab/running/api.py).
(() => {
  "use strict";
  const $ = (id) => document.getElementById(id);
  const POLL_MS = 250;
  const PRESETS = {
    dyad: { condition: "leader_follower", leaders: "0", players: [
      { label: "A1", kind: "avatar", spec: "bundled:slow" }, { label: "P1", kind: "human" }] },
    people: { condition: "leader_follower", leaders: "0", players: [
      { label: "P1", kind: "human" }, { label: "P2", kind: "human" }] },
    joint: { condition: "joint", leaders: "", players: [
      { label: "P1", kind: "human" }, { label: "A1", kind: "avatar", spec: "bundled:slow" }] },
    ring: { condition: "group", graph: "ring", leaders: "", players: [
      { label: "P1", kind: "human" }, { label: "A1", kind: "avatar", spec: "bundled:slow" },
      { label: "P2", kind: "human" }, { label: "A2", kind: "avatar", spec: "bundled:fast" }] },
    solo: { condition: "solo", leaders: "", players: [
      { label: "P1", kind: "human" }, { label: "P2", kind: "human" }] },
  };
  let current = null;   // the session shown
  let lastStatus = null;

  async function api(path, options = {}) {
    const response = await fetch(path, {
      credentials: "same-origin",
      headers: { "Content-Type": "application/json" },
      ...options,
    });
    const data = await response.json().catch(() => ({ error: response.statusText }));
    if (!response.ok) throw new Error(data.error || response.statusText);
    return data;
  }

  function cell(row, content) {
    const td = document.createElement("td");
    if (content instanceof Node) td.append(content); else td.textContent = content ?? "";
    row.append(td);
    return td;
  }

  function playerRow(player = { label: "", kind: "human" }) {
    const body = $("players-form").querySelector("tbody");
    const row = document.createElement("tr");
    const index = body.children.length;
    cell(row, String(index));
    const label = Object.assign(document.createElement("input"), { value: player.label, size: 8, className: "label" });
    cell(row, label);
    const kind = document.createElement("select");
    kind.className = "kind";
    ["human", "avatar"].forEach((k) => kind.append(new Option(k, k, false, k === player.kind)));
    cell(row, kind);
    const spec = Object.assign(document.createElement("input"), { value: player.spec || "", size: 22, className: "spec" });
    const device = document.createElement("select");
    device.className = "device";
    ["pointer", "lsl"].forEach((d) => device.append(new Option(d, d, false, d === (player.device || "pointer"))));
    const which = document.createElement("span");
    which.append(spec, device);
    cell(row, which);
    const lsl = Object.assign(document.createElement("input"), { placeholder: "stream, 0, 1", size: 18, className: "lsl" });
    cell(row, lsl);
    const remove = Object.assign(document.createElement("button"), { textContent: "×", className: "secondary small", type: "button" });
    remove.addEventListener("click", () => { row.remove(); renumber(); });
    cell(row, remove);
    const sync = () => { spec.hidden = kind.value !== "avatar"; device.hidden = kind.value !== "human"; lsl.hidden = kind.value !== "human" || device.value !== "lsl"; };
    kind.addEventListener("change", sync);
    device.addEventListener("change", sync);
    sync();
    body.append(row);
  }

  function renumber() {
    [...$("players-form").querySelectorAll("tbody tr")].forEach((row, i) => { row.firstChild.textContent = String(i); });
  }

  function applyPreset(name) {
    const preset = PRESETS[name];
    if (!preset) return;
    $("condition").value = preset.condition;
    $("graph").value = preset.graph || "complete";
    $("leaders").value = preset.leaders;
    $("players-form").querySelector("tbody").innerHTML = "";
    preset.players.forEach(playerRow);
  }

  function readPlan() {
    const players = [...$("players-form").querySelectorAll("tbody tr")].map((row) => {
      const kind = row.querySelector(".kind").value;
      const player = { label: row.querySelector(".label").value.trim(), kind };
      if (kind === "avatar") player.spec = row.querySelector(".spec").value.trim();
      else {
        player.device = row.querySelector(".device").value;
        if (player.device === "lsl") {
          const [stream, channel, scale] = row.querySelector(".lsl").value.split(",").map((s) => s.trim());
          player.lsl = { stream, channel: Number(channel || 0), scale: Number(scale || 1) };
        }
      }
      return player;
    });
    const leaders = $("leaders").value.split(",").map((s) => s.trim()).filter(Boolean).map(Number);
    return {
      condition: $("condition").value,
      graph: $("graph").value,
      leaders,
      duration: Number($("duration").value),
      trials: Number($("trials").value),
      pause: Number($("pause").value),
      show_metrics: $("show-metrics").checked,
      on_drop: $("on-drop").value,
      max_lateness: Number($("max-lateness").value),
      players,
    };
  }

  async function create() {
    $("create-error").textContent = "";
    try {
      const status = await api("/api/sessions", { method: "POST", body: JSON.stringify(readPlan()) });
      show(status.id);
    } catch (error) {
      $("create-error").textContent = error.message;
    }
  }

  // Show a session; its id goes into the URL's fragment, so a reloaded console shows it again.
  function show(id) {
    current = id;
    $("session").hidden = !id;
    $("session-id").textContent = id || "";
    $("session-error").textContent = "";
    history.replaceState(null, "", id ? `#${encodeURIComponent(id)}` : location.pathname);
  }

  async function command(action, body = {}) {
    $("session-error").textContent = "";
    try {
      await api(`/api/sessions/${current}/${action}`, { method: "POST", body: JSON.stringify(body) });
    } catch (error) {
      $("session-error").textContent = error.message;
    }
  }

  // Export the session's trials as BIDS (OUT/bids) and say where and how many files.
  async function exportBids() {
    $("session-error").textContent = "";
    $("export-result").textContent = "exporting...";
    try {
      const done = await api(`/api/sessions/${current}/export`, { method: "POST", body: "{}" });
      $("export-result").textContent = `exported ${done.motion_files} motion file(s); ${done.folder} holds ${done.files} files`;
    } catch (error) {
      $("export-result").textContent = "";
      $("session-error").textContent = error.message;
    }
  }

  function fmt(value, digits = 1) { return value === null || value === undefined ? "-" : Number(value).toFixed(digits); }

  function renderSlots(status) {
    const body = $("slots").querySelector("tbody");
    body.innerHTML = "";
    status.slots.forEach((slot) => {
      const row = document.createElement("tr");
      row.dataset.label = slot.label;
      const swatch = document.createElement("span");
      swatch.className = "dot";
      swatch.style.background = slot.colour;
      cell(row, swatch);
      cell(row, slot.label);
      cell(row, slot.role);
      const avatar = `avatar: ${slot.spec}` + (slot.plays ? ` · plays ${slot.plays}` : "");
      cell(row, slot.kind === "hidden" ? "person or avatar: hidden until export" : slot.kind === "avatar" ? avatar : `person (${slot.device})`);
      let state = slot.kind === "hidden" ? "-" : "ready";
      if (slot.kind === "human") {
        state = slot.connected ? "connected" : slot.joined ? "disconnected" : "not joined";
        if (slot.dropped_at !== null && slot.dropped_at !== undefined) state += ` · dropped at sample ${slot.dropped_at}`;
        if (slot.input_live === false) state += " · input lost";
        if (slot.connected && slot.entry_rtt_p95_ms !== null && slot.entry_rtt_p95_ms !== undefined) state += ` · entry p95 ${fmt(slot.entry_rtt_p95_ms, 0)} ms`;
      }
      cell(row, state).className = `state ${state.split(" ")[0]}`;
      const waiting = slot.rtt_waiting_ms > 1000 ? ` (no answer for ${fmt(slot.rtt_waiting_ms, 0)})` : "";
      cell(row, slot.kind === "human" ? `${fmt(slot.rtt_median_ms)} / ${fmt(slot.rtt_p95_ms)}${waiting}` : "");
      cell(row, slot.kind === "human" ? `${slot.frames_dropped} / ${slot.late_frames}` : "");
      cell(row, slot.kind === "human" ? `${slot.held ?? "-"} / ${slot.lost ?? "-"}` : "");
      const link = status.links[slot.label];
      if (link) {
        const box = document.createElement("span");
        box.className = "link";
        const anchor = Object.assign(document.createElement("a"), { href: link, textContent: "join link", target: "_blank", className: "join" });
        anchor.dataset.label = slot.label;
        const qr = Object.assign(document.createElement("img"), { src: `/api/sessions/${status.id}/qr/${slot.label}.svg`, alt: `QR code of ${slot.label}'s link`, className: "qr" });
        box.append(anchor, qr);
        cell(row, box);
      } else cell(row, "");
      body.append(row);
    });
  }

  // The field's measures of a trial in words, one line each (keys: lab/running/runner.py headline_measures).
  function measureLines(measures, labels) {
    if (measures.error) return [`measures failed: ${measures.error}`];
    // At the floor of its surrogates (1 / (n + 1)) a p-value is only bounded: "p <= floor".
    const floor = measures.surrogates ? 1 / (measures.surrogates.n + 1) : 0;
    const p = (key) => {
      const value = measures[`${key}_p_value`];
      if (value === undefined || value === null) return "";
      return value <= floor + 1e-12 ? ` (p ≤ ${fmt(floor, 2)})` : ` (p ${fmt(value, 2)})`;
    };
    const lines = [];
    if (measures.leader !== undefined) {
      lines.push(measures.leader === "none" ? "no clear leader (neither led most of the time)"
        : `leader ${labels[measures.leader]}, ${fmt(measures.leader_lag_s, 2)} s ahead in ${fmt(100 * measures.leader_share, 0)} % of windows${p("leader_share")}`);
    }
    if (measures.co_confidence_rate !== undefined) {
      lines.push(`co-confidence ${fmt(100 * measures.co_confidence_rate, 0)} % of the time, ${measures.co_confidence_count} stretch(es)${p("co_confidence_rate")}`);
    }
    if (measures.transfer_entropy_0_to_1 !== undefined) {
      lines.push(`transfer entropy ${labels[0]}→${labels[1]} ${fmt(measures.transfer_entropy_0_to_1, 3)} bits${p("transfer_entropy_0_to_1")}, ${labels[1]}→${labels[0]} ${fmt(measures.transfer_entropy_1_to_0, 3)} bits${p("transfer_entropy_1_to_0")}`);
    }
    const perPlayer = (prefix) => labels.map((label, k) => [label, measures[`${prefix}${k}`]])
      .filter(([, v]) => v !== undefined).map(([label, v]) => `${label} ${fmt(v, 3)}`).join(", ");
    const influence = perPlayer("influence_player_");
    if (influence) lines.push(`influence (bits) ${influence}`);
    const jitter = perPlayer("jitter_index_player_");
    if (jitter) lines.push(`2-3 Hz jitter ${jitter}`);
    return lines;
  }

  const KIND_WORDS = { human: "person", avatar: "avatar", hidden: "hidden until export" };

  // One line per item, in a cell (the partners, the answers of each person).
  function listed(items) {
    const box = document.createElement("div");
    items.forEach((text) => box.append(Object.assign(document.createElement("div"), { textContent: text })));
    return box;
  }

  // Each person's answers, in the order of the trial's partners whatever order they came in.
  function answerLines(answers, partners) {
    const slot = (label) => (partners.includes(label) ? partners.indexOf(label) : partners.length);
    return Object.keys(answers)
      .sort((a, b) => slot(a) - slot(b))
      .map((label) => `${label}: ` + Object.entries(answers[label]).map(([question, value]) => `${question} ${value}`).join(", "));
  }

  function renderTrials(status) {
    $("trial-list").classList.toggle("study", Boolean(status.study));
    const body = $("trial-list").querySelector("tbody");
    body.innerHTML = "";
    const names = { phase_locking: "CV", rmse: "RMS", time_lag: "lag (s)", group_synchronisation: "ρg", mean_phase_locking: "mean CV", mean_rmse: "mean RMS", kuramoto_order: "r" };
    status.trials.forEach((trial) => {
      const row = document.createElement("tr");
      cell(row, String(trial.n));
      cell(row, trial.condition ? `${trial.condition} (${trial.block})` : "").className = "study-only condition";
      cell(row, listed(Object.entries(trial.partners || {}).map(([label, kind]) => `${label} ${KIND_WORDS[kind] || kind}`))).className = "study-only partners";
      cell(row, listed(answerLines(trial.answers || {}, Object.keys(trial.partners || {})))).className = "study-only answers";
      cell(row, trial.complete ? "complete" : `incomplete: ${trial.end_reason}`);
      cell(row, String(trial.n_samples));
      cell(row, Object.entries(trial.metrics).filter(([k]) => names[k]).map(([k, v]) => `${names[k]} ${fmt(v, 3)}`).join(" · ")).className = "metrics";
      const lines = document.createElement("div");
      measureLines(trial.measures || {}, status.slots.map((slot) => slot.label)).forEach((line) => lines.append(Object.assign(document.createElement("div"), { textContent: line })));
      cell(row, lines).className = "metrics measures";
      const dropped = Object.entries(trial.dropped).map(([k, v]) => `${k} dropped at ${v}`);
      const lost = Object.entries(trial.lost || {}).filter(([, v]) => v > 0).map(([k, v]) => `${k} lost ${v}`);
      const late = trial.late_ms && trial.late_ms.max !== null ? [`clock late ≤ ${fmt(trial.late_ms.max, 0)} ms`] : [];
      cell(row, [Object.entries(trial.held).map(([k, v]) => `${k}: ${v}`).join(", "), ...dropped, ...lost, ...late].join("; "));
      const files = document.createElement("span");
      trial.files.forEach((name) => files.append(Object.assign(document.createElement("a"), { href: `/api/sessions/${status.id}/files/${name}`, textContent: name }), " "));
      cell(row, files);
      body.append(row);
    });
  }

  // Where the session stands: the trial running, the next one, or that it is over.
  function whereNow(status) {
    const done = status.trials.length;
    if (status.trial) return `trial ${status.trial.n} running · clock late ${fmt(status.trial.late_ms, 0)} ms (max ${fmt(status.trial.max_late_ms, 0)})`;
    if (status.state === "finished") return `finished: ${done} of ${status.plan.trials} trial(s) played`;
    if (status.state === "aborted") return `aborted after ${done} trial(s)`;
    return `next trial ${Math.min(status.next_trial, status.plan.trials)}`;
  }

  function render(status) {
    lastStatus = status;
    $("state").textContent = status.state;
    $("state").className = `badge ${status.state}`;
    const plan = status.plan;
    $("session-summary").textContent = `${plan.condition.replace("_", "-")} · ${plan.slots.length} players · ${plan.trials} trial(s) of ${plan.duration} s · seed ${plan.seed} · ` + whereNow(status);
    if (status.study) {
      const study = status.study;
      const where = status.state === "finished" ? `finished: all ${study.total_trials} trials played` : study.where;
      const pages = study.pages ? ` · pages: ${Object.entries(study.pages).map(([label, on]) => `${label} ${on ? "connected" : "not connected"}`).join(", ")} · double blind: partner kinds hidden until export` : "";
      $("session-summary").textContent = `participant ${study.participant} · ${where} · order: ${study.order.join(", ")}` + (study.waiting.length ? ` · waiting: ${study.waiting.join(", ")}` : "") + Object.entries(study.unanswered).map(([label, ids]) => ` · ${label} to answer: ${ids.join(", ")}`).join("") + pages;
    }
    $("session-error").textContent = status.error || $("session-error").textContent;
    renderSlots(status);
    renderTrials(status);
    $("events").textContent = status.events.join("\n");
    const running = ["countdown", "running", "pause"].includes(status.state);
    $("start").disabled = status.state !== "waiting";
    $("start-force").disabled = status.state !== "waiting";
    $("stop").disabled = !running;
    $("abort").disabled = ["finished", "aborted"].includes(status.state);
    $("export").disabled = running;
    $("sync-box").hidden = plan.slots.length < 3;
  }

  function drawLive(live) {
    const canvas = $("live-plot");
    const ctx = canvas.getContext("2d");
    const { width, height } = canvas;
    ctx.clearRect(0, 0, width, height);
    ctx.strokeStyle = "#d8dde6";
    ctx.strokeRect(0.5, 0.5, width - 1, height - 1);
    $("live-trial").textContent = live.trial ? `trial ${live.trial}` : "(no trial running)";
    $("live-progress").style.width = `${(100 * (live.progress || 0)).toFixed(1)}%`;
    $("sync").textContent = live.group_sync === null || live.group_sync === undefined ? "-" : live.group_sync.toFixed(3);
    if (!live.times || live.times.length < 2 || !lastStatus) return;
    const t0 = live.times[0];
    const span = Math.max(10, live.times[live.times.length - 1] - t0);
    const px = (t) => ((t - t0) / span) * (width - 20) + 10;
    const py = (x) => height / 2 - x * (height - 20);
    live.positions.forEach((series, k) => {
      ctx.strokeStyle = lastStatus.slots[k].colour;
      ctx.lineWidth = 2;
      ctx.beginPath();
      series.forEach((x, i) => { if (i === 0) ctx.moveTo(px(live.times[i]), py(x)); else ctx.lineTo(px(live.times[i]), py(x)); });
      ctx.stroke();
      ctx.fillStyle = lastStatus.slots[k].colour;
      ctx.fillText(lastStatus.slots[k].label, width - 40, 14 + 14 * k);
    });
  }

  // A session shown while an answer was on its way (just created) is not judged by that answer.
  async function poll() {
    try {
      const asked = current;
      const listing = await api("/api/sessions");
      renderSessionList(listing.sessions);
      showProtocol(listing.protocol);
      if (asked && current === asked && !listing.sessions.some((s) => s.id === asked)) show(null);  // forgotten by the server
      const id = current;
      if (id) {
        const status = await api(`/api/sessions/${id}`);
        if (id === current) render(status);
        const live = await api(`/api/sessions/${id}/live`);
        if (id === current) drawLive(live);
      }
    } catch (error) {
      $("session-error").textContent = error.message;
    }
    setTimeout(poll, POLL_MS);
  }

  function showProtocol(protocol) {
    $("study").classList.toggle("loaded", Boolean(protocol));
    $("study-run").hidden = !protocol;
    $("study-title").textContent = protocol ? `"${protocol.title}" · seed ${protocol.seed} · people ${protocol.people.join(", ")}` + (protocol.blind === "double" ? " · double blind" : "") + (protocol.warnings || []).map((w) => ` · warning: ${w}`).join("") : "none loaded";
  }

  async function loadProtocol() {
    $("protocol-error").textContent = "";
    $("protocol-result").textContent = "";
    const file = $("protocol-file").files[0];
    if (!file) {
      $("protocol-error").textContent = "choose a protocol file first";
      return;
    }
    try {
      const answer = await api("/api/protocol", { method: "POST", body: JSON.stringify({ name: file.name, text: await file.text() }) });
      showProtocol(answer.protocol);
      $("protocol-result").textContent = `loaded; kept as ${answer.protocol.file}`;
    } catch (error) {
      $("protocol-error").textContent = error.message;
    }
  }

  function renderSessionList(sessions) {
    const box = $("sessions-list");
    box.innerHTML = "";
    sessions.forEach((s) => {
      const link = Object.assign(document.createElement("a"), { href: "#", textContent: `${s.id} (${s.state})` });
      link.addEventListener("click", (event) => { event.preventDefault(); show(s.id); });
      box.append(link, " ");
    });
  }

  $("preset").addEventListener("change", (event) => applyPreset(event.target.value));
  $("add-player").addEventListener("click", () => playerRow());
  $("create-session").addEventListener("click", create);
  $("load-protocol").addEventListener("click", loadProtocol);
  $("create-participant").addEventListener("click", async () => {
    $("study-error").textContent = "";
    try {
      const status = await api("/api/sessions", { method: "POST", body: JSON.stringify({ participant: Number($("participant").value) }) });
      show(status.id);
    } catch (error) {
      $("study-error").textContent = error.message;
    }
  });
  $("start").addEventListener("click", () => command("start"));
  $("start-force").addEventListener("click", () => command("start", { force: true }));
  $("stop").addEventListener("click", () => command("stop"));
  $("export").addEventListener("click", exportBids);
  $("abort").addEventListener("click", () => { if (confirm("Abort the session? Its links expire.")) command("abort"); });
  applyPreset("dyad");
  if (location.hash.length > 1) show(decodeURIComponent(location.hash.slice(1)));
  poll();
})();
