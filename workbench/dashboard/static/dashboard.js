// workbench bridge dashboard: polls /api/versions, fetches the panels whose ETag changed
// and draws them with plain DOM and SVG (no library, nothing from the network but this
// server). Every value from the state files is inserted as text, never as HTML.
"use strict";
(function () {
  const CONFIG = JSON.parse(document.getElementById("dashboard-config").textContent);
  const SVG = "http://www.w3.org/2000/svg";
  // Tableau-10 colours, one per mode number (mode 1 is the first colour)
  const PALETTE = ["#4e79a7", "#f28e2b", "#e15759", "#76b7b2", "#59a14f",
                   "#edc948", "#b07aa1", "#ff9da7", "#9c755f", "#bab0ac"];
  const modeColour = (mode) => PALETTE[(mode - 1 + PALETTE.length * 100) % PALETTE.length];
  const etags = {};
  const state = { rendered: {}, polls: 0, errors: 0, serverOffsetMs: 0 };
  window.dashboard = state;

  const $ = (sel, root = document) => root.querySelector(sel);
  function el(tag, attrs = {}, text = null) {
    const node = tag.startsWith("svg:") ? document.createElementNS(SVG, tag.slice(4))
                                        : document.createElement(tag);
    for (const [k, v] of Object.entries(attrs)) node.setAttribute(k, v);
    if (text !== null) node.textContent = text;
    return node;
  }
  const fmt = (v, digits) => (v === null || v === undefined) ? "–" : Number(v).toFixed(digits);
  const hhmm = (iso) => iso ? iso.slice(0, 16).replace("T", " ") : "–";
  function ago(seconds) {
    if (seconds === null || seconds === undefined) return "";
    if (seconds < 90) return `${Math.round(seconds)} s ago`;
    if (seconds < 5400) return `${Math.round(seconds / 60)} min ago`;
    return `${(seconds / 3600).toFixed(1)} h ago`;
  }

  // ------------------------------------------------------------------ panels
  function setPanel(id, data) {
    const section = document.getElementById(id);
    section.classList.toggle("ready", !!data.available);
    $(".placeholder", section).textContent =
      data.available ? "" : `waiting for data${data.message ? ": " + data.message : ""}`;
    let note = $(".note", section);
    if (data.available && data.message) {
      if (!note) { note = el("p", { class: "note" }); $("h2", section).after(note); }
      note.textContent = data.message;
    } else if (note) note.remove();
    return section;
  }

  const render = {};

  render.status = function (d) {
    const box = document.getElementById("status");
    const liveness = d.available ? (d.liveness || d.state) : "waiting";
    box.className = "status " + liveness.replace(/ /g, "-");
    const beat = d.available ? d.heartbeat : null;
    $("#status-heartbeat").dataset.time = beat ? beat.time : "";
    if (!d.available) {
      $("#status-state").textContent = "waiting for data";
      for (const id of ["block", "updated", "heartbeat", "worker", "given-up"]) {
        $(`#status-${id}`).textContent = "";
      }
      $("#status-message").textContent = d.message || "";
      return null;
    }
    $("#status-state").textContent = `monitor ${liveness}`;
    state.heartbeat = beat;
    heartbeatText();
    // the background forecast/health worker: stopped, or restarted after it stopped
    const worker = beat ? beat.worker : null;
    const workerNote = $("#status-worker");
    workerNote.textContent = worker && (worker.state === "stopped" || worker.message)
      ? (worker.state === "stopped" ? "background worker stopped: " : "") + worker.message : "";
    workerNote.className = worker && worker.state === "stopped" ? "stopped" : "";
    $("#status-block").textContent =
      d.last_block === null ? "no block yet" : `last block ${d.last_block} (${d.blocks_done} done)`;
    $("#status-updated").textContent = `updated ${hhmm(d.updated_at)}Z`;
    $("#status-updated").dataset.updatedAt = d.updated_at;
    $("#status-message").textContent = d.message || "";
    // blocks given up (their file landed after the late window): named with their span
    const spans = (d.given_up || []).map((s) =>
      (s.first_block === s.last_block ? `${s.first_block}` : `${s.first_block}-${s.last_block}`) +
      ` (${hhmm(s.start)} to ${hhmm(s.end)} UTC)`);
    const givenUp = $("#status-given-up");
    givenUp.textContent = spans.length
      ? `blocks given up: ${spans.join(", ")} - workbench identify over the folder includes them`
      : "";
    givenUp.title = d.given_up_note || "";
    box.dataset.block = d.last_block === null ? "" : d.last_block;
    return d.last_block;
  };

  render.modes = function (d) {
    const section = setPanel("modes", d);
    const cards = $(".cards", section);
    cards.replaceChildren();
    if (!d.available) return null;
    $("#modes-sub").textContent = d.block === null ? "" :
      `block ${d.block}, ${hhmm(d.block_start)}Z` + (d.option ? ` · forecast option ${d.option}` : "");
    for (const m of d.modes) {
      const card = el("div", { class: "mode-card", "data-mode": m.mode });
      card.style.setProperty("--mode", modeColour(m.mode));
      if (!m.current) card.classList.add("stale");
      if (m.inside_bounds === false) card.classList.add("outside");
      card.append(el("h3", {}, `Mode ${m.mode}`));
      const shown = m.frequency_hz !== undefined && m.frequency_hz !== null ? m.frequency_hz
                  : (m.current && m.ssi_frequency_hz !== undefined ? m.ssi_frequency_hz : null);
      card.append(el("div", { class: "freq" }, shown === null ? "– Hz" : `${fmt(shown, 3)} Hz`));
      if (m.model_frequency_hz !== undefined) {
        card.append(el("div", { class: "row forecast" },
          `model ${fmt(m.model_frequency_hz, 3)} [${fmt(m.model_lower_hz, 3)}, ${fmt(m.model_upper_hz, 3)}] Hz`));
        const std2 = m.kalman_std_hz === null ? null : 1.96 * m.kalman_std_hz;
        card.append(el("div", { class: "row kalman" },
          `Kalman ${fmt(m.kalman_frequency_hz, 3)} ± ${fmt(std2, 3)} Hz (95 %)`));
      }
      if (m.damping_ratio !== undefined && m.damping_ratio !== null) {
        card.append(el("div", { class: "row damping" }, `damping ${fmt(100 * m.damping_ratio, 2)} %`));
      }
      if (!m.current) {
        const seen = m.last_block === undefined ? "never" : `last in block ${m.last_block}`;
        card.append(el("div", { class: "flag" }, `not identified in block ${d.block} (${seen})`));
      } else if (m.inside_bounds === false) {
        card.append(el("div", { class: "flag" }, "outside the model's 95 % bounds"));
      }
      cards.append(card);
    }
    return d.block;
  };

  const signed = (v, digits) => (v === null || v === undefined) ? "–"
    : `${v > 0 ? "+" : (v < 0 ? "−" : "")}${Math.abs(v).toFixed(digits)}`;
  const orderName = (order) => `${Number.isInteger(order) ? order : order.toFixed(1)}×`;

  // one panel per mode: relative change [%] against the mode's reference, with the model's
  // prediction and 95 % band; the shaft orders near the mode drawn dashed, never as modes
  render.tracked = function (d) {
    const section = setPanel("tracked", d);
    const panels = document.getElementById("mode-panels");
    panels.replaceChildren();
    if (!d.available) return null;
    $("#tracked-sub").textContent = (d.start ? `last ${d.hours} h: ${hhmm(d.start)}Z – ${hhmm(d.end)}Z` : "") +
      (d.reference ? ` · reference: ${d.reference}` : "") + (d.option ? ` · band: forecast option ${d.option}` : "");
    const when = new Map(d.blocks.block.map((b, i) => [b, d.blocks.t[i]]));
    const charts = [];  // drawn once every panel is in place: one layout, not one per panel
    for (const s of d.series) {
      const panel = el("div", { class: "mode-panel", "data-mode": s.mode });
      panel.style.setProperty("--mode", modeColour(s.mode));
      const head = el("h3");
      head.append(el("b", {}, `Mode ${s.mode}`));
      let last = null;
      if (s.change_percent) for (const v of s.change_percent) if (v !== null) last = v;
      const now = el("span", { class: "now" }, last === null ? "– %" : `${signed(last, 2)} %`);
      // the newest estimate outside the model's band, as the mode card says
      const band = s.band;
      if (band && s.block.length) {
        const i = band.block.indexOf(s.block[s.block.length - 1]);
        if (i >= 0 && last !== null && band.lower_percent[i] !== null &&
            (last < band.lower_percent[i] || last > band.upper_percent[i])) now.classList.add("outside");
      }
      head.append(" ", now, " ", el("span", { class: "ref" },
        s.reference_hz === null ? "no reference yet" : `vs ${fmt(s.reference_hz, 3)} Hz`));
      panel.append(head);
      const svg = el("svg:svg", { class: "chart", "data-mode": s.mode, role: "img",
                                  "aria-label": `mode ${s.mode}, change against its reference in %` });
      panel.append(svg);
      panels.append(panel);
      if (s.change_percent === null) continue;
      const series = [];
      const bandT = band ? band.block.map((b) => when.get(b)) : null;
      if (band) {
        series.push({ key: "model", cls: "model", x: bandT, y: band.model_percent, block: band.block,
                      noMarkers: true });
      }
      series.push({ key: s.mode, colour: modeColour(s.mode), x: s.t, y: s.change_percent, block: s.block });
      for (const o of s.orders) {
        series.push({ key: `order ${o.order}`, cls: "harmonic", x: o.t, y: o.change_percent, block: o.block,
                      noMarkers: true, clip: true, label: `order ${orderName(o.order)}` });
      }
      charts.push([svg, {
        series, markers: true, zero: true, ylabel: "change [%]",
        band: band ? { x: bandT, lo: band.lower_percent, hi: band.upper_percent, block: band.block } : null,
      }]);
    }
    const sizes = charts.map(([svg]) => [svg.clientWidth, svg.clientHeight]);
    charts.forEach(([svg, spec], i) => drawChart(svg, { ...spec, size: sizes[i] }));
    return d.block;
  };

  render.shaft = function (d) {
    const section = setPanel("shaft", d);
    const orders = document.getElementById("shaft-orders");
    const tracks = document.getElementById("shaft-tracks");
    const svg = document.getElementById("shaft-chart");
    orders.replaceChildren();
    tracks.replaceChildren();
    if (!d.available) { svg.replaceChildren(); return null; }
    $("#shaft-sub").textContent = `block ${d.block}` +
      (d.shaft_rpm === null ? "" : ` · shaft ${fmt(d.shaft_rpm, 1)} rpm`) + ` · last ${d.hours} h`;
    for (const o of d.orders) {
      orders.append(el("dt", {}, `order ${orderName(o.order)}`));
      orders.append(el("dd", { "data-order": o.order },
        o.frequency_hz === null ? "– Hz" : `${fmt(o.frequency_hz, 3)} Hz`));
    }
    if (!d.tracks.length) {
      tracks.append(el("li", { class: "none" }, "no tracked line is a harmonic"));
    }
    for (const h of d.tracks) {
      const on = h.order === null ? "" : ` on order ${orderName(h.order)}`;
      tracks.append(el("li", { "data-track": h.track },
        `harmonic ${h.track}: ${fmt(h.median_frequency_hz, 3)} Hz${on}, ${h.blocks} blocks (last ${h.last_block}) - not a mode`));
    }
    const series = d.orders.map((o) => ({ key: `order ${o.order}`, cls: "harmonic", x: o.t, y: o.line_hz,
                                          block: o.block, noMarkers: true, label: `order ${orderName(o.order)}` }));
    const points = d.tracks.map((h) => ({ key: `harmonic ${h.track}`, cls: "harmonic-line", x: h.t,
                                          y: h.frequency_hz, block: h.block, dots: "harmonic-point" }));
    drawChart(svg, { series: series.concat(points), ylabel: "frequency [Hz]", markers: true });
    return d.block;
  };

  render.health = function (d) {
    const section = setPanel("health", d);
    const svg = document.getElementById("health-chart");
    if (!d.available) { svg.replaceChildren(); return null; }
    const verdict = d.alarm ? "ALARM" : (d.phase === "reference" ? "learning reference" : "in control");
    const top = d.contributions.filter((c) => c.share >= 0.05).slice(0, 3)
      .map((c) => `mode ${c.mode} ${Math.round(100 * c.share)} %`).join(", ");
    $("#health-sub").textContent =
      `block ${d.block}: statistic ${fmt(d.statistic, 2)}, limit ${fmt(d.limit, 2)} · ${verdict}` +
      (d.alarm && top ? ` · driven by ${top}` : "");
    section.classList.toggle("alarming", !!d.alarm);
    const p = d.points;
    drawChart(svg, {
      series: [{ key: "statistic", cls: "statistic", x: p.t, y: p.statistic, block: p.block }],
      limit: { x: p.t, y: p.limit },
      shade: p.reference.some(Boolean) ? { x: p.t, on: p.reference } : null,
      points: { x: p.t, y: p.statistic, on: p.alarm, cls: "alarm-point" },
      ylabel: "statistic", floorZero: true,
    });
    return d.block;
  };

  render.alarms = function (d) {
    const section = setPanel("alarms", d);
    const body = $("tbody", section);
    body.replaceChildren();
    if (!d.available) return null;
    $("#alarms-sub").textContent = d.count === 0 ? "none" :
      `${d.count} episode${d.count > 1 ? "s" : ""}` + (d.active ? " · ACTIVE" : "");
    for (const a of d.alarms) {
      const tr = el("tr", { "data-alarm": a.alarm, class: a.active ? "active" : "" });
      const shift = a.top_mode_shift_percent === null ? "–" :
        `mode ${a.top_mode} ${a.top_mode_shift_percent > 0 ? "+" : ""}${fmt(a.top_mode_shift_percent, 2)} %`;
      for (const text of [a.alarm, hhmm(a.start_time), a.active ? "ongoing" : hhmm(a.end_time),
                          fmt(a.peak_statistic, 1), a.modes, shift]) {
        tr.append(el("td", {}, String(text)));
      }
      body.append(tr);
    }
    return d.count;
  };

  render.data_health = function (d) {
    const section = setPanel("data_health", d);
    const facts = $(".facts", section);
    const body = $("tbody", section);
    facts.replaceChildren();
    body.replaceChildren();
    if (!d.available || !d.latest) {
      if (d.available) section.classList.remove("ready");
      return null;
    }
    const l = d.latest, s = d.summary;
    $("#data_health-sub").textContent = `block ${l.block}, last ${d.hours} h`;
    const rows = [
      ["channels", `${l.n_channels}`],
      ["dropped now", l.dropped_channels.length ? l.dropped_channels.join(", ") : "none"],
      ["gap in block", `${fmt(l.gap_seconds, 1)} s`],
      ["last file landed", `${hhmm(l.last_file_landed)}Z`],
      ["latency", `${fmt(l.latency_s, 1)} s (median ${fmt(s.median_latency_s, 1)}, worst ${fmt(s.worst_latency_s, 1)})`],
      ["blocks with dropped channels", `${s.blocks_with_dropped_channels} of ${s.blocks}`],
      ["gaps in total", `${fmt(s.gap_seconds, 1)} s`],
    ];
    for (const [k, v] of rows) { facts.append(el("dt", {}, k)); facts.append(el("dd", { "data-fact": k }, v)); }
    for (const r of d.rows) {
      const tr = el("tr", { "data-block": r.block, class: r.dropped_channels.length ? "dropped" : "" });
      for (const text of [r.block, hhmm(r.block_start), r.n_channels,
                          r.dropped_channels.join(", ") || "–", fmt(r.gap_seconds, 1), fmt(r.latency_s, 1)]) {
        tr.append(el("td", {}, String(text)));
      }
      body.append(tr);
    }
    return l.block;
  };

  // ------------------------------------------------------------------ SVG chart
  function niceTicks(lo, hi, count) {
    if (!(hi > lo)) { const pad = Math.abs(lo) * 0.01 || 1; lo -= pad; hi += pad; }
    const raw = (hi - lo) / count;
    const mag = Math.pow(10, Math.floor(Math.log10(raw)));
    const step = [1, 2, 2.5, 5, 10].map((m) => m * mag).find((s) => s >= raw);
    const ticks = [];
    for (let v = Math.ceil(lo / step) * step; v <= hi + step * 1e-9; v += step) ticks.push(v);
    return { lo, hi, ticks, digits: Math.max(0, -Math.floor(Math.log10(step))) };
  }

  function drawChart(svg, spec) {
    const [w, h] = spec.size || [svg.clientWidth, svg.clientHeight];
    const width = w || 1000, height = h || 280;
    const m = { left: 58, right: 12, top: 10, bottom: 26 };
    svg.setAttribute("viewBox", `0 0 ${width} ${height}`);
    svg.replaceChildren();
    const xs = [], ys = [];
    for (const s of spec.series) {
      if (s.clip) continue;  // drawn inside the others' range, never stretching it
      xs.push(...s.x); ys.push(...s.y.filter((v) => v !== null));
    }
    if (spec.limit) ys.push(...spec.limit.y.filter((v) => v !== null));
    if (spec.band) {
      xs.push(...spec.band.x);
      ys.push(...spec.band.lo.filter((v) => v !== null), ...spec.band.hi.filter((v) => v !== null));
    }
    if (spec.zero && ys.length) ys.push(0);
    if (!xs.length || !ys.length) return;
    let x0 = Math.min(...xs), x1 = Math.max(...xs);
    if (x1 === x0) { x0 -= 150000; x1 += 150000; }
    let y0 = Math.min(...ys), y1 = Math.max(...ys);
    if (spec.floorZero) y0 = 0;
    const pad = (y1 - y0) * 0.05;
    const yt = niceTicks(y0 - (spec.floorZero ? 0 : pad), y1 + pad, 5);
    const X = (t) => m.left + (t - x0) / (x1 - x0) * (width - m.left - m.right);
    const Y = (v) => height - m.bottom - (v - yt.lo) / (yt.hi - yt.lo) * (height - m.top - m.bottom);
    const axes = el("svg:g", { class: "axes" });
    for (const v of yt.ticks) {
      if (v < yt.lo || v > yt.hi) continue;
      axes.append(el("svg:line", { class: "grid", x1: m.left, x2: width - m.right, y1: Y(v), y2: Y(v) }));
      axes.append(el("svg:text", { x: m.left - 6, y: Y(v) + 4, "text-anchor": "end" }, v.toFixed(yt.digits)));
    }
    const hour = 3600000, spanH = (x1 - x0) / hour;
    const stepH = [0.25, 0.5, 1, 2, 3, 6, 12, 24, 48].find((s) => spanH / s <= 8) || 96;
    for (let t = Math.ceil(x0 / (stepH * hour)) * stepH * hour; t <= x1; t += stepH * hour) {
      const label = new Date(t).toISOString().slice(stepH >= 24 ? 5 : 11, 16).replace("T", " ");
      axes.append(el("svg:line", { class: "grid", x1: X(t), x2: X(t), y1: m.top, y2: height - m.bottom }));
      axes.append(el("svg:text", { x: X(t), y: height - 8, "text-anchor": "middle" }, label));
    }
    axes.append(el("svg:text", { x: 12, y: m.top + 8, transform: `rotate(-90 12 ${m.top + 8})`,
                                 "text-anchor": "end" }, spec.ylabel));
    svg.append(axes);
    if (spec.zero) {
      svg.append(el("svg:line", { class: "zero", x1: m.left, x2: width - m.right, y1: Y(0), y2: Y(0) }));
    }
    if (spec.band) {
      // the model's band as one polygon per run of blocks with bounds
      const b = spec.band;
      let run = [];
      const flush = () => {
        if (run.length) {
          const upper = run.map((i) => `${X(b.x[i]).toFixed(1)},${Y(b.hi[i]).toFixed(1)}`);
          const lower = run.slice().reverse().map((i) => `${X(b.x[i]).toFixed(1)},${Y(b.lo[i]).toFixed(1)}`);
          svg.append(el("svg:path", { class: "band", d: `M${upper.join("L")}L${lower.join("L")}Z` }));
        }
        run = [];
      };
      for (let i = 0; i < b.x.length; i++) {
        const ok = b.lo[i] !== null && b.hi[i] !== null;
        const joined = run.length && (!b.block || b.block[i] - b.block[run[run.length - 1]] === 1);
        if (!ok || !joined) flush();
        if (ok) run.push(i);
      }
      flush();
    }
    if (spec.shade) {
      const on = spec.shade.on, x = spec.shade.x;
      let start = null;
      for (let i = 0; i <= on.length; i++) {
        if (i < on.length && on[i] && start === null) start = i;
        if ((i === on.length || !on[i]) && start !== null) {
          const a = X(x[start]), b = X(x[i - 1]);
          svg.append(el("svg:rect", { class: "reference", x: a, y: m.top, width: Math.max(b - a, 1),
                                      height: height - m.top - m.bottom }));
          start = null;
        }
      }
    }
    for (const s of spec.series) {
      // break the line where a block is missing or has no value (or, clipped, is off the axis)
      const y = s.clip ? s.y.map((v) => (v === null || v < yt.lo || v > yt.hi) ? null : v) : s.y;
      let d = "", lastX = null, lastY = null;
      for (let i = 0; i < s.x.length; i++) {
        if (y[i] === null) continue;
        const joined = i > 0 && y[i - 1] !== null && (!s.block || s.block[i] - s.block[i - 1] === 1);
        lastX = X(s.x[i]); lastY = Y(y[i]);
        d += `${joined ? "L" : "M"}${lastX.toFixed(1)},${lastY.toFixed(1)}`;
      }
      const g = el("svg:g", { class: "series", "data-key": s.key, "data-points": y.filter((v) => v !== null).length });
      if (s.block && s.block.length) g.setAttribute("data-last-block", s.block[s.block.length - 1]);
      const path = el("svg:path", { d, class: s.cls || "" });
      if (s.colour) { path.setAttribute("stroke", s.colour); }
      g.append(path);
      if (spec.markers && !s.noMarkers) {
        for (let i = 0; i < s.x.length; i++) {
          if (y[i] === null) continue;
          const dot = el("svg:circle", { cx: X(s.x[i]).toFixed(1), cy: Y(y[i]).toFixed(1), r: s.dots ? 2.2 : 1.8 });
          if (s.dots) dot.setAttribute("class", s.dots); else dot.setAttribute("fill", s.colour);
          g.append(dot);
        }
      }
      // a line that is not a mode says what it is where it ends
      if (s.label && lastX !== null) {
        g.append(el("svg:text", { class: "series-label", x: Math.min(lastX, width - m.right - 2),
                                  y: lastY - 4, "text-anchor": "end" }, s.label));
      }
      svg.append(g);
    }
    if (spec.limit) {
      let d = "";
      spec.limit.x.forEach((t, i) => {
        const v = spec.limit.y[i];
        if (v !== null) d += `${d ? "L" : "M"}${X(t).toFixed(1)},${Y(v).toFixed(1)}`;
      });
      svg.append(el("svg:path", { class: "limit", d }));
    }
    if (spec.points) {
      const p = spec.points;
      p.x.forEach((t, i) => {
        if (p.on[i] && p.y[i] !== null) {
          svg.append(el("svg:circle", { class: p.cls, cx: X(t), cy: Y(p.y[i]), r: 3 }));
        }
      });
    }
  }

  // the heartbeat: when missed, how long ago and the last file the monitor took
  function heartbeatText() {
    const node = $("#status-heartbeat");
    const beat = state.heartbeat;
    const box = document.getElementById("status");
    if (!beat || !box.classList.contains("not-responding")) {
      node.textContent = beat && beat.last_file
        ? `last file ${beat.last_file} taken ${hhmm(beat.last_file_taken_at)}Z` : "";
      return;
    }
    const age = (Date.now() + state.serverOffsetMs - Date.parse(beat.time)) / 1000;
    const file = beat.last_file
      ? `last file taken: ${beat.last_file} at ${beat.last_file_taken_at.slice(11, 19)}Z`
      : "no file taken yet";
    if (beat.stalled) {  // the heartbeat thread lives, the main loop does not move
      const busy = (Date.now() + state.serverOffsetMs - Date.parse(beat.doing_since)) / 1000;
      node.textContent = `main loop stuck ${ago(busy).replace(" ago", "")} ` +
        `${beat.doing} (since ${beat.doing_since.slice(11, 19)}Z; pid ${beat.pid} on ` +
        `${beat.host}); ${file}`;
      return;
    }
    node.textContent = `no heartbeat for ${ago(age).replace(" ago", "")} ` +
      `(pid ${beat.pid} on ${beat.host}); ${file}`;
  }

  // ------------------------------------------------------------------ polling
  const connection = document.getElementById("connection");
  async function fetchPanel(name) {
    const headers = etags[name] ? { "If-None-Match": etags[name] } : {};
    const response = await fetch(`api/${name}`, { cache: "no-store", headers });
    if (response.status === 304) return;
    const data = await response.json();
    const started = performance.now();
    const shown = render[name](data);
    const ms = performance.now() - started;  // drawing time, for benchmarks
    etags[name] = response.headers.get("ETag");
    const section = document.getElementById(name);
    if (section) section.dataset.block = shown === null || shown === undefined ? "" : shown;
    state.rendered[name] = { at: Date.now(), value: shown, ms };
  }

  async function poll() {
    try {
      const response = await fetch("api/versions", { cache: "no-store" });
      const versions = await response.json();
      state.serverOffsetMs = Date.parse(versions.server_time) - Date.now();
      const changed = Object.keys(versions.panels).filter((k) => versions.panels[k] !== etags[k]);
      await Promise.all(changed.map(fetchPanel));
      state.polls += 1;
      connection.className = "connection";
      connection.textContent = `live · checked ${new Date().toISOString().slice(11, 19)}Z`;
      const updated = $("#status-updated").dataset.updatedAt;
      if (updated) {
        const age = (Date.now() + state.serverOffsetMs - Date.parse(updated)) / 1000;
        $("#status-updated").textContent = `updated ${hhmm(updated)}Z (${ago(age)})`;
        const box = document.getElementById("status");
        const silent = box.classList.contains("running") && age > CONFIG.stale_s;
        box.classList.toggle("stale", silent);
        $("#status-stale").textContent = silent ? `no news from the monitor for ${ago(age).replace(" ago", "")}` : "";
      }
      heartbeatText();
    } catch (error) {
      state.errors += 1;
      state.lastError = String(error);
      connection.className = "connection lost";
      connection.textContent = "connection to the dashboard server lost; retrying…";
    }
    setTimeout(poll, CONFIG.poll_ms);
  }
  poll();
})();
