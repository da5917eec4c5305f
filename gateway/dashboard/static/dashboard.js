/* lakegate metrics dashboard: renders the JSON API under ./api (see gateway/dashboard.py). No build step. */
"use strict";
(() => {
  const ROOT = location.pathname.endsWith("/") ? location.pathname : location.pathname + "/";
  const API = ROOT + "api";
  const MAX_TABLE_ROWS = 2000;
  const EVENT_STATUS = { FAIL_WARN: "WARNING", FAIL_BLOCK: "BLOCKER" };
  const KEYWORDS = new Set(("select from where group by order having limit offset fetch first next rows only join " +
    "left right full inner outer cross natural on using as and or not in is null case when then else end with " +
    "recursive union all distinct intersect except cast try_cast between like escape exists over partition range " +
    "preceding following unbounded current row asc desc nulls last true false values unnest lateral ordinality " +
    "filter window interval array map at time zone date timestamp varchar double bigint integer boolean decimal " +
    "real smallint tinyint char varbinary json uuid some any").split(" "));
  const TOKEN = /(--[^\n]*|\/\*[\s\S]*?(?:\*\/|$))|('(?:[^']|'')*'?)|("(?:[^"]|"")*"?)|(\b\d+(?:\.\d*)?(?:[eE][+-]?\d+)?\b)|([A-Za-z_][A-Za-z0-9_]*)/g;

  const app = {
    lake: null, state: null, sessionId: null, jobId: null, debug: null, tab: "metrics",
    cards: new Map(), lastRun: null, explorerEditor: null, addEditor: null, flash: null,
  };
  const $ = (selector, root = document) => root.querySelector(selector);

  // -- helpers ---------------------------------------------------------------------------------

  function el(tag, attrs = {}, ...children) {
    const node = document.createElement(tag);
    for (const [key, value] of Object.entries(attrs)) {
      if (value === null || value === undefined || value === false) continue;
      if (key === "text") node.textContent = value;
      else if (key === "class") node.className = value;
      else if (key === "dataset") Object.assign(node.dataset, value);
      else if (key.startsWith("on")) node.addEventListener(key.slice(2), value);
      else node.setAttribute(key, value === true ? "" : value);
    }
    for (const child of children.flat()) {
      if (child !== null && child !== undefined && child !== false) node.append(child);
    }
    return node;
  }

  function escapeHtml(text) {
    return text.replace(/[&<>"]/g, (c) => ({ "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;" }[c]));
  }

  async function api(method, path, body) {
    const options = { method, headers: {} };
    if (body !== undefined) {
      options.headers["Content-Type"] = "application/json";
      options.body = JSON.stringify(body);
    }
    const response = await fetch(API + path, options);
    const data = await response.json().catch(() => ({}));
    if (!response.ok) {
      const detail = data.detail || {};
      const error = new Error(typeof detail === "string" ? detail : detail.message || response.statusText);
      error.problems = detail.problems || [];
      throw error;
    }
    return data;
  }

  const sessionPath = (suffix = "") => `/sessions/${encodeURIComponent(app.sessionId)}${suffix}`;
  const jobQuery = () => (app.jobId ? `?job=${encodeURIComponent(app.jobId)}` : "");
  const shortId = (id) => (id && id.length > 12 ? id.slice(0, 8) : id);
  const plural = (n, word) => `${n.toLocaleString()} ${word}${n === 1 ? "" : "s"}`;

  function badge(status) {
    const shown = EVENT_STATUS[status] || status;
    return el("span", { class: `badge s-${shown || "none"}`, text: status || "not evaluated" });
  }

  /** A number as every lakegate page shows it, the same rule as format_number of gateway/metrics/templates.py:
   * integers in full, others to 6 significant digits but never losing integer digits below 1e15. */
  function formatNumber(value) {
    if (Number.isNaN(value)) return "NaN";
    if (!Number.isFinite(value)) return value > 0 ? "Infinity" : "-Infinity";
    if (Number.isInteger(value) && Math.abs(value) < 1e15) return String(value);
    if (value === 0) return "0";
    const magnitude = Math.abs(value);
    if (magnitude >= 1e15 || magnitude < 1e-4) {  // Python's "%.6g": 1.23457e+15, 1e-05
      const [mantissa, exponent] = value.toExponential(5).split("e");
      const digits = mantissa.includes(".") ? mantissa.replace(/0+$/, "").replace(/\.$/, "") : mantissa;
      const power = Number(exponent);
      return `${digits}e${power < 0 ? "-" : "+"}${String(Math.abs(power)).padStart(2, "0")}`;
    }
    const decimals = Math.max(0, 6 - (Math.floor(Math.log10(magnitude)) + 1));
    let text = value.toFixed(decimals);  // a tie rounds away from zero here, to even in Python:
    const exact = value.toFixed(Math.min(100, decimals + 70));  // every digit of the double
    const rest = exact.slice(exact.length - 70);
    const kept = exact.slice(0, exact.length - 70).replace(/\.$/, "");
    if (decimals + 70 <= 100 && /^50*$/.test(rest) && Number(kept.slice(-1)) % 2 === 0) text = kept;
    return text.includes(".") ? text.replace(/0+$/, "").replace(/\.$/, "") : text;
  }

  function display(value) {
    if (value === null || value === undefined) return "NULL";
    if (typeof value === "number") return formatNumber(value);
    if (typeof value === "object") return JSON.stringify(value);
    return String(value);
  }

  function dataTable(columns, rows, limit = MAX_TABLE_ROWS) {
    const head = el("tr", {}, columns.map((c) => el("th", { text: c })));
    const body = rows.slice(0, limit).map((row) => el("tr", {}, row.map((v) => {
      const text = display(v);
      const exact = typeof v === "number" && String(v) !== text ? String(v) : null;  // the full value on hover
      return el("td", { class: v === null ? "null" : typeof v === "number" ? "num" : null, text, title: exact });
    })));
    return el("div", { class: "table-wrap" }, el("table", { class: "data" }, el("thead", {}, head), el("tbody", {}, body)));
  }

  function plot(node, figure) {
    const layout = Object.assign({ autosize: true }, figure.layout || {});
    Plotly.newPlot(node, figure.data || [], layout, { responsive: true, displaylogo: false });
  }

  // -- SQL highlighting and the editor ---------------------------------------------------------

  function offsetOf(text, line, column) {
    if (!line || !column) return -1;
    const lines = text.split("\n");
    let offset = 0;
    for (let i = 0; i < line - 1 && i < lines.length; i++) offset += lines[i].length + 1;
    return offset + column - 1;
  }

  /** HTML of `text` with Trino keywords, functions, strings, numbers and comments coloured, and the
   * token at `errorAt` (a character offset, -1 for none) marked. */
  function highlight(text, errorAt = -1) {
    const parts = [];
    let last = 0;
    const plain = (end) => { if (end > last) parts.push([last, end, null]); };
    for (const m of text.matchAll(TOKEN)) {
      plain(m.index);
      const end = m.index + m[0].length;
      let cls = m[1] ? "hl-com" : m[2] ? "hl-str" : m[3] ? "hl-id" : m[4] ? "hl-num" : "hl-name";
      if (m[5]) {
        if (KEYWORDS.has(m[5].toLowerCase())) cls = "hl-kw";
        else if (/^\s*\(/.test(text.slice(end))) cls = "hl-fn";
      }
      parts.push([m.index, end, cls]);
      last = end;
    }
    plain(text.length);
    let html = "";
    let marked = errorAt < 0;
    for (const [start, end, cls] of parts) {
      const piece = text.slice(start, end);
      if (!marked && errorAt >= start && errorAt < end && !(cls === null && /^\s$/.test(text[errorAt]))) {
        marked = true;
        if (cls) {
          html += `<span class="${cls} hl-err">${escapeHtml(piece)}</span>`;
        } else {
          const at = errorAt - start;
          html += escapeHtml(piece.slice(0, at)) + `<span class="hl-err">${escapeHtml(piece[at])}</span>` +
            escapeHtml(piece.slice(at + 1));
        }
        continue;
      }
      html += cls ? `<span class="${cls}">${escapeHtml(piece)}</span>` : escapeHtml(piece);
    }
    if (!marked) html += '<span class="hl-err"> </span>';
    return html;
  }

  /** A SQL editor in `container`: a textarea over a highlighted copy; Ctrl+Enter calls onRun. */
  function makeEditor(container, { value = "", onRun = null, minRows = 3, label = "SQL query" } = {}) {
    const pre = el("pre", { "aria-hidden": "true" });
    const area = el("textarea", { spellcheck: "false", wrap: "off", autocapitalize: "off", "aria-label": label });
    area.value = value;
    const editor = {
      area, errorAt: -1,
      get value() { return area.value; },
      set value(text) { area.value = text; editor.errorAt = -1; render(); },
      markError(line, column) { editor.errorAt = offsetOf(area.value, line, column); render(); },
    };
    function render() {
      pre.innerHTML = highlight(area.value, editor.errorAt) + "\n";
      area.rows = Math.max(minRows, area.value.split("\n").length + 1);
    }
    area.addEventListener("input", () => { editor.errorAt = -1; render(); });
    area.addEventListener("scroll", () => { pre.scrollTop = area.scrollTop; pre.scrollLeft = area.scrollLeft; });
    area.addEventListener("keydown", (event) => {
      if ((event.ctrlKey || event.metaKey) && event.key === "Enter" && onRun) {
        event.preventDefault();
        onRun();
      } else if (event.key === "Tab" && !event.shiftKey) {
        event.preventDefault();
        area.setRangeText("  ", area.selectionStart, area.selectionEnd, "end");
        render();
      }
    });
    container.replaceChildren(pre, area);
    render();
    return editor;
  }

  function errorBox(error) {
    const where = error.line ? `line ${error.line}, column ${error.column}` : "";
    const which = error.query && error.query !== "query" ? `${error.query}: ` : "";
    return el("div", { class: "error", role: "alert" },
      where || which ? el("span", { class: "where", text: `${which}${where}${where ? ": " : ""}` }) : null,
      error.message,
      error.location ? el("div", { class: "meta", text: `at ${error.location}` }) : null);
  }

  // -- the metrics ------------------------------------------------------------------------------

  function logUrl(name) {
    return `${API}${sessionPath(`/logs/${encodeURIComponent(app.jobId)}/${encodeURIComponent(name)}`)}`;
  }

  // videos: an HTML5 player per file (a GIF as an image); files: a download link per file, with its size
  function filesBody(metric, table) {
    return el("div", { class: "files" }, table.rows.map(([name, bytes, type]) => {
      if (metric.shows === "videos") {
        const media = String(type).startsWith("video/")
          ? el("video", { src: logUrl(name), controls: "", preload: "metadata" })
          : el("img", { src: logUrl(name), alt: name });
        return el("figure", {}, media, el("figcaption", { text: name }));
      }
      return el("p", {}, el("a", { href: logUrl(name), download: name.split("/").pop(), text: name }),
        el("span", { class: "meta", text: ` ${Number(bytes).toLocaleString()} bytes` }));
    }));
  }

  function resultBody(metric, result) {
    if (result.error) return null;
    if (result.table && ["videos", "files"].includes(metric.shows) && app.jobId) return filesBody(metric, result.table);
    if (result.table) return dataTable(result.table.columns, result.table.rows);
    if (result.figure) {
      const timeline = metric.shows === "timeline";
      const height = (result.figure.layout || {}).height;
      const node = el("div", { class: `chart${timeline ? " timeline" : ""}` });
      if (height) node.style.height = `${height}px`;
      node.lgFigure = result.figure;
      return node;
    }
    if (metric.shows === "images") {
      return el("div", { class: "lg-images" }, result.images.map((name) => el("figure", {},
        el("img", { src: logUrl(name), alt: name }),
        el("figcaption", { text: name }))));
    }
    return el("div", { class: "scalar", text: result.text || "" });
  }

  function metricCard(metric) {
    const result = metric.result || { status: null, problems: [], images: [] };
    const card = el("article", { class: "metric", dataset: { metric: metric.name, template: metric.template || "", status: result.status || "" } });
    const errorAt = (which) => result.error && (result.error.query || "query") === which;
    card.append(el("header", {},
      el("h3", { text: metric.name }), badge(result.status),
      el("span", { class: "chip", text: `${metric.type} · ${metric.template || metric.template_type}` }),
      metric.origin !== "config" ? el("span", { class: `chip ${metric.origin}`, text: metric.origin }) : null));
    if (metric.description) card.append(el("p", { class: "desc", text: metric.description }));
    if (metric.units && metric.shows !== "scalar") card.append(el("p", { class: "meta", text: `Units: ${metric.units}` }));
    if (result.error) card.append(errorBox(result.error));
    const body = resultBody(metric, result);
    if (body) card.append(body);
    if (result.problems && result.problems.length) {
      card.append(el("ul", { class: "problems" }, result.problems.map((p) => el("li", { text: p }))));
    }
    if (metric.shows === "table" && result.table) {  // its summary may be its values: the size instead
      card.append(el("p", { class: "meta", text: `${plural(result.table.rows.length, "row")}, ${plural(result.table.columns.length, "column")}` }));
    } else if (result.text && body && !body.classList.contains("scalar")) {
      card.append(el("p", { class: "meta", text: result.text }));
    }

    const details = el("details", { class: "query", open: Boolean(result.error) || metric.origin !== "config" },
      el("summary", { text: `Query${metric.location ? ` (${metric.location.split("/").pop()})` : ""}`, title: metric.location }));
    const holder = el("div", { class: "editor" });
    details.append(holder);
    const editor = makeEditor(holder, { value: metric.query_string, onRun: () => run(), label: `Query of ${metric.name}` });
    if (errorAt("query")) editor.markError(result.error.line, result.error.column);
    if (metric.status) {
      const status = metric.status;
      const at = errorAt("status query") ? offsetOf(status.query_string, result.error.line, result.error.column) : -1;
      const pre = el("pre");
      pre.innerHTML = highlight(status.query_string, at);
      details.append(el("div", { class: "status-check" },
        `Status check: block ${status.block}${status.warn !== null ? `, warn ${status.warn}` : ""}`, pre));
    }
    const timing = el("span", { class: "timing" });
    if (app.lastRun && app.lastRun.name === metric.name) timing.textContent = `ran in ${app.lastRun.ms} ms`;
    else if (result.seconds !== null && result.seconds !== undefined) timing.textContent = `query ${Math.round(result.seconds * 1000)} ms`;
    const runButton = el("button", { type: "button", class: "primary run", text: "Run", title: "Run the query (Ctrl+Enter)" });
    const buttons = el("div", { class: "buttons" }, runButton);
    if (metric.origin !== "config") {
      buttons.append(el("button", {
        type: "button", class: "revert", text: metric.origin === "added" ? "Remove" : "Revert to the config file",
        onclick: () => act(() => api("DELETE", sessionPath(`/metrics/${encodeURIComponent(metric.name)}`) + jobQuery())),
      }));
    }
    buttons.append(timing);
    details.append(buttons);
    card.append(details);

    async function run() {
      runButton.disabled = true;
      const started = performance.now();
      try {
        const state = await api("PUT", sessionPath(`/metrics/${encodeURIComponent(metric.name)}`) + jobQuery(),
          { query_string: editor.value });
        app.lastRun = { name: metric.name, ms: Math.round(performance.now() - started) };
        applyState(state);
      } catch (error) {
        details.querySelector(".error")?.remove();
        holder.before(errorBox({ message: [error.message, ...error.problems].join("\n") }));
      } finally {
        runButton.disabled = false;
      }
    }
    runButton.addEventListener("click", run);
    return card;
  }

  function renderMetrics() {
    const state = app.state;
    const groups = {
      test: $("#test-metrics"), batch: $("#batch-metrics"), "test-scalar": $("#test-scalars"), "batch-scalar": $("#batch-scalars"),
    };
    const seen = new Set();
    for (const metric of state.metrics) {
      const group = metric.type === "test" ? "test" : "batch";
      const ran = app.lastRun && app.lastRun.name === metric.name ? app.lastRun.ms : null;
      const signature = JSON.stringify([metric, group === "test" ? state.job_id : null, ran]);
      let entry = app.cards.get(metric.name);
      if (!entry || entry.signature !== signature) {
        const card = metricCard(metric);
        if (entry) {
          entry.card.querySelectorAll(".chart").forEach((node) => Plotly.purge(node));
          entry.card.replaceWith(card);
        }
        entry = { card, signature, fresh: true };
        app.cards.set(metric.name, entry);
      }
      groups[metric.shows === "scalar" ? `${group}-scalar` : group].append(entry.card);
      seen.add(metric.name);
    }
    for (const [name, entry] of app.cards) {
      if (!seen.has(name)) { entry.card.remove(); app.cards.delete(name); }
    }
    for (const entry of app.cards.values()) {
      if (!entry.fresh) continue;
      entry.fresh = false;
      entry.card.querySelectorAll(".chart").forEach((node) => plot(node, node.lgFigure));
    }
    const job = state.jobs.find((j) => j.job_id === state.job_id);
    const tests = state.metrics.filter((m) => m.type === "test").length;
    $("#test-title").textContent = `Test metrics${job ? ` — ${job.experience_name || "job"} (${shortId(job.job_id)})` : ""}`;
    $("#test-title").hidden = !tests;
    $("#batch-title").hidden = tests === state.metrics.length;
  }

  // -- the rest of the page --------------------------------------------------------------------

  function renderBanner() {
    const config = app.state.config;
    const items = [
      ...config.problems.map((p) => el("div", { class: "problem", text: `Config problem (the last good config is used): ${p}` })),
      ...config.notices.map((n) => el("div", { class: "notice", text: n })),
    ];
    if (app.flash) items.unshift(el("div", { class: "problem", role: "alert", text: app.flash }));
    $("#banner").replaceChildren(...items);
    $("#banner").hidden = !items.length;
  }

  function renderSummary() {
    const s = app.state;
    const config = s.config;
    const edits = config.edited.length + config.added.length;
    const source = s.origin === "stored" ? `stored results from ${s.evaluated_at}` : `evaluated ${s.evaluated_at || ""}${s.seconds ? ` in ${s.seconds} s` : ""}`;
    $("#summary").replaceChildren(
      s.debug ? "Debug session · " : "", "batch ", el("strong", { text: s.batch_id }), " on branch ", el("strong", { text: s.branch }),
      " ", badge(s.status), ` · ${plural(s.jobs.length, "job")} · metrics set `,
      el("strong", { text: s.metrics_set || "(all metrics)" }),
      ` · config ${config.paths.join(", ")}${config.version ? ` (version ${config.version})` : ""}`,
      edits ? ` · ${plural(edits, "session change")} (Export Config to keep them)` : "", ` · ${source} · `,
      el("a", { id: "compare-previous", href: `compare/?${new URLSearchParams({ branch: s.branch, batch: s.batch_id })}`,
        text: "compare with the previous build" }));
  }

  function fillSelect(select, options, value) {
    select.replaceChildren(...options.map(([v, label]) => el("option", { value: v, text: label })));
    select.value = value ?? "";
  }

  function renderPicker() {
    const s = app.state;
    const branches = (app.lake && app.lake.branches) || [];
    fillSelect($("#pick-branch"), branches.map((b) => [b.name, b.name]), s.branch);
    const branch = branches.find((b) => b.name === s.branch);
    fillSelect($("#pick-batch"), (branch ? branch.batches : [{ id: s.batch_id, jobs: [] }]).map((b) =>
      [b.id, `${b.id}${app.debug && app.debug.batch === b.id && app.debug.branch === s.branch ? " (debug)" : ""}`]), s.batch_id);
    const sets = s.metrics_sets.length ? s.metrics_sets.map((n) => [n, n]) : [["", "(all metrics)"]];
    fillSelect($("#pick-set"), sets, s.metrics_set || "");
    fillSelect($("#pick-job"), s.jobs.map((j) => [j.job_id,
      `${j.experience_name || "job"} · ${shortId(j.job_id)} · ${j.conflated_status || "not evaluated"}`]), s.job_id);
    $("#export").href = `${API}${sessionPath("/export")}`;
    fillSelect($("#add-metric select[name=template]"), s.templates.map((t) => [t, t]),
      $("#add-metric select[name=template]").value || "scalar");
  }

  function renderJobs() {
    const s = app.state;
    const names = s.matrix.metrics;
    const head = el("tr", {}, ["Job", "Experience", "Job status", "Metrics status", "Conflated status", ...names].map((c) => el("th", { text: c })));
    const rows = s.matrix.rows.map((job) => el("tr", { class: job.job_id === s.job_id ? "current" : null, dataset: { job: job.job_id } },
      el("td", { class: "job", text: shortId(job.job_id), title: job.job_id, onclick: () => selectJob(job.job_id, "metrics") }),
      el("td", { text: job.experience_name || "" }), el("td", { text: job.job_status || "" }),
      el("td", {}, badge(job.metrics_status)), el("td", {}, badge(job.conflated_status)),
      job.cells.map((cell) => el("td", { title: cell && cell.error ? cell.error : null },
        cell ? [badge(cell.status), " ", cell.error ? "" : cell.text || ""] : "—"))));
    $("#jobs-table").replaceChildren(el("thead", {}, head), el("tbody", {}, rows));
  }

  async function loadEvents() {
    if (!app.jobId) { $("#events").replaceChildren(el("p", { class: "hint", text: "The batch has no jobs." })); return; }
    const { events } = await api("GET", sessionPath(`/events?job=${encodeURIComponent(app.jobId)}`));
    const root = $("#events");
    root.querySelectorAll(".chart").forEach((node) => Plotly.purge(node));
    if (!events.length) { root.replaceChildren(el("p", { class: "hint", text: "This job has no events." })); return; }
    root.replaceChildren(...events.map((event) => {
      const texts = event.metrics.filter((m) => m.type === "scalar" || m.type === "text");
      const box = el("article", { class: "event" },
        el("header", {}, el("span", { class: "time", text: `${(event.timestamp / 1e9).toFixed(3)} s` }),
          el("strong", { text: event.name || event.topic }), event.status ? badge(event.status) : null,
          el("span", { class: "chip", text: event.topic }), event.tags.map((t) => el("span", { class: "chip", text: t }))),
        event.description ? el("p", { class: "desc", text: event.description }) : null,
        texts.length ? dataTable(["Metric", "Type", "Value", "Status", "Description"],
          texts.map((m) => [m.name, m.type, m.value, m.status, m.description])) : null);
      for (const m of event.metrics) {
        if (m.type === "image") {
          const files = Array.isArray(m.value) ? m.value : [m.value];
          box.append(el("div", { class: "lg-images" }, el("p", { class: "meta", text: m.name }), files.map((name) => el("figure", {},
            el("img", { src: logUrl(name), alt: name }),
            el("figcaption", { text: name })))));
        } else if (m.type === "plotly" && m.value && typeof m.value === "object") {
          const node = el("div", { class: "chart" });
          box.append(el("p", { class: "meta", text: m.name }), node);
          node.lgFigure = m.value;
        }
      }
      return box;
    }));
    root.querySelectorAll(".chart").forEach((node) => plot(node, node.lgFigure));
  }

  async function loadTables() {
    const scope = $("#explorer-scope").value;
    const { tables } = await api("GET", sessionPath(`/tables?scope=${scope}${app.jobId ? `&job=${encodeURIComponent(app.jobId)}` : ""}`));
    $("#tables").replaceChildren(...tables.map((table) => el("details", { class: "table-item", dataset: { table: table.name } },
      el("summary", {}, el("code", { text: table.name }), el("span", { class: "count", text: plural(table.rows, "row") })),
      el("button", { type: "button", text: "Query it", onclick: () => {
        const name = /^[a-z_][a-z0-9_]*$/.test(table.name) ? table.name : `"${table.name.replaceAll('"', '""')}"`;
        app.explorerEditor.value = `SELECT * FROM ${name}`;
        runQuery();
      } }),
      el("ul", {}, table.columns.map((c) => el("li", {}, c.name, " ", el("span", { class: "type", text: c.type })))))));
  }

  async function runQuery() {
    const button = $("#explorer-run");
    button.disabled = true;
    try {
      const answer = await api("POST", sessionPath("/query"),
        { sql: app.explorerEditor.value, scope: $("#explorer-scope").value, job: app.jobId });
      if (answer.error) {
        app.explorerEditor.markError(answer.error.line, answer.error.column);
        $("#query-result").replaceChildren(errorBox(answer.error));
        return;
      }
      const shown = answer.rows.length < answer.total ? `, showing the first ${answer.rows.length.toLocaleString()}` : "";
      $("#query-result").replaceChildren(
        el("p", { class: "result-meta", text: `${plural(answer.total, "row")}${shown} · ${Math.round(answer.seconds * 1000)} ms` }),
        dataTable(answer.columns.map((c) => `${c.name} (${c.type})`), answer.rows, answer.limit));
    } catch (error) {
      $("#query-result").replaceChildren(errorBox({ message: error.message }));
    } finally {
      button.disabled = false;
    }
  }

  // -- loading and navigating ------------------------------------------------------------------

  function applyState(state) {
    app.state = state;
    app.sessionId = state.id;
    app.jobId = state.job_id;
    if (state.debug) app.debug = { id: state.id, branch: state.branch, batch: state.batch_id };
    const url = new URL(location.href);
    url.search = "";
    url.searchParams.set("session", state.id);
    if (state.job_id) url.searchParams.set("job", state.job_id);
    history.replaceState(null, "", url);
    renderPicker();
    renderBanner();
    renderSummary();
    renderMetrics();
    renderJobs();
    if (app.tab === "events") loadEvents().catch(showError);
    if (app.tab === "explorer") loadTables().catch(showError);
    document.body.dataset.ready = "true";
  }

  function showError(error) {
    app.flash = [error.message, ...(error.problems || [])].join("\n");
    if (app.state) renderBanner();
    else $("#summary").textContent = app.flash;
  }

  async function act(request) {
    app.flash = null;
    try {
      applyState(await request());
    } catch (error) {
      showError(error);
    }
  }

  function selectJob(jobId, tab) {
    app.jobId = jobId;
    if (tab) showTab(tab);
    act(() => api("GET", sessionPath() + jobQuery()));
  }

  function openBatch(branch, batch, metricsSet) {
    const debug = app.debug;
    if (debug && debug.branch === branch && debug.batch === batch && !metricsSet) {
      app.sessionId = debug.id;
      return act(() => api("GET", sessionPath()));
    }
    return act(() => api("POST", "/sessions", { branch, batch, metrics_set: metricsSet || null }));
  }

  function showTab(name) {
    app.tab = name;
    document.querySelectorAll(".tabs button").forEach((b) => b.classList.toggle("active", b.dataset.tab === name));
    document.querySelectorAll("main > .tab").forEach((t) => { t.hidden = t.id !== `tab-${name}`; });
    if (name === "events") loadEvents().catch(showError);
    if (name === "explorer") loadTables().catch(showError);
    if (name === "metrics") window.dispatchEvent(new Event("resize"));
  }

  function addMetricForm() {
    const form = $("#add-metric");
    app.addEditor = makeEditor($("[data-editor=add-query]", form), { value: "SELECT COUNT(*) FROM metadata", label: "Query of the new metric" });
    $("#add-metric-open").addEventListener("click", () => { form.hidden = false; form.elements.name.focus(); });
    $("#add-metric-cancel").addEventListener("click", () => { form.hidden = true; });
    form.addEventListener("submit", async (event) => {
      event.preventDefault();
      const f = form.elements;
      const body = {
        name: f.name.value, type: f.type.value, template: f.template.value, description: f.description.value,
        units: f.units.value, query_string: app.addEditor.value,
        status: { query_string: f.status_query.value, block: f.block.value, warn: f.warn.value },
      };
      const problem = $(".form-error", form);
      try {
        const state = await api("POST", sessionPath("/metrics") + jobQuery(), body);
        problem.hidden = true;
        form.hidden = true;
        form.reset();
        applyState(state);
      } catch (error) {
        problem.textContent = [error.message, ...error.problems].join("\n");
        problem.hidden = false;
      }
    });
  }

  async function start() {
    addMetricForm();
    app.explorerEditor = makeEditor($("[data-editor=explorer-sql]"), { value: "SELECT * FROM metadata", onRun: runQuery, minRows: 4, label: "Ad hoc SQL" });
    document.querySelectorAll(".tabs button").forEach((b) => b.addEventListener("click", () => showTab(b.dataset.tab)));
    $("#explorer-run").addEventListener("click", runQuery);
    $("#explorer-scope").addEventListener("change", () => loadTables().catch(showError));
    $("#run-all").addEventListener("click", () => act(() => api("POST", sessionPath("/evaluate") + jobQuery())));
    $("#pick-job").addEventListener("change", (e) => selectJob(e.target.value));
    $("#pick-set").addEventListener("change", (e) => openBatch(app.state.branch, app.state.batch_id, e.target.value));
    $("#pick-batch").addEventListener("change", (e) => openBatch(app.state.branch, e.target.value));
    $("#pick-branch").addEventListener("change", (e) => {
      const branch = app.lake.branches.find((b) => b.name === e.target.value);
      if (branch && branch.batches.length) openBatch(branch.name, branch.batches[0].id);
    });
    try {
      app.lake = await api("GET", "/lake");
      const params = new URLSearchParams(location.search);
      app.jobId = params.get("job");
      app.sessionId = params.get("session");
      if (app.sessionId) {
        applyState(await api("GET", sessionPath() + jobQuery()));
        return;
      }
      const branch = app.lake.branches.find((b) => b.name === params.get("branch")) ||
        app.lake.branches.find((b) => b.batches.length);
      if (!branch) { $("#summary").textContent = "The lake has no batches yet: ingest some jobs first."; return; }
      const batch = branch.batches.find((b) => b.id === params.get("batch")) || branch.batches[0];
      await openBatch(branch.name, batch.id, params.get("set"));
    } catch (error) {
      showError(error);
    }
  }

  window.lakegate = { formatNumber };  // the page's number format, which the browser test compares with the report's
  start();
})();
