// The service's pages: the caller's jobs (data-page="jobs") and one job (data-page="job").
// Every request goes to this server's /v1 API with the caller's API key (kept in the tab's
// sessionStorage once entered) in the X-API-Key header; the job's events are read from a
// streamed fetch (an EventSource cannot send that header). Text from the server is always set
// as text, never as HTML.
"use strict";

const KEY_STORAGE = "trajopt-api-key";
const ROOT = location.pathname.replace(/\/ui(\/.*)?$/, "");
const ACTIVE = new Set(["queued", "running"]);

function authHeaders() {
  const key = sessionStorage.getItem(KEY_STORAGE);
  return key ? { "X-API-Key": key } : {};
}

class ApiError extends Error {
  constructor(status, code, message) {
    super(message);
    this.status = status;
    this.code = code;
  }
}

async function apiError(response) {
  let code = "http_" + response.status;
  let message = response.statusText || "request failed";
  try {
    const body = await response.json();
    if (body && body.error) {
      code = body.error.code;
      message = body.error.message;
    }
  } catch (ignored) {
    // not a JSON error body: keep the status line
  }
  return new ApiError(response.status, code, message);
}

async function api(path, options = {}) {
  const response = await fetch(ROOT + path, {
    ...options,
    headers: { ...authHeaders(), ...(options.headers || {}) },
  });
  if (!response.ok) {
    throw await apiError(response);
  }
  return response;
}

async function getJson(path) {
  return (await api(path)).json();
}

function el(tag, text, attributes = {}) {
  const node = document.createElement(tag);
  if (text !== undefined && text !== null) {
    node.textContent = String(text);
  }
  for (const [name, value] of Object.entries(attributes)) {
    node.setAttribute(name, value);
  }
  return node;
}

function fmt(value) {
  if (value === null || value === undefined) {
    return "–";
  }
  if (typeof value === "boolean") {
    return value ? "yes" : "no";
  }
  if (typeof value !== "number") {
    return String(value);
  }
  if (value === 0) {
    return "0";
  }
  const size = Math.abs(value);
  if (size >= 1e6 || size < 1e-3) {
    return value.toExponential(4);
  }
  return String(parseFloat(value.toPrecision(6)));
}

function seconds(value) {
  return typeof value === "number" ? value.toFixed(3) : "–";
}

function say(text, kind = "") {
  const message = document.getElementById("message");
  message.textContent = text;
  message.className = kind;
}

function showKeyForm() {
  const form = document.getElementById("key-form");
  form.replaceChildren();
  const label = el("label", "API key ", { for: "api-key" });
  const input = el("input", null, { id: "api-key", type: "password", autocomplete: "off" });
  const save = el("button", "use this key", { type: "button" });
  save.addEventListener("click", () => {
    sessionStorage.setItem(KEY_STORAGE, input.value.trim());
    location.reload();
  });
  form.append(label, input, save);
  form.hidden = false;
}

function reportError(error) {
  if (error instanceof ApiError && error.status === 401) {
    showKeyForm();
  }
  const text = error instanceof ApiError ? `${error.code}: ${error.message}` : String(error);
  say(text, "error");
}

async function download(path, filename) {
  try {
    const blob = await (await api(path)).blob();
    const url = URL.createObjectURL(blob);
    const anchor = el("a", null, { href: url, download: filename });
    document.body.append(anchor);
    anchor.click();
    anchor.remove();
    setTimeout(() => URL.revokeObjectURL(url), 10000);
  } catch (error) {
    reportError(error);
  }
}

function downloadLink(text, path, filename) {
  const link = el("a", text, { href: ROOT + path });
  link.addEventListener("click", (event) => {
    event.preventDefault();
    download(path, filename);
  });
  return link;
}

// --- the list of jobs --------------------------------------------------------------------

// A job's method; for auto, the method it runs or chose ("auto → foh-ptr").
function methodText(job) {
  const chosen = job.progress && job.progress.method;
  return job.method === "auto" && chosen ? `auto → ${chosen}` : job.method;
}

