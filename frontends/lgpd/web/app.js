// The inspection page's script (index.html), served by lgpd at /app.js.
"use strict";
(() => {
  const API = "/api/v1";
  const params = new URLSearchParams(location.search);
  const state = { runs: [], run: params.get("run"), member: params.has("member") ?
                  Number(params.get("member")) : null, front: null, frontGen: -1,
                  lang: null, residuals: null, token: sessionStorage.getItem("lgpd-token") };
  const $ = (id) => document.getElementById(id);
  const SVGNS = "http://www.w3.org/2000/svg";

  function el(tag, attrs, text) {
    const e = tag.startsWith("svg:") ? document.createElementNS(SVGNS, tag.slice(4))
                                     : document.createElement(tag);
    for (const [k, v] of Object.entries(attrs || {})) e.setAttribute(k, v);
    if (text !== undefined) e.textContent = text;
    return e;
  }
  function fmt(v, digits = 3) {
    if (v === null || v === undefined || Number.isNaN(v)) return "\u2013";
    if (typeof v !== "number") return String(v);
    if (v === 0) return "0";
    const a = Math.abs(v);
    return (a < 1e-3 || a >= 1e5) ? v.toExponential(digits - 1) : Number(v.toPrecision(digits)).toString();
  }
  function fmtTime(s) {
    if (!(s >= 0)) return "\u2013";
    if (s < 60) return s.toFixed(1) + " s";
    if (s < 3600) return Math.floor(s / 60) + " min " + Math.round(s % 60) + " s";
    return Math.floor(s / 3600) + " h " + Math.round((s % 3600) / 60) + " min";
  }

  async function api(path, opts = {}, retries = 5) {
    const headers = Object.assign({}, opts.headers || {});
    if (state.token) headers["Authorization"] = "Bearer " + state.token;
    const r = await fetch(API + path, Object.assign({}, opts, { headers }));
    if (r.status === 401) {
      const t = window.prompt("lgpd needs its bearer token:");
      if (t) { state.token = t; sessionStorage.setItem("lgpd-token", t); return api(path, opts); }
    }
    // 503 with Retry-After: lgpd is loading the run's table in the background; ask again.
    const after = Number(r.headers.get("Retry-After"));
    if (r.status === 503 && after > 0 && retries > 0) {
      await new Promise((ok) => setTimeout(ok, Math.min(after, 10) * 1000));
      return api(path, opts, retries - 1);
    }
    return r;
  }
  async function apiJson(path, opts) {
    const r = await api(path, opts);
    let body = null;
    try { body = await r.json(); } catch (e) { body = null; }
    return { ok: r.ok, status: r.status, body };
  }

  // ---- runs list -------------------------------------------------------------------------
  function renderRuns() {
    const tbody = $("runs").querySelector("tbody");
    tbody.textContent = "";
    $("runs").dataset.count = String(state.runs.length);
    $("norun").hidden = state.runs.length > 0;
    for (const r of state.runs) {
      const tr = el("tr", { "data-id": r.id });
      if (r.id === state.run) tr.className = "sel";
      const idc = el("td");
      idc.append(el("div", { class: "mono" }, r.id.slice(0, 8)));
      if (r.name) idc.append(el("div", { class: "muted" }, r.name));
      tr.append(idc);
      const st = el("td");
      st.append(el("span", { class: "badge " + r.status }, r.status));
      const g = r.budget && r.budget.generations;
      if (g) {
        const bar = el("div", { class: "bar" });
        bar.append(el("div", { style: "width:" + Math.min(100, 100 * r.generation / g).toFixed(1) + "%" }));
        st.append(bar);
      }
      tr.append(st);
      tr.append(el("td", { class: "num" }, g ? r.generation + "/" + g : String(r.generation)));
      tr.append(el("td", { class: "num" }, fmt(r.best_error)));
      tr.append(el("td", { class: "num" }, String(r.front_size)));
      const act = el("td");
      if (r.status === "running" || r.status === "queued") {
        const b = el("button", { title: "cancel: stop and keep the front" }, "cancel");
        // Asked first, as delete is: one stray click (or a click a framing page lured) must
        // not end a night's run.
        b.onclick = async (ev) => {
          ev.stopPropagation();
          if (!window.confirm("Cancel run " + r.id + "? It stops after its current generation and keeps its front.")) return;
          await api("/runs/" + r.id + "/cancel", { method: "POST", headers: { "Content-Type": "application/json" } });
          refresh();
        };
        act.append(b);
      }
      const d = el("button", { title: "delete the run and its front", "aria-label": "delete run " + r.id }, "\u2715");
      d.onclick = async (ev) => {
        ev.stopPropagation();
        if (!window.confirm("Delete run " + r.id + " and its front?")) return;
        await api("/runs/" + r.id, { method: "DELETE" });
        if (state.run === r.id) { state.run = null; state.front = null; }
        refresh();
      };
      act.append(" ", d);
      tr.append(act);
      tr.onclick = () => selectRun(r.id);
      tbody.append(tr);
    }
  }

  async function refresh() {
    const r = await apiJson("/runs");
    if (!r.ok || !r.body) { $("clock").textContent = "daemon unreachable (" + r.status + ")"; return; }
    state.runs = r.body.runs;
    $("clock").textContent = "updated " + new Date().toLocaleTimeString();
    if (!state.run && state.runs.length) state.run = state.runs[0].id;
    renderRuns();
    if (state.run) await renderRun();
    document.body.dataset.state = "ready";
  }

  function selectRun(id) {
    if (state.run !== id) { state.run = id; state.member = null; state.front = null; state.frontGen = -1; }
    renderRuns();
    renderRun();
  }

  // ---- one run ---------------------------------------------------------------------------
  async function renderRun() {
    const run = state.runs.find((r) => r.id === state.run);
    $("nodetail").hidden = !!run;
    $("detail").hidden = !run;
    if (!run) return;
    const head = $("runhead");
    head.textContent = "";
    const kv = (k, v, cls) => { const s = el("span"); s.append(el("span", { class: "k" }, k), el("span", { class: cls || "" }, v)); head.append(s); };
    kv("run", run.id, "mono");
    if (run.name) kv("name", run.name);
    const b = el("span", { class: "badge " + run.status }, run.status);
    head.append(b);
    kv("generation", String(run.generation) + (run.budget.generations ? " / " + run.budget.generations : ""));
    kv("evaluations", run.evaluations.toLocaleString());
    kv("elapsed", fmtTime(run.elapsed_s));
    if (run.best && run.best.error) kv("best error", fmt(run.best.error.value, 4));
    if (run.best && run.best.cost) kv("min cost", fmt(run.best.cost.value, 4));
    if (run.best && run.best.discontinuity) kv("min disc.", fmt(run.best.discontinuity.value, 3));
    if (run.checkpoint) kv("checkpoint", "gen " + run.checkpoint.generation);
    if (run.resumes) kv("resumed", run.resumes + "\u00d7");
    if (run.error) head.append(el("span", { class: "err" }, run.error));

    // Refetch the front when its generation moved (or the run finished).
    const wantGen = run.generation * 2 + (run.status === "running" ? 0 : 1);
    if (!state.front || state.frontGen !== wantGen || state.front.lgpd.run !== run.id) {
      const f = await apiJson("/runs/" + run.id + "/front");
      state.front = f.ok ? f.body : null;
      // References still being scored by lgpd: fetch the front again at the next refresh.
      const pending = state.front && Array.isArray(state.front.references) &&
        state.front.references.some((x) => x && x.pending);
      state.frontGen = pending ? -1 : wantGen;
      if (state.front && state.member === null && state.front.members.length) {
        let best = 0;
        state.front.members.forEach((m, i) => { if (m.error < state.front.members[best].error) best = i; });
        state.member = best;
      }
      drawPareto();
      drawMembers();
      drawHistory(run.id);
      if (state.member !== null) await showMember(state.member, false);
    }
  }

  function discColour(d, maxD) {
    if (!(d > 0)) return "#2563eb";
    const t = maxD > 0 ? Math.min(1, d / maxD) : 1;
    // orange -> deep red as discontinuity grows
    const r = Math.round(234 + (153 - 234) * t), g = Math.round(88 + (27 - 88) * t), b = Math.round(12 + (27 - 12) * t);
    return "rgb(" + r + "," + g + "," + b + ")";
  }

  // A reference of the front's "references" (scored like a member: error, cost, ...; or
  // {"name", "expr", "invalid": why} when it did not parse or score). Anything that is not
  // a finite, non-negative error and a finite cost is left off the plot and listed instead.
  function refScore(ref) {
    const r = ref && typeof ref === "object" ? ref : {};
    const pick = (k) => (typeof r[k] === "number" ? r[k] :
      (r.objectives && typeof r.objectives[k] === "number" ? r.objectives[k] : null));
    const name = String(r.name || r.label || r.expression || "reference");
    const error = pick("error"), cost = pick("cost");
    const why = r.invalid ? String(r.invalid)
      : !(Number.isFinite(error) && error >= 0) ? "no finite error"
      : !Number.isFinite(cost) ? "no finite cost" : null;
    return { error, cost, disc: pick("discontinuity") || 0, name, why,
             formula: typeof r.formula === "string" ? r.formula : null, isa: isaText(r),
             cancellation: r.cancellation && typeof r.cancellation === "object" ? r.cancellation : null };
  }

  // The member's whole program as one formula ("A = ...; B = ..."): the front's "formula",
  // or, for fronts stored before it existed, the outputs' expressions joined the same way.
  function formulaOf(m) {
    if (m && typeof m.formula === "string" && m.formula) return m.formula;
    return ((m && m.outputs) || []).map((o) => o.name + " = " + o.expression).join("; ");
  }
  // {bits, flagged} from "cancellation": {"bits_lost", "flagged"}, or null when absent.
  function cancellationOf(m) {
    const c = m && m.cancellation;
    if (!c || typeof c !== "object") return null;
    return { bits: typeof c.bits_lost === "number" ? c.bits_lost : null, flagged: c.flagged === true };
  }
  function cancelBadge(c) {
    const b = el("span", { class: "badge cancel", role: "img",
      "aria-label": "float32 cancellation: " + fmt(c.bits, 3) + " bits lost",
      title: "float32 cancellation: loses " + fmt(c.bits, 3) + " of 24 bits to cancelling terms; fragile on a GPU" },
      "\u26a0 cancellation");
    return b;
  }

  // ---- copy to the clipboard -------------------------------------------------------------
  // navigator.clipboard needs a secure context (https or loopback); elsewhere a hidden
  // textarea and execCommand("copy") do it.
  async function copyText(text) {
    if (navigator.clipboard && window.isSecureContext) {
      try { await navigator.clipboard.writeText(text); return true; } catch (e) { /* fall back */ }
    }
    const active = document.activeElement;
    const ta = el("textarea", { readonly: "", "aria-hidden": "true", tabindex: "-1",
      style: "position:fixed;top:0;left:0;width:1px;height:1px;padding:0;border:0;opacity:0" });
    ta.value = text;
    document.body.append(ta);
    ta.select();
    let ok = false;
    try { ok = document.execCommand("copy"); } catch (e) { ok = false; }
    ta.remove();
    if (active && active.focus) active.focus();
    return ok;
  }
  function wireCopy(button, getText) {
    button.addEventListener("click", async (ev) => {
      ev.stopPropagation();
      const text = getText();
      const ok = !!text && await copyText(text);
      button.textContent = ok ? "copied \u2713" : "copy failed";
      button.classList.toggle("ok", ok);
      button.classList.toggle("fail", !ok);
      $("copystatus").textContent = ok ? "Formula copied to the clipboard" : "Copy failed: select the formula and copy it by hand";
      clearTimeout(button.copyTimer);
      button.copyTimer = setTimeout(() => { button.textContent = "copy"; button.classList.remove("ok", "fail"); }, 1600);
    });
  }
  function copyButton(label, getText) {
    const b = el("button", { type: "button", class: "copy", "aria-label": label, title: "copy the formula" }, "copy");
    wireCopy(b, getText);
    return b;
  }

  function niceTicks(lo, hi, n) {
    const span = hi - lo || 1, step0 = span / n, mag = Math.pow(10, Math.floor(Math.log10(step0)));
    const step = [1, 2, 5, 10].map((m) => m * mag).find((s) => span / s <= n) || 10 * mag;
    const out = [];
    for (let v = Math.ceil(lo / step) * step; v <= hi + 1e-9 * span; v += step) out.push(Number(v.toPrecision(12)));
    return out;
  }

  function drawPareto() {
    const svg = $("pareto");
    svg.textContent = "";
    const f = state.front;
    const members = f ? f.members : [];
    const allRefs = f && Array.isArray(f.references) ? f.references.map(refScore) : [];
    const refs = allRefs.filter((r) => !r.why);
    const badRefs = allRefs.filter((r) => r.why);
    svg.dataset.run = state.run || "";
    svg.dataset.points = String(members.length);
    svg.dataset.references = String(refs.length);
    $("frontinfo").textContent = f ? (members.length + " members" + (f.lgpd.final ? " (final)" : " (live, gen " + f.lgpd.generation + ")")) : "no front yet";
    const ri = $("refinfo");
    ri.textContent = badRefs.length ? badRefs.length + " reference" + (badRefs.length > 1 ? "s" : "") + " not drawn" : "";
    ri.title = badRefs.map((r) => r.name + ": " + r.why).join("\n");
    const W = 560, H = 380, L = 62, R = 14, T = 12, B = 40;
    svg.dataset.plot = [L, T, W - R, H - B].join(" ");
    if (!members.length && !refs.length) {
      svg.append(el("svg:text", { x: W / 2, y: H / 2, "text-anchor": "middle" }, f ? "empty front" : "no front yet"));
      return;
    }
    const pts = members.map((m, i) => ({ i, error: m.error, cost: m.cost, disc: m.discontinuity || 0,
                                          canc: cancellationOf(m) }));
    // The axes span the members and the references alike, so every reference is drawn.
    const all = pts.concat(refs);
    const pos = all.map((p) => p.error).filter((e) => e > 0 && isFinite(e));
    let ylo = pos.length ? Math.log10(Math.min(...pos)) : -1, yhi = pos.length ? Math.log10(Math.max(...pos)) : 0;
    if (yhi - ylo < 0.5) { ylo -= 0.25; yhi += 0.25; }
    ylo = Math.floor(ylo * 4) / 4 - 0.1; yhi = Math.ceil(yhi * 4) / 4 + 0.1;
    const costs = all.map((p) => p.cost).filter((c) => Number.isFinite(c));
    let xhi = Math.max(0, ...costs) * 1.06 || 1, xlo = Math.min(0, ...costs);
    const X = (c) => L + (c - xlo) / (xhi - xlo) * (W - L - R);
    const Y = (e) => T + (yhi - Math.log10(Math.max(e, Math.pow(10, ylo)))) / (yhi - ylo) * (H - T - B);
    const maxD = Math.max(0, ...pts.map((p) => p.disc));
    // grid + axes
    for (let k = Math.ceil(ylo); k <= Math.floor(yhi); k++) {
      svg.append(el("svg:line", { x1: L, x2: W - R, y1: Y(Math.pow(10, k)), y2: Y(Math.pow(10, k)), class: "grid" }));
      svg.append(el("svg:text", { x: L - 6, y: Y(Math.pow(10, k)) + 4, "text-anchor": "end" }, "1e" + k));
    }
    // Minor ticks; labelled too when the plot spans less than two decades.
    const labelMinor = Math.floor(yhi) - Math.ceil(ylo) < 2;
    for (let k = Math.floor(ylo); k <= Math.floor(yhi); k++) {
      for (let m = 2; m < 10; m++) {
        const v = m * Math.pow(10, k), lv = Math.log10(v);
        if (lv <= ylo || lv >= yhi) continue;
        svg.append(el("svg:line", { x1: L - 3, x2: L, y1: Y(v), y2: Y(v), class: "axis" }));
        if (labelMinor && (m === 2 || m === 3 || m === 5 || (yhi - ylo < 0.7)))
          svg.append(el("svg:text", { x: L - 6, y: Y(v) + 4, "text-anchor": "end" }, m + "e" + k));
      }
    }
    for (const c of niceTicks(xlo, xhi, 8)) {
      svg.append(el("svg:line", { x1: X(c), x2: X(c), y1: T, y2: H - B, class: "grid" }));
      svg.append(el("svg:text", { x: X(c), y: H - B + 15, "text-anchor": "middle" }, String(c)));
    }
    svg.append(el("svg:line", { x1: L, x2: W - R, y1: H - B, y2: H - B, class: "axis" }));
    svg.append(el("svg:line", { x1: L, x2: L, y1: T, y2: H - B, class: "axis" }));
    svg.append(el("svg:text", { x: (L + W - R) / 2, y: H - 6, "text-anchor": "middle" },
      "cost (" + ((f && f.cost_model) || "model") + ")"));
    svg.append(el("svg:text", { x: 14, y: (T + H - B) / 2, "text-anchor": "middle",
      transform: "rotate(-90 14 " + (T + H - B) / 2 + ")" }, "error (" + ((f && f.config && f.config.objectives && f.config.objectives.error) || "rmse") + ", log)"));
    // staircase through the front
    const sorted = pts.filter((p) => p.error > 0).sort((a, b) => a.cost - b.cost);
    if (sorted.length > 1) {
      let d = "M" + X(sorted[0].cost) + " " + Y(sorted[0].error);
      for (let k = 1; k < sorted.length; k++) d += " H" + X(sorted[k].cost) + " V" + Y(sorted[k].error);
      svg.append(el("svg:path", { d, fill: "none", stroke: "#93c5fd", "stroke-width": 1.2 }));
    }
    // references
    for (const r of refs) {
      const x = Number(X(r.cost).toFixed(2)), y = Number(Y(r.error).toFixed(2)), s = 6;
      const g = el("svg:g", { class: "refmark", "data-x": x, "data-y": y, "data-name": r.name });
      g.append(el("svg:path", { d: "M" + x + " " + (y - s) + " L" + (x + s) + " " + y + " L" + x + " " + (y + s) + " L" + (x - s) + " " + y + " Z", class: "ref" }));
      // The name goes to the right of the marker, or to its left near the right edge.
      const label = r.name.length > 28 ? r.name.slice(0, 27) + "\u2026" : r.name;
      const left = x + 8 + 6.2 * label.length > W - R;
      g.append(el("svg:text", { x: left ? x - 8 : x + 8, y: y < T + 14 ? y + 16 : y - 6,
        "text-anchor": left ? "end" : "start", style: "fill:#c026d3" }, label));
      let tip = r.name + "\nerror " + fmt(r.error, 4) + ", cost " + fmt(r.cost, 4) +
        (r.isa !== "-" ? ", measured " + r.isa + " instructions" : "");
      if (r.formula) tip += "\n" + r.formula;
      if (r.cancellation && r.cancellation.flagged) tip += "\n\u26a0 float32 cancellation: " + fmt(r.cancellation.bits_lost, 3) + " bits lost";
      g.append(el("svg:title", {}, tip));
      svg.append(g);
    }
    // members
    for (const p of pts) {
      const x = X(p.cost), y = Y(p.error), fill = discColour(p.disc, maxD);
      const shape = p.disc > 0
        ? el("svg:path", { d: "M" + x + " " + (y - 6) + " L" + (x + 5.5) + " " + (y + 4) + " L" + (x - 5.5) + " " + (y + 4) + " Z" })
        : el("svg:circle", { cx: x, cy: y, r: 4.8 });
      shape.setAttribute("fill", fill);
      shape.setAttribute("class", "pt" + (p.i === state.member ? " sel" : ""));
      shape.setAttribute("data-member", String(p.i));
      shape.append(el("svg:title", {}, "#" + p.i + "  error " + fmt(p.error, 4) + "  cost " + fmt(p.cost, 4) + "  disc " + fmt(p.disc, 3)));
      shape.addEventListener("click", () => showMember(p.i, true));
      if (p.canc && p.canc.flagged) {
        svg.append(el("svg:circle", { cx: x, cy: y, r: 8.5, class: "cancring" }));
        shape.firstChild.textContent += "  \u26a0 cancellation " + fmt(p.canc.bits, 3) + " bits";
      }
      svg.append(shape);
    }
  }

  // Measured instructions of a member or reference per family ("14/15/14"), or "-" (gpu_cost.hpp).
  function measuredFamilies() {
    const info = state.front && state.front.cost_measured_info;
    return info && Array.isArray(info.families) ? info.families : [];
  }
  function isaText(m) {
    const fams = measuredFamilies();
    if (!fams.length || !m || !m.cost_measured || m.cost_measured.error) return "-";
    return fams.map((f) => (m.cost_measured[f] ? fmt(m.cost_measured[f].instructions, 4) : "-")).join("/");
  }

  // ---- the members as a list -------------------------------------------------------------
  function drawMembers() {
    const table = $("members"), tbody = table.querySelector("tbody");
    tbody.textContent = "";
    const members = state.front ? state.front.members : [];
    table.dataset.rows = String(members.length);
    $("isahead").textContent = measuredFamilies().length ? "ISA " + measuredFamilies().join("/") : "ISA";
    const order = members.map((m, i) => i).sort((a, b) => (members[a].cost - members[b].cost) || (a - b));
    for (const i of order) {
      const m = members[i], text = formulaOf(m), c = cancellationOf(m);
      const tr = el("tr", { "data-index": String(i) });
      if (i === state.member) tr.className = "sel";
      tr.append(el("td", { class: "num" }, String(i)), el("td", { class: "num" }, fmt(m.error, 4)),
        el("td", { class: "num" }, fmt(m.cost, 4)), el("td", { class: "num isa" }, isaText(m)),
        el("td", { class: "num" }, fmt(m.discontinuity, 3)));
      const flags = el("td");
      if (c && c.flagged) flags.append(cancelBadge(c));
      tr.append(flags);
      tr.append(el("td", { class: "formula", title: text, "data-formula": text }, text));
      const act = el("td");
      act.append(copyButton("copy the formula of member " + i, () => text));
      tr.append(act);
      tr.tabIndex = 0;
      tr.onclick = () => showMember(i, true);
      tr.onkeydown = (ev) => {
        if (ev.target === tr && (ev.key === "Enter" || ev.key === " ")) { ev.preventDefault(); showMember(i, true); }
      };
      tbody.append(tr);
    }
  }

  async function drawHistory(id) {
    const svg = $("history");
    const r = await apiJson("/runs/" + id + "/history");
    svg.textContent = "";
    if (!r.ok) return;
    const rows = r.body.history.filter((h) => h.best_error !== null && h.best_error > 0);
    if (rows.length < 2) { svg.append(el("svg:text", { x: 280, y: 50, "text-anchor": "middle", style: "font:11px sans-serif;fill:#66707c" }, "not enough history yet")); return; }
    const W = 560, H = 90, L = 62, R = 14, T = 6, B = 18;
    const g0 = rows[0].generation, g1 = Math.max(g0 + 1, rows[rows.length - 1].generation);
    const es = rows.map((h) => Math.log10(h.best_error));
    let lo = Math.min(...es), hi = Math.max(...es);
    if (hi - lo < 0.1) { lo -= 0.05; hi += 0.05; }
    const X = (g) => L + (g - g0) / (g1 - g0) * (W - L - R);
    const Y = (e) => T + (hi - Math.log10(e)) / (hi - lo) * (H - T - B);
    let d = "";
    rows.forEach((h, k) => { d += (k ? " L" : "M") + X(h.generation).toFixed(1) + " " + Y(h.best_error).toFixed(1); });
    svg.append(el("svg:path", { d, fill: "none", stroke: "#2563eb", "stroke-width": 1.5 }));
    for (const h of r.body.history.filter((h) => h.event === "resumed" || h.event === "checkpoint"))
      svg.append(el("svg:line", { x1: X(h.generation), x2: X(h.generation), y1: T, y2: H - B,
        stroke: h.event === "resumed" ? "#b45309" : "#d1d5db", "stroke-dasharray": "2 2" }));
    const t = (x, y, s, a) => svg.append(el("svg:text", { x, y, "text-anchor": a, style: "font:10px sans-serif;fill:#66707c" }, s));
    t(L - 6, T + 8, fmt(Math.pow(10, hi)), "end"); t(L - 6, H - B, fmt(Math.pow(10, lo)), "end");
    t(L, H - 4, "gen " + g0, "start"); t(W - R, H - 4, "gen " + g1, "end");
  }

  // ---- one member ------------------------------------------------------------------------
  async function showMember(k, userClick) {
    const f = state.front;
    if (!f || k === null || k < 0 || k >= f.members.length) return;
    state.member = k;
    if (userClick) {
      const u = new URL(location.href);
      u.searchParams.set("run", state.run); u.searchParams.set("member", String(k));
      history.replaceState(null, "", u);
    }
    for (const p of $("pareto").querySelectorAll(".pt"))
      p.classList.toggle("sel", Number(p.dataset.member) === k);
    for (const tr of $("members").querySelectorAll("tbody tr"))
      tr.classList.toggle("sel", Number(tr.dataset.index) === k);
    const m = f.members[k];
    $("member").dataset.member = String(k);
    $("memberhint").hidden = true;
    $("memberbody").hidden = false;
    const head = $("memberhead");
    head.textContent = "";
    head.append(el("b", {}, "#" + k + "  "),
      el("span", { class: "muted" }, "error "), el("span", {}, fmt(m.error, 5) + "   "),
      el("span", { class: "muted" }, "cost "), el("span", {}, fmt(m.cost, 4) + "   "),
      el("span", { class: "muted" }, "measured "), el("span", { id: "memberisa" }, isaText(m) + "   "),
      el("span", { class: "muted" }, "discontinuity "), el("span", {}, fmt(m.discontinuity, 3)));
    const c = cancellationOf(m);
    if (c && c.flagged) head.append("   ", cancelBadge(c));
    else if (c && c.bits !== null) head.append(el("span", { class: "muted" }, "   cancellation " + fmt(c.bits, 2) + " bits"));
    // The whole program as one formula, one statement a line; copy takes the exact text.
    const text = formulaOf(m);
    const fe = $("formula");
    fe.textContent = "";
    fe.dataset.formula = text;
    for (const stmt of text.split("; ")) fe.append(el("span", { class: "stmt" }, stmt));
    $("copyformula").setAttribute("aria-label", "copy the formula of member " + k);
    const fitted = (m.outputs || []).filter((o) => o.transform && o.transform !== "none");
    $("transforms").textContent = fitted.length ? "fitted as " + fitted.map((o) => o.transform + " for " + o.name).join(", ") : "";
    // Each output's own text (its temporaries, then its expression), when the front has both.
    const ex = $("exprs");
    ex.textContent = "";
    $("exprsec").hidden = !(typeof m.formula === "string" && m.formula);
    for (const o of m.outputs || []) {
      ex.append(el("div", { class: "muted", style: "margin-top:6px" }, o.name + " ="));
      ex.append(el("div", { class: "expr" }, o.expression));
    }
    const t = $("metrics");
    t.textContent = "";
    const keys = ["rmse", "max_abs", "mae", "mean_rel", "r2"];
    const hr = el("tr"); hr.append(el("th", {}, "output / path"));
    for (const key of keys) hr.append(el("th", { class: "num" }, key));
    t.append(hr);
    for (const o of m.outputs || []) for (const path of ["float32", "double"]) {
      if (!o[path]) continue;
      const tr = el("tr"); tr.append(el("td", {}, o.name + " \u00b7 " + path));
      for (const key of keys) tr.append(el("td", { class: "num" }, fmt(o[path][key], 4)));
      t.append(tr);
    }
    if (m.cost_by_target) {
      const tr = el("tr"); tr.append(el("td", { colspan: 6, class: "muted" },
        "cost by target: " + Object.entries(m.cost_by_target).map(([a, b]) => a + " " + fmt(b, 4)).join(", ")));
      t.append(tr);
    }
    if (m.cost_measured && !m.cost_measured.error) {
      const info = state.front.cost_measured_info || {};
      const tr = el("tr"); tr.append(el("td", { colspan: 6, class: "muted", id: "measured" },
        "measured (" + (info.emitted || "") + "; instructions / latency / VGPRs): " +
        measuredFamilies().filter((f) => m.cost_measured[f]).map((f) => f + " " +
          fmt(m.cost_measured[f].instructions, 4) + "/" + fmt(m.cost_measured[f].latency, 4) + "/" +
          fmt(m.cost_measured[f].vgprs, 4)).join(", ")));
      t.append(tr);
    }
    await showCode();
    await showResiduals();
  }

  async function showCode() {
    const pre = $("code");
    pre.dataset.lang = state.lang;
    for (const b of $("langs").querySelectorAll("button")) b.classList.toggle("on", b.dataset.lang === state.lang);
    const r = await api("/runs/" + state.run + "/front/" + state.member + "/code?lang=" + state.lang);
    const text = await r.text();
    if (r.ok) { pre.textContent = text; return; }
    let msg = text;
    try { msg = JSON.parse(text).error; } catch (e) { /* plain text */ }
    pre.textContent = "// " + state.lang + " unavailable: " + msg;
  }
  wireCopy($("copyformula"), () => $("formula").dataset.formula);
  // One tab per language the daemon exports (GET /languages: lgp::emit::allLanguages).
  async function buildLangTabs() {
    const r = await apiJson("/languages");
    const langs = r.ok && Array.isArray(r.body.languages) ? r.body.languages : [];
    const tabs = $("langs");
    tabs.replaceChildren();
    for (const l of langs) {
      const b = el("button", { "data-lang": String(l.name) }, String(l.title));
      b.addEventListener("click", () => { state.lang = b.dataset.lang; showCode(); });
      tabs.append(b);
    }
    if (langs.length && !langs.some((l) => l.name === state.lang)) state.lang = String(langs[0].name);
  }

  async function showResiduals() {
    const f = state.front;
    const inputs = f && f.table && f.table.inputs;
    const two = Array.isArray(inputs) && inputs.length === 2;
    $("heatsec").hidden = !two;
    $("heatmap").dataset.cells = "0";
    if (!two) return;
    const r = await apiJson("/runs/" + state.run + "/front/" + state.member + "/residuals");
    if (!r.ok) { $("heatinfo").textContent = (r.body && r.body.error) || "residuals unavailable"; return; }
    state.residuals = r.body;
    const sel = $("heatout");
    const prev = sel.value;
    sel.textContent = "";
    r.body.outputs.forEach((o, i) => sel.append(el("option", { value: String(i) }, o.name)));
    if (prev && Number(prev) < r.body.outputs.length) sel.value = prev;
    drawHeat();
  }
  $("heatout").addEventListener("change", drawHeat);

  function diverging(t) {  // t in [-1, 1]: blue - white - red
    const a = Math.min(1, Math.abs(t));
    const c = t < 0 ? [37, 99, 235] : [220, 38, 38];
    return [255 + (c[0] - 255) * a, 255 + (c[1] - 255) * a, 255 + (c[2] - 255) * a].map(Math.round);
  }

  function drawHeat() {
    const res = state.residuals;
    if (!res) return;
    const o = res.outputs[Number($("heatout").value || 0)];
    const [nx, ny] = res.inputs;
    const xs = res.columns[nx], ys = res.columns[ny], e = o.residual;
    const ux = [...new Set(xs)].sort((a, b) => a - b), uy = [...new Set(ys)].sort((a, b) => a - b);
    const cv = $("heat"), ctx = cv.getContext("2d");
    const S = 300;
    ctx.clearRect(0, 0, S, S);
    let emax = 0;
    for (const v of e) if (v !== null && isFinite(v)) emax = Math.max(emax, Math.abs(v));
    const gridded = ux.length * uy.length <= xs.length * 1.05 && ux.length > 1 && uy.length > 1;
    const x0 = ux[0], x1 = ux[ux.length - 1], y0 = uy[0], y1 = uy[uy.length - 1];
    const px = (x) => (x1 > x0 ? (x - x0) / (x1 - x0) : 0.5), py = (y) => (y1 > y0 ? (y - y0) / (y1 - y0) : 0.5);
    const ix = new Map(ux.map((v, i) => [v, i])), iy = new Map(uy.map((v, i) => [v, i]));
    let cells = 0;
    for (let k = 0; k < e.length; k++) {
      const v = e[k];
      const [r, g, b] = v === null ? [120, 120, 120] : diverging(emax > 0 ? v / emax : 0);
      ctx.fillStyle = "rgb(" + r + "," + g + "," + b + ")";
      if (gridded) {
        const cw = S / ux.length, ch = S / uy.length;
        ctx.fillRect(ix.get(xs[k]) * cw, S - (iy.get(ys[k]) + 1) * ch, Math.ceil(cw), Math.ceil(ch));
      } else {
        ctx.fillRect(px(xs[k]) * (S - 4), S - 4 - py(ys[k]) * (S - 4), 4, 4);
      }
      cells++;
    }
    $("heatmap").dataset.cells = String(cells);
    const bar = $("heatbar"), bc = bar.getContext("2d");
    bc.clearRect(0, 0, 60, 300);
    for (let i = 0; i < 280; i++) {
      const [r, g, b] = diverging(1 - 2 * i / 279);
      bc.fillStyle = "rgb(" + r + "," + g + "," + b + ")";
      bc.fillRect(0, 10 + i, 14, 1);
    }
    bc.fillStyle = "#1d232b"; bc.font = "10px sans-serif";
    bc.fillText("+" + fmt(emax, 2), 17, 16); bc.fillText("0", 17, 153); bc.fillText("\u2212" + fmt(emax, 2), 17, 292);
    $("heatinfo").textContent = nx + " \u2192 (" + fmt(x0) + " \u2026 " + fmt(x1) + "),  " + ny + " \u2191 (" +
      fmt(y0) + " \u2026 " + fmt(y1) + "),  " + res.rows + " rows" + (res.stride > 1 ? " (every " + res.stride + "th)" : "") +
      ",  rmse " + fmt(o.rmse, 3) + ", max |e| " + fmt(o.max_abs, 3) + (o.transform !== "none" ? ", original scale" : "");
  }

  // ---- submit ----------------------------------------------------------------------------
  $("submitbtn").addEventListener("click", async () => {
    const msg = $("submitmsg");
    msg.className = ""; msg.textContent = "submitting\u2026";
    const r = await apiJson("/runs", { method: "POST", headers: { "Content-Type": "application/json" }, body: $("cfgtext").value });
    if (r.ok) { msg.textContent = "queued " + r.body.id; state.run = r.body.id; state.member = null; state.front = null; refresh(); }
    else { msg.className = "err"; msg.textContent = (r.body && r.body.error) || ("HTTP " + r.status); }
  });

  buildLangTabs().then(() => { refresh(); setInterval(refresh, 2000); });
})();