async function jobsPage() {
  const body = document.querySelector("#jobs tbody");
  const more = document.getElementById("more");
  let offset = 0;
  async function load() {
    const page = await getJson(`/v1/jobs?limit=50&offset=${offset}`);
    for (const job of page.items) {
      const row = el("tr");
      const link = el("a", job.id, { href: `jobs/${encodeURIComponent(job.id)}` });
      const cell = el("td");
      cell.append(link);
      row.append(cell);
      row.append(el("td", job.status, { class: "status-" + job.status }));
      row.append(el("td", methodText(job)));
      row.append(el("td", job.scenario || "–"));
      row.append(el("td", job.created_at));
      row.append(el("td", fmt(job.progress ? job.progress.iteration : null)));
      row.append(el("td", fmt(job.solve_s)));
      body.append(row);
    }
    offset = page.next_offset === null ? null : page.next_offset;
    more.hidden = offset === null;
    say(page.total === 0 ? "no jobs yet" : `${page.total} job(s)`);
  }
  more.addEventListener("click", () => load().catch(reportError));
  await load();
  await batchList();
}

function countsText(counts) {
  return Object.entries(counts)
    .map(([status, count]) => `${count} ${status}`)
    .join(", ");
}

async function batchList() {
  const body = document.querySelector("#batches tbody");
  const page = await getJson("/v1/batches?limit=50");
  for (const batch of page.items) {
    const row = el("tr");
    const cell = el("td");
    cell.append(el("a", batch.id, { href: `batches/${encodeURIComponent(batch.id)}` }));
    row.append(cell, el("td", batch.name || "–"), el("td", batch.kind));
    row.append(el("td", batch.status, { class: "status-" + batch.status }));
    row.append(el("td", countsText(batch.counts)), el("td", batch.created_at));
    body.append(row);
  }
}

// --- one batch ---------------------------------------------------------------------------

const BATCH_COLUMNS = [
  ["status", "status"],
  ["failure_code", "failure"],
  ["objective", "objective"],
  ["final_latitude_deg", "final lat (deg)"],
  ["final_longitude_deg", "final lon (deg)"],
  ["heat_rate_ratio", "heat / limit"],
  ["load_factor_ratio", "load / limit"],
  ["iterations", "iterations"],
  ["optimization_s", "optimization s"],
];

function showChildren(summary) {
  const head = document.querySelector("#children thead tr");
  head.replaceChildren(el("th", "child"));
  for (const path of summary.parameters) {
    head.append(el("th", path));
  }
  for (const [, label] of BATCH_COLUMNS) {
    head.append(el("th", label));
  }
  const body = document.querySelector("#children tbody");
  body.replaceChildren();
  for (const row of summary.rows) {
    const tr = el("tr");
    const cell = el("td");
    cell.append(el("a", row.index, { href: `../jobs/${encodeURIComponent(row.job_id)}` }));
    tr.append(cell);
    for (const path of summary.parameters) {
      const value = row.parameters[path];
      tr.append(el("td", typeof value === "object" && value !== null ? JSON.stringify(value) : fmt(value)));
    }
    for (const [key] of BATCH_COLUMNS) {
      tr.append(el("td", fmt(row[key]), key === "status" ? { class: "status-" + row.status } : {}));
    }
    body.append(tr);
  }
}

async function batchPage() {
  const batchId = decodeURIComponent(location.pathname.split("/").filter(Boolean).pop());
  document.getElementById("batch-id").textContent = batchId;
  document.title = `trajopt - batch ${batchId}`;
  const base = `/v1/batches/${encodeURIComponent(batchId)}`;
  for (;;) {
    const summary = await getJson(`${base}/summary`);
    const batch = summary.batch;
    document.getElementById("name").textContent = batch.name || "–";
    document.getElementById("kind").textContent = batch.kind;
    document.getElementById("status").textContent = batch.status;
    document.getElementById("status").className = "status-" + batch.status;
    document.getElementById("counts").textContent = `${batch.size}: ${countsText(batch.counts)}`;
    showChildren(summary);
    if (batch.status !== "running") {
      break;
    }
    say("running: refreshed every 2 s");
    await new Promise((resolve) => setTimeout(resolve, 2000));
  }
  document.getElementById("links").replaceChildren(
    downloadLink("summary CSV", `${base}/summary.csv`, `${batchId}-summary.csv`),
    " · ",
    downloadLink("summary JSON", `${base}/summary`, `${batchId}-summary.json`),
  );
  const blob = await (await api(`${base}/plot.png`)).blob();
  const figure = el("figure", null, { "data-plot": "batch" });
  figure.append(el("img", null, { alt: "batch plot", src: URL.createObjectURL(blob), width: "800", height: "500" }));
  document.getElementById("plots").replaceChildren(figure);
  document.getElementById("figures").hidden = false;
  say("finished");
}

// --- one job -----------------------------------------------------------------------------

function stateChangeText(change) {
  if (change === null || change === undefined) {
    return "–";
  }
  if (typeof change === "number") {
    return fmt(change);
  }
  return Object.entries(change)
    .map(([name, value]) => `${name} ${fmt(value)}`)
    .join("; ");
}

function showStatus(status) {
  document.getElementById("status").textContent = status;
  document.getElementById("status").className = "status-" + status;
}

function showJob(job) {
  showStatus(job.status);
  document.getElementById("method").textContent = methodText(job);
  const progress = job.progress || {};
  document.getElementById("phase").textContent = progress.phase || "waiting";
  document.getElementById("iteration").textContent = fmt(progress.iteration);
  document.getElementById("failure").textContent = job.error
    ? `${job.error.code}: ${job.error.message}`
    : "–";
}

function addIteration(table, seen, record) {
  const key = `${record.attempt}:${record.iteration}`;
  if (seen.has(key)) {
    return;
  }
  seen.add(key);
  const row = el("tr");
  row.append(el("td", record.iteration));
  row.append(el("td", fmt(record.cost)));
  row.append(el("td", stateChangeText(record.max_state_change)));
  row.append(el("td", fmt(record.virtual_control_norm)));
  row.append(el("td", record.conic_status || "–"));
  table.append(row);
  document.getElementById("iteration").textContent = fmt(record.iteration);
}

function parseBlock(block) {
  let event = "message";
  const data = [];
  for (const line of block.split(/\r?\n/)) {
    if (line === "" || line.startsWith(":")) {
      continue;
    }
    const colon = line.indexOf(":");
    const field = colon < 0 ? line : line.slice(0, colon);
    let value = colon < 0 ? "" : line.slice(colon + 1);
    if (value.startsWith(" ")) {
      value = value.slice(1);
    }
    if (field === "event") {
      event = value;
    } else if (field === "data") {
      data.push(value);
    }
  }
  return data.length ? { event, data: JSON.parse(data.join("\n")) } : null;
}

async function readEvents(path, onEvent) {
  const response = await api(path, { headers: { Accept: "text/event-stream" } });
  const reader = response.body.getReader();
  const decoder = new TextDecoder();
  let buffer = "";
  for (;;) {
    const { value, done } = await reader.read();
    if (done) {
      return false;
    }
    buffer += decoder.decode(value, { stream: true });
    for (;;) {
      const match = /\r?\n\r?\n/.exec(buffer);
      if (!match) {
        break;
      }
      const block = buffer.slice(0, match.index);
      buffer = buffer.slice(match.index + match[0].length);
      const parsed = parseBlock(block);
      if (parsed && onEvent(parsed.event, parsed.data)) {
        await reader.cancel();
        return true;
      }
    }
  }
}

async function followJob(base, table) {
  const seen = new Set();
  let attempt = null;
  for (;;) {
    const ended = await readEvents(`${base}/events`, (event, data) => {
      if (event === "iteration") {
        if (attempt !== null && data.attempt !== attempt) {
          table.replaceChildren(); // a new attempt starts its history again
        }
        attempt = data.attempt;
        showStatus("running"); // a page opened while the job was queued sees it start here
        addIteration(table, seen, data);
      } else if (event === "phase") {
        document.getElementById("phase").textContent = data.phase;
      } else if (event === "end") {
        showJob(data);
        return true;
      }
      return false;
    });
    if (ended) {
      return;
    }
    const job = await getJson(base); // the stream closed early: reconnect if still active
    showJob(job);
    if (!ACTIVE.has(job.status)) {
      return;
    }
    await new Promise((resolve) => setTimeout(resolve, 1000));
  }
}

function checkRow(table, name, value, bound, within) {
  const row = el("tr", null, { class: within === false ? "fail" : "pass" });
  row.append(el("td", name), el("td", value), el("td", bound));
  row.append(el("td", within === null || within === undefined ? "–" : within ? "pass" : "fail"));
  table.append(row);
}

function showVerification(verification) {
  const section = document.getElementById("checks");
  const table = document.querySelector("#verification tbody");
  table.replaceChildren();
  if (!verification) {
    document.getElementById("verdict").textContent = "not verified (no trajectory, or stopped)";
    section.hidden = false;
    return;
  }
  document.getElementById("verdict").textContent = verification.feasible
    ? "feasible: the propagated controls meet every check"
    : "NOT feasible: see the failed checks";
  checkRow(table, "reached the end", fmt(verification.reached_end), "yes", verification.reached_end);
  for (const [name, check] of Object.entries(verification.terminal_error_vs_target || {})) {
    checkRow(table, `terminal ${name} (${check.kind})`, fmt(check.error), fmt(check.tolerance), check.within);
  }
  for (const [name, peak] of Object.entries(verification.path_maxima || {})) {
    const ratio = peak.ratio === null || peak.ratio === undefined ? "" : ` (${fmt(peak.ratio)} of the limit)`;
    checkRow(table, `peak ${name}`, fmt(peak.max) + ratio, fmt(peak.limit), peak.within);
  }
  const zoneTolerance = (verification.tolerances || {}).no_fly_zone_deg;
  for (const [index, zone] of (verification.no_fly_zones || []).entries()) {
    checkRow(
      table,
      `no-fly zone ${zone.name || index} clearance (deg)`,
      fmt(zone.min_clearance_deg),
      `≥ −${fmt(zoneTolerance)}`,
      zone.within,
    );
  }
  for (const [name, peak] of Object.entries(verification.control_limits || {})) {
    if (peak) {
      checkRow(table, `flown ${name}`, fmt(peak.max), fmt(peak.limit), peak.within);
    }
  }
  section.hidden = false;
}

async function showPlots(base) {
  const names = await getJson(`${base}/plots`);
  const holder = document.getElementById("plots");
  holder.replaceChildren();
  for (const name of names) {
    const figure = el("figure", null, { "data-plot": name });
    const blob = await (await api(`${base}/plots/${name}.png`)).blob();
    const image = el("img", null, { alt: name, src: URL.createObjectURL(blob), width: "800", height: "500" });
    const caption = el("figcaption", `${name} `);
    caption.append(downloadLink("PNG", `${base}/plots/${name}.png`, `${name}.png`), " · ");
    caption.append(downloadLink("SVG", `${base}/plots/${name}.svg`, `${name}.svg`));
    figure.append(image, caption);
    holder.append(figure);
  }
  document.getElementById("figures").hidden = names.length === 0;
}

async function showResult(base, jobId) {
  let result;
  try {
    result = await getJson(`${base}/result`);
  } catch (error) {
    if (error instanceof ApiError && error.status === 409) {
      say(error.message); // finished without a result (e.g. cancelled before it started)
      return;
    }
    throw error;
  }
  const objective = result.objective;
  document.getElementById("objective").textContent = objective
    ? `${objective.name} ${fmt(objective.value)} ${objective.units || ""}`
    : "–";
  const timing = result.timing || {};
  document.getElementById("timing").textContent =
    `optimization ${seconds(timing.wall_s)} s (conic ${seconds(timing.conic_solve_s)} s), ` +
    `verification ${seconds(timing.verification_s)} s, ${fmt(timing.iterations)} iterations`;
  if (result.failure) {
    const failure = document.getElementById("failure");
    failure.textContent = `${result.failure.code}: ${result.failure.message}`;
    const advice = result.failure.advice || [];
    if (advice.length) {
      const list = el("ul", null, { id: "advice" });
      for (const hint of advice) {
        list.append(el("li", `try: ${hint}`));
      }
      failure.append(list);
    }
  }
  const links = document.getElementById("links");
  links.replaceChildren(
    downloadLink("result JSON", `${base}/result`, `${jobId}-result.json`),
    " · ",
    downloadLink("history JSON", `${base}/history`, `${jobId}-history.json`),
  );
  if (result.trajectory) {
    links.append(" · ", downloadLink("trajectory CSV", `${base}/trajectory.csv`, `${jobId}-trajectory.csv`));
  }
  if (result.trajectory || result.history) {
    showVerification(result.verification);
  }
  const table = document.querySelector("#progress tbody");
  if (table.children.length === 0) {
    const seen = new Set();
    for (const record of result.history || []) {
      addIteration(table, seen, record);
    }
  }
  document.getElementById("live").open = false; // the plots and checks come first now
  await showPlots(base);
  say(`finished ${result.status}`);
}

async function jobPage() {
  const jobId = decodeURIComponent(location.pathname.split("/").filter(Boolean).pop());
  document.getElementById("job-id").textContent = jobId;
  document.title = `trajopt - job ${jobId}`;
  const base = `/v1/jobs/${encodeURIComponent(jobId)}`;
  const job = await getJson(base);
  showJob(job);
  const table = document.querySelector("#progress tbody");
  if (ACTIVE.has(job.status)) {
    say("running: progress arrives live");
    await followJob(base, table);
  }
  await showResult(base, jobId);
}

document.addEventListener("DOMContentLoaded", () => {
  const pages = { jobs: jobsPage, job: jobPage, batch: batchPage };
  const run = pages[document.body.dataset.page];
  run().catch(reportError);
});
