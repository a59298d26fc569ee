// The operator's page: wiring of the mission, the live stream, the views and the replay.
import { api, ApiError, ViewStream } from "./client.js";
import { SideView, TopView, Trail } from "./map.js";
import {
  clearFieldErrors, fieldErrors, influenceRadius, parseMission, renderForm, showFieldErrors,
} from "./mission.js";
import { eventLevel, eventWords } from "./words.js";

const $ = (id) => document.getElementById(id);
const ACTIVE = new Set(["starting", "running"]);
const MAX_EVENTS_SHOWN = 300;

const state = {
  doc: null, // the mission document being planned (the form edits it)
  fileName: null,
  storedId: null, // the service's id for `doc` as last stored
  missionDirty: false, // edited since stored (needs a new POST /missions)
  obstaclesDirty: false, // obstacles edited since stored (PUT …/obstacles)
  plan: null, // POST …/plan's answer for storedId
  frame: null, // the last view frame
  missions: new Map(), // id → mission document, for frames of other missions
  runId: null, // the run the live view shows
  events: [], // its events
  seen: new Set(),
  notResponding: new Set(),
  trails: new Map(),
  selected: null,
  paused: false,
  mode: "live", // or "replay"
  replay: null,
};

const perf = { frames: 0, draws: 0, drawMs: 0, drawMaxMs: 0, messages: 0 };

// Views ---------------------------------------------------------------------------------
const top = new TopView($("map"), {
  onPlace: placeObstacle,
  onZoneDrawn: addDrawnZone,
  onObstacleEdit: editObstacle,
  onSelect: (i) => {
    state.selected = i;
    highlightObstacleRow();
  },
});
const side = new SideView($("profile"));

function withGeometry(o, limits) {
  const keepOut = limits ? o.radius + limits.safe_distance_obstacle : null;
  return {
    center_m: o.center,
    radius_m: o.radius,
    keep_out_m: keepOut,
    influence_m: limits && keepOut ? influenceRadius(limits.v_max, limits.max_yaw_rate, keepOut) : null,
  };
}

/** A mission document's zones in ICS metres, as the service's frames give them (zones
 * given in lat/lon only come drawn from the service, which converts them). */
function docZones(doc) {
  const point = (p) => Array.isArray(p) && p.length === 2 && p.every(Number.isFinite);
  const height = (h) => (Number.isFinite(h) ? h : null);
  return (Array.isArray(doc && doc.zones) ? doc.zones : []).flatMap((z) => {
    if (!z || typeof z !== "object") return [];
    const band = {
      name: typeof z.name === "string" ? z.name : null, kind: z.kind, inclusion: z.inclusion === true,
      floor_m: height(z.floor), ceiling_m: height(z.ceiling),
    };
    if (z.kind === "cylinder" && point(z.center) && Number.isFinite(z.radius) && z.radius > 0) {
      return [{ ...band, center_m: z.center, radius_m: z.radius }];
    }
    if (z.kind === "polygon" && Array.isArray(z.vertices) && z.vertices.length >= 3 && z.vertices.every(point)) {
      return [{ ...band, vertices_m: z.vertices }];
    }
    return [];
  });
}

function missionOf(id) {
  if (id === null || id === undefined) return null;
  if (id === state.storedId && state.doc) return state.doc;
  if (!state.missions.has(id)) {
    state.missions.set(id, null);
    api("GET", `/missions/${id}`).then((m) => state.missions.set(id, m.mission)).catch(() => state.missions.delete(id));
  }
  return state.missions.get(id);
}

/** What the views draw now, live or replayed. */
function buildScene() {
  if (state.mode === "replay") return replayScene();
  const f = state.frame;
  const run = f && f.run;
  const active = run && ACTIVE.has(run.state);
  const own = state.doc && (!f || f.mission_id === null || f.mission_id === state.storedId) && (!active || f.mission_id === state.storedId);
  const doc = own ? state.doc : missionOf(f && f.mission_id);
  const limits = doc && doc.limits && typeof doc.limits === "object" ? doc.limits : null;
  const valid = (o) => o && Array.isArray(o.center) && o.center.length === 3 && o.center.every(Number.isFinite) && Number.isFinite(o.radius) && o.radius > 0;
  const obstacles = own
    ? (Array.isArray(doc.obstacles) ? doc.obstacles : []).filter(valid).map((o) => withGeometry(o, limits))
    : (f ? f.obstacles : []);
  const vehicles = (f ? f.vehicles : []).map((v) => ({ ...v, notResponding: state.notResponding.has(v.id) }));
  const shownRunning = run && run.state && run.state !== "pending";
  const starts = own && !shownRunning && Array.isArray(doc.vehicles)
    ? doc.vehicles.filter((v) => Array.isArray(v.position) && v.position.every(Number.isFinite))
        .map((v) => ({ id: v.id, role: v.role, pos: v.position, yaw: Number(v.yaw) || 0 }))
    : [];
  const served = f && Array.isArray(f.zones) && (!own || (f.mission_id === state.storedId && !state.missionDirty));
  return {
    obstacles,
    zones: served ? f.zones : (own ? docZones(doc) : []),
    target_m: own ? (Array.isArray(doc.target) && doc.target.every(Number.isFinite) ? doc.target : null) : f && f.target_m,
    route: validRoute(own ? doc.route : f && f.route),
    leg: run && run.leg ? run.leg.index : null,
    turnPoint: run && run.leg && Array.isArray(run.leg.turn_point_m) ? run.leg.turn_point_m : null,
    accuracy_m: limits ? limits.target_accuracy : 10,
    ground: doc ? doc.ground : null,
    limits,
    starts,
    plan: own && state.plan ? state.plan.trajectories : null,
    vehicles: vehicles.filter((v) => v.pos_m),
    trails: state.trails,
    selected: own ? state.selected : null,
    editable: Boolean(own),
    run,
  };
}

// Redrawn when something changed (a frame, the pointer, a key, a resize, the replay
// clock), and at least every REDRAW_MS; otherwise an animation frame costs nothing.
const REDRAW_MS = 250;
let dirty = true;
let lastDraw = 0;
const touch = () => (dirty = true);

const currentScene = () => (state.paused && state.frozen ? state.frozen : buildScene());

/** Zooms the view the user is about to see: one still waiting to be framed (a mission just
 * read, before the next frame is drawn) is framed first, so a quick key is not undone. */
function zoomBy(factor) {
  if (!top.fitted) top.scene = currentScene();
  top.zoom(factor);
  touch();
}

function draw() {
  requestAnimationFrame(draw);
  const t0 = performance.now();
  perf.frames += 1;
  if (state.mode === "replay") replayAdvance(t0);
  if (!dirty && t0 - lastDraw < REDRAW_MS) return;
  dirty = false;
  lastDraw = t0;
  const scene = currentScene();
  top.scene = scene;
  side.scene = scene;
  top.draw();
  side.draw();
  const ms = performance.now() - t0;
  perf.draws += 1;
  perf.drawMs += ms;
  perf.drawMaxMs = Math.max(perf.drawMaxMs, ms);
}

// Live stream ---------------------------------------------------------------------------
const stream = new ViewStream(onFrame, onConnection);
let lastTableUpdate = 0;

function onFrame(f) {
  perf.messages += 1;
  dirty = true;
  if (f.type !== "frame") return;
  const runId = f.run ? f.run.run_id : null;
  if (runId !== state.runId) {
    state.runId = runId;
    state.events = [];
    state.seen.clear();
    state.notResponding.clear();
    for (const t of state.trails.values()) t.clear();
    if (state.mode === "live") renderEvents();
  }
  for (const e of f.events || []) addEvent(e);
  if (state.paused) {
    state.frame = f;
    return;
  }
  state.frame = f;
  if (f.run && ACTIVE.has(f.run.state)) {
    for (const v of f.vehicles) {
      if (!v.pos_m) continue;
      let t = state.trails.get(v.id);
      if (!t) state.trails.set(v.id, (t = new Trail()));
      t.push(v.pos_m[0], v.pos_m[1], v.pos_m[2]);
    }
  }
  if (state.mode === "live") updateHeader(buildScene());
  const now = performance.now();
  if (now - lastTableUpdate > 500) {
    lastTableUpdate = now;
    updateVehicleTable(f);
    updateButtons();
  }
}

function onConnection(kind, words, recovered) {
  const pill = $("conn");
  pill.dataset.state = kind;
  pill.textContent = { live: "connected", lost: "connection lost", connecting: "connecting…" }[kind];
  pill.title = words;
  if (kind === "lost") banner(words, "bad");
  else if (kind === "live" && recovered) {
    banner(words, "ok", 8000);
    refreshLinks();
    refreshRuns();
  } else if (kind === "live") banner("");
}

let bannerTimer = null;
function banner(text, kind, hideAfterMs) {
  const b = $("banner");
  clearTimeout(bannerTimer);
  b.textContent = text;
  b.dataset.kind = kind || "";
  b.hidden = !text;
  if (hideAfterMs) bannerTimer = setTimeout(() => (b.hidden = true), hideAfterMs);
}

function addEvent(e) {
  const key = `${e.run_id}|${e.mission_time_s}|${e.kind}|${e.vehicle_id}|${JSON.stringify(e.detail)}`;
  if (state.seen.has(key)) return;
  state.seen.add(key);
  if (e.kind === "vehicle_not_responding") state.notResponding.add(e.vehicle_id);
  if (e.kind === "vehicle_responding") state.notResponding.delete(e.vehicle_id);
  state.events.push(e);
  if (state.mode === "live") prependEvent(e);
}

function eventItem(e) {
  const li = document.createElement("li");
  li.dataset.level = eventLevel(e.kind);
  li.dataset.kind = e.kind;
  const t = document.createElement("time");
  t.textContent = e.mission_time_s === null || e.mission_time_s === undefined ? "" : `${e.mission_time_s.toFixed(1)} s`;
  const s = document.createElement("span");
  s.textContent = eventWords(e);
  li.append(t, s);
  return li;
}

function prependEvent(e) {
  const list = $("events");
  list.prepend(eventItem(e));
  while (list.children.length > MAX_EVENTS_SHOWN) list.lastChild.remove();
}

function renderEvents() {
  const list = $("events");
  list.replaceChildren(...state.events.slice(-MAX_EVENTS_SHOWN).reverse().map(eventItem));
  $("events-scope").textContent = state.runId ? `(run #${state.runId})` : "";
}

const m = (v) => (v === null || v === undefined ? "–" : `${v.toFixed(1)} m`);

function nowSeparation(vehicles) {
  let best = null;
  const live = vehicles.filter((v) => v.pos_m && !v.lost && v.role !== "other");
  for (let i = 0; i < live.length; i++) {
    for (let j = i + 1; j < live.length; j++) {
      const a = live[i].pos_m, b = live[j].pos_m;
      const d = Math.hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]);
      if (best === null || d < best) best = d;
    }
  }
  return best;
}

function nowClearance(vehicles, obstacles) {
  let best = null;
  for (const v of vehicles) {
    if (!v.pos_m || v.lost || v.role === "other") continue;
    for (const o of obstacles) {
      const c = o.center_m;
      const d = Math.hypot(v.pos_m[0] - c[0], v.pos_m[1] - c[1], v.pos_m[2] - c[2]) - o.radius_m;
      if (best === null || d < best) best = d;
    }
  }
  return best;
}

function updateHeader(scene) {
  const run = scene.run;
  const pill = $("run-state");
  pill.dataset.state = run ? run.state : "none";
  pill.textContent = run ? `mission ${run.mission_id}: ${run.state}` : "no run";
  pill.title = run && run.outcome ? run.outcome : "";
  const loiter = run && run.leg && run.leg.loiter && run.leg.loiter.on_circle
    ? `, loitering ${run.leg.loiter.turns_flown.toFixed(1)}${run.leg.loiter.turns ? `/${run.leg.loiter.turns}` : ""} turns` : "";
  const leg = run && run.leg && run.leg.of > 1 ? ` · leg ${run.leg.index + 1}/${run.leg.of}${loiter}` : "";
  $("mission-time").textContent = run && run.mission_time_s !== undefined ? `${run.mission_time_s.toFixed(1)} s${leg}` : "–";
  const lim = scene.limits;
  const active = run && ACTIVE.has(run.state);
  const sepNow = active ? nowSeparation(scene.vehicles) : null;
  const clrNow = active ? nowClearance(scene.vehicles, scene.obstacles) : null;
  const sepMin = run ? run.min_separation_m : null;
  const clrMin = run ? run.min_obstacle_clearance_m : null;
  const safeSep = lim ? lim.safe_distance_uav : null;
  const safeClr = lim ? lim.safe_distance_obstacle : null;
  $("sep").textContent = `${m(sepNow)} / ${m(sepMin)}${safeSep ? ` (safe ${safeSep})` : ""}`;
  $("clr").textContent = `${m(clrNow)} / ${m(clrMin)}${safeClr ? ` (safe ${safeClr})` : ""}`;
  const below = (v, safe) => v !== null && v !== undefined && safe !== null && v < safe;
  $("fig-sep").classList.toggle("alarm", below(sepNow, safeSep) || below(sepMin, safeSep));
  $("fig-clr").classList.toggle("alarm", below(clrNow, safeClr) || below(clrMin, safeClr));
  $("violations").textContent = run && run.safety_violations !== undefined ? String(run.safety_violations) : "–";
  $("violations").parentElement.classList.toggle("alarm", Boolean(run && run.safety_violations));
  const rate = active && run.tick_rate ? run.tick_rate : null;
  $("tick-rate").textContent = rate ? `${rate.measured_hz === null ? "–" : rate.measured_hz.toFixed(1)} / ${rate.target_hz} Hz${rate.overrunning ? " (over its period)" : ""}` : "–";
  $("fig-rate").classList.toggle("alarm", Boolean(rate && rate.overrunning));
  showFormation(run && run.formation);
}

// The formation flown (the status's "formation", or a stored run's summary figures).
function formationText(f) {
  if (!f) return "–";
  const pct = (x) => (x === null || x === undefined ? "" : `, ${(100 * x).toFixed(0)} % in formation`);
  const worst = f.worst_error_m === null || f.worst_error_m === undefined ? "" :
    ` worst ${f.worst_error_m.toFixed(1)} m (≤ ${f.accuracy_m})`;
  if (f.formed === undefined) {  // a stored summary: figures only
    return f.time_to_form_s === null ? "never formed" :
      `formed at ${f.time_to_form_s.toFixed(1)} s${pct(f.fraction_in_formation)}, longest hold ${f.longest_hold_s.toFixed(1)} s`;
  }
  if (f.formed) return `formed${worst}, held ${f.current_hold_s.toFixed(0)} s${pct(f.fraction_in_formation)}`;
  const before = f.time_to_form_s === null ? "" : ` (formed at ${f.time_to_form_s.toFixed(1)} s)`;
  return `not formed${worst}${before}`;
}

function showFormation(f) {
  const el = $("formation");
  el.textContent = formationText(f);
  el.parentElement.dataset.formed = f && f.formed ? "yes" : "no";
  state.slotErrors = new Map(((f && f.wingmen) || []).map((w) => [w.id, w]));
}

// A wingman's slot error as the service's formation watch measures it (Eq. 6 from the
// reported positions); the plan's distance to its local target when there is no run.
function slotError(v) {
  const w = state.slotErrors && state.slotErrors.get(v.id);
  if (w) return `${w.slot_error_m.toFixed(1)} m${w.within ? " ✓" : ""}`;
  const d = v.local_target_distance_m;
  return d === null || d === undefined ? "–" : `${d.toFixed(1)} m`;
}

// The keep-out nearest a vehicle (the mission's obstacles[j] or zones[k]) and its clearance
// now, as the service's monitor measures it from the reported positions.
function nearestKeepOut(v) {
  if (!v.nearest_keep_out) return "–";
  return `${v.nearest_keep_out} ${v.clearance_m === null ? "" : `${v.clearance_m.toFixed(0)} m`}`.trim();
}

function updateVehicleTable(f) {
  const body = $("vehicles-table").tBodies[0];
  const rows = f.vehicles.map((v) => [
    v.id, v.role, v.mode ?? "–", v.armed ? "armed" : "disarmed", v.link_id,
    v.lost ? "LOST" : `${v.seconds_since_heard.toFixed(1)} s ago`,
    state.notResponding.has(v.id) ? "not responding" : v.ppf_state ?? "–",
    v.pos_m ? v.pos_m.map((c) => c.toFixed(0)).join(", ") : "–",
    v.speed_m_s === null ? "–" : `${v.speed_m_s.toFixed(1)} m/s`,
    slotError(v),
    nearestKeepOut(v),
  ]);
  while (body.rows.length > rows.length) body.deleteRow(-1);
  rows.forEach((cells, i) => {
    const tr = body.rows[i] || body.insertRow();
    tr.dataset.vehicle = String(cells[0]);
    while (tr.cells.length < cells.length) tr.insertCell();
    cells.forEach((c, k) => {
      const text = String(c);
      if (tr.cells[k].textContent !== text) tr.cells[k].textContent = text;
    });
  });
}

// The mission: load, validate, edit, preview, start, abort --------------------------------
function message(text, kind) {
  const el = $("load-message");
  el.textContent = text;
  el.dataset.kind = kind || "";
}

function showErrors(detail, prefix, what) {
  const errors = fieldErrors(detail, prefix);
  const loose = showFieldErrors($("mission-form"), errors);
  const box = $("mission-errors");
  box.replaceChildren();
  const p = document.createElement("p");
  p.textContent = `The service refused ${what}: ${errors.length} problem(s)` +
    (errors.length > loose.length ? ", shown next to the fields below." : ".");
  box.append(p);
  if (loose.length) {
    const ul = document.createElement("ul");
    for (const e of loose) {
      const li = document.createElement("li");
      li.textContent = e.path ? `${e.path}: ${e.message}` : e.message;
      ul.append(li);
    }
    box.append(ul);
  }
}

function clearErrors() {
  $("mission-errors").replaceChildren();
  clearFieldErrors($("mission-form"));
}

function renderMission() {
  renderForm($("mission-form"), state.doc, onFieldChange, deleteObstacle);
  highlightObstacleRow();
  updateButtons();
}

async function loadFile(file) {
  let text;
  try {
    text = await file.text();
  } catch (err) {
    message(`Could not read ${file.name}: ${err.message}`, "bad");
    return;
  }
  let doc;
  try {
    doc = parseMission(text, file.name);
  } catch (err) {
    message(err.message, "bad");
    return;
  }
  state.doc = doc;
  state.fileName = file.name;
  state.storedId = null;
  state.missionDirty = true;
  state.obstaclesDirty = false;
  state.plan = null;
  state.selected = null;
  $("plan-metrics").replaceChildren();
  clearErrors();
  renderMission();
  top.fitted = false;
  message(`Read ${file.name}; checking it with the service…`);
  await store();
}

/** Sends the document (or only its obstacles) to the service; true when it is stored. */
async function store() {
  if (!state.doc) return false;
  if (!state.missionDirty && !state.obstaclesDirty && state.storedId) return true;
  clearErrors();
  if (!state.missionDirty && state.obstaclesDirty && state.storedId) {
    try {
      const m = await api("PUT", `/missions/${state.storedId}/obstacles`, state.doc.obstacles || []);
      state.obstaclesDirty = false;
      state.doc = m.mission;
      renderMission();
      message(`Obstacles of mission #${m.id} replaced (${m.mission.obstacles.length}).`, "ok");
      return true;
    } catch (err) {
      reportApiError(err, "obstacles", "the obstacles");
      return false;
    }
  }
  try {
    const m = await api("POST", "/missions", state.doc);
    state.storedId = m.id;
    state.doc = m.mission;
    state.missionDirty = state.obstaclesDirty = false;
    state.missions.set(m.id, m.mission);
    renderMission();
    message(`Valid: stored as mission #${m.id} "${m.name}" (${m.vehicle_ids.length} vehicles, ${m.mission.obstacles.length} obstacles${(m.mission.zones || []).length ? `, ${m.mission.zones.length} zones` : ""}).`, "ok");
    stream.view(m.id);
    return true;
  } catch (err) {
    reportApiError(err, "", "the mission");
    return false;
  }
}

function reportApiError(err, prefix, what) {
  if (err instanceof ApiError && (err.status === 422 || err.status === 400)) {
    showErrors(err.detail, prefix, what);
    message(`Not valid: see the ${what === "the mission" ? "fields" : "obstacles"} marked in red.`, "bad");
  } else {
    message(err.message, "bad");
  }
}

function onFieldChange(path, kind) {
  if (kind === "obstacles") state.obstaclesDirty = true;
  else state.missionDirty = true;
  staleEdit();
}

function staleEdit() {
  if (state.plan) {
    state.plan = null;
    $("plan-metrics").replaceChildren();
  }
  const run = state.frame && state.frame.run;
  const running = run && ACTIVE.has(run.state) && state.frame.mission_id === state.storedId;
  message(running
    ? "Edited: press Validate to send the obstacles to the running mission."
    : "Edited: Validate or Preview plan sends it to the service again.");
  updateButtons();
}

function placeObstacle(x, y) {
  setPlacing(false);
  if (!state.doc) return;
  const z = Array.isArray(state.doc.target) ? Number(state.doc.target[2]) || 0 : 0;
  const radius = Math.max(50, Math.round(25 / top.view.scale / 50) * 50); // 25 px, in 50 m
  state.doc.obstacles = Array.isArray(state.doc.obstacles) ? state.doc.obstacles : [];
  state.doc.obstacles.push({ center: [Math.round(x), Math.round(y), z], radius, velocity: [0, 0, 0] });
  state.selected = state.doc.obstacles.length - 1;
  state.obstaclesDirty = true;
  renderMission();
  staleEdit();
}

/** A no-fly polygon drawn on the map (its corners in ICS m; null: cancelled): added to the
 * stored mission by the service (a running one keeps out of it from its next tick), or to
 * the document being edited. */
async function addDrawnZone(corners) {
  showDrawing(false);
  if (!corners || !state.doc) return;
  const zone = {
    kind: "polygon",
    name: `drawn ${(state.doc.zones || []).length + 1}`,
    vertices: corners.map(([x, y]) => [Math.round(x), Math.round(y)]),
  };
  if (state.storedId && !state.missionDirty) {
    try {
      const m = await api("POST", `/missions/${state.storedId}/zones`, { zones: [zone] });
      state.doc = m.mission;
      state.missions.set(m.id, m.mission);
      renderMission();
      message(`No-fly zone "${zone.name}" added to mission #${m.id}${isRunning() ? ": the run keeps out of it from its next tick" : ""}.`, "ok");
    } catch (err) {
      message(`The zone was not added: ${err.message}`, "bad");
    }
    return;
  }
  state.doc.zones = Array.isArray(state.doc.zones) ? state.doc.zones : [];
  state.doc.zones.push(zone);
  state.missionDirty = true;
  renderMission();
  staleEdit();
}

function editObstacle(index, patch, done) {
  const o = state.doc && state.doc.obstacles && state.doc.obstacles[index];
  if (!o) return;
  if (patch.center) o.center = patch.center.map((c) => Math.round(c));
  if (patch.radius) o.radius = Math.round(patch.radius);
  state.obstaclesDirty = true;
  if (done) {
    renderMission();
    const previewed = Boolean(state.plan);
    staleEdit();
    if (previewed && !isRunning()) preview(); // re-plan around the moved obstacle
  }
}

function deleteObstacle(index) {
  if (!state.doc || !state.doc.obstacles || !state.doc.obstacles[index]) return;
  state.doc.obstacles.splice(index, 1);
  state.selected = null;
  state.obstaclesDirty = true;
  renderMission();
  staleEdit();
}

// The route's waypoints that can be drawn (a document being edited may hold others).
function validRoute(route) {
  return (Array.isArray(route) ? route : []).filter((w) => w && Array.isArray(w.position) &&
    w.position.length === 3 && w.position.every(Number.isFinite));
}

function highlightObstacleRow() {
  document.querySelectorAll("#obstacle-table tbody tr").forEach((tr) => {
    tr.classList.toggle("selected", Number(tr.dataset.index) === state.selected);
  });
}

function isRunning() {
  const run = state.frame && state.frame.run;
  return Boolean(run && ACTIVE.has(run.state));
}

async function preview() {
  if (!(await store())) return;
  const id = state.storedId;
  message(`Planning mission #${id} offline…`);
  $("btn-preview").disabled = true;
  try {
    const plan = await api("POST", `/missions/${id}/plan?every_s=0.5`);
    if (id !== state.storedId || state.missionDirty || state.obstaclesDirty) return; // edited meanwhile
    state.plan = plan;
    showMetrics(plan.metrics);
    message(`Plan of mission #${id}: ${plan.metrics.reached ? "the leader reaches the target" : "the leader does NOT reach the target"}.`, plan.metrics.reached ? "ok" : "bad");
    top.fitted = false;
  } catch (err) {
    message(err.message, "bad");
  } finally {
    updateButtons();
  }
}

function showMetrics(mt) {
  const s = (v, unit = "", digits = 1) => (v === null || v === undefined ? "never" : `${Number(v).toFixed(digits)}${unit}`);
  const lim = state.doc.limits || {};
  const rows = [
    ["leader reaches target", mt.reached ? "yes" : "no"],
    ["flight time", s(mt.flight_time_s, " s")],
    ["formation formed at", s(mt.formation_time_s, " s")],
    ["min separation", `${s(mt.min_separation_m, " m")} (safe ${lim.safe_distance_uav ?? "?"})`],
    ["min obstacle clearance", `${s(mt.min_obstacle_clearance_m, " m")} (safe ${lim.safe_distance_obstacle ?? "?"})`],
    ["collisions", String(mt.collisions)],
    ["speed range", `${s(mt.min_speed_m_s)}–${s(mt.max_speed_m_s, " m/s")}`],
    ["max pitch / yaw rate", `${s(mt.max_pitch_rate_rad_s, "", 3)} / ${s(mt.max_yaw_rate_rad_s, " rad/s", 3)}`],
    ["max accel / decel", `${s(mt.max_accel_m_s2)} / ${s(mt.max_decel_m_s2, " m/s²")}`],
    ["planning wall time", s(mt.planning_wall_time_s * 1000, " ms")],
  ];
  const table = document.createElement("table");
  table.className = "grid metrics";
  table.id = "metrics-table";
  for (const [k, v] of rows) {
    const tr = table.insertRow();
    tr.insertCell().textContent = k;
    tr.insertCell().textContent = v;
  }
  const bad = (mt.collisions > 0) || (mt.min_separation_m < lim.safe_distance_uav) || (mt.min_obstacle_clearance_m < lim.safe_distance_obstacle);
  table.dataset.safe = bad ? "no" : "yes";
  const h = document.createElement("h3");
  h.textContent = "Offline plan (metrics.json)";
  $("plan-metrics").replaceChildren(h, table);
}

async function start() {
  if (!(await store())) return;
  const id = state.storedId;
  const launch = async (query) => {
    const st = await api("POST", `/missions/${id}/start${query}`);
    message(`Mission #${id} started (run #${st.run_id}): launching the vehicles.`, "ok");
    stream.view(id);
    top.fitted = false;
  };
  try {
    await launch("");
  } catch (err) {
    // a vehicle inside a keep-out or far from its start: the operator may start as they are
    const misplaced = err.status === 409 && String(err.detail).includes("from_where_they_are");
    if (misplaced && window.confirm(`${err.detail}.\n\nStart from where the vehicles are?`)) {
      try {
        await launch("?from_where_they_are=true");
      } catch (again) {
        message(again.message, "bad");
      }
    } else {
      message(err.status === 409 ? `Cannot start: ${err.detail}.` : err.message, "bad");
    }
  }
  updateButtons();
}

async function resume() {
  const id = state.frame && state.frame.run && state.frame.run.mission_id;
  if (!id) return;
  try {
    const st = await api("POST", `/missions/${id}/resume`);
    message(`Mission #${id} resumed (run #${st.run_id}): taking the vehicles back.`, "ok");
  } catch (err) {
    message(err.status === 409 ? `Cannot resume: ${err.detail}.` : err.message, "bad");
  }
  updateButtons();
}

async function abort() {
  const id = state.frame && state.frame.run && state.frame.run.mission_id;
  if (!id) return;
  try {
    await api("POST", `/missions/${id}/abort`);
    message(`Mission #${id} aborted: every vehicle holds clear of the obstacles.`, "ok");
  } catch (err) {
    message(err.message, "bad");
  }
}

function updateButtons() {
  const hasDoc = Boolean(state.doc);
  const running = isRunning();
  $("btn-validate").disabled = !hasDoc;
  $("btn-preview").disabled = !hasDoc || running;
  $("btn-start").disabled = !hasDoc || running;
  const interrupted = Boolean(state.frame && state.frame.run && state.frame.run.state === "interrupted");
  $("btn-resume").disabled = !interrupted;
  $("btn-abort").disabled = !running && !interrupted;
  $("btn-add-obstacle").disabled = !hasDoc || state.mode === "replay";
  $("btn-draw-zone").disabled = !hasDoc || state.mode === "replay";
}

// Links and vehicles ----------------------------------------------------------------------
async function refreshLinks() {
  let links;
  try {
    links = await api("GET", "/links");
  } catch (err) {
    return;
  }
  const body = $("links-table").tBodies[0];
  body.replaceChildren();
  for (const l of links) {
    const tr = body.insertRow();
    tr.insertCell().textContent = l.id;
    tr.insertCell().textContent = l.url;
    tr.insertCell().textContent = l.connected ? "connected" : "down";
    tr.insertCell().textContent = l.vehicles.join(", ") || "–";
    const del = document.createElement("button");
    del.textContent = "remove";
    del.addEventListener("click", async () => {
      try {
        await api("DELETE", `/links/${l.id}`);
        linkMessage(`Link ${l.id} (${l.url}) removed.`, "ok");
      } catch (err) {
        linkMessage(err.message, "bad");
      }
      refreshLinks();
    });
    tr.insertCell().append(del);
  }
}

function linkMessage(text, kind) {
  const el = $("link-message");
  el.textContent = text;
  el.dataset.kind = kind || "";
}

async function addLink() {
  const url = $("link-url").value.trim();
  if (!url) {
    linkMessage("Type a MAVLink URL first, e.g. tcp:127.0.0.1:5760.", "bad");
    return;
  }
  try {
    const l = await api("POST", "/links", { url });
    linkMessage(`Link ${l.id} added: ${l.url}.`, "ok");
    $("link-url").value = "";
  } catch (err) {
    linkMessage(err.status === 422 ? `Not a URL the service takes: ${JSON.stringify(err.detail)}` : err.message, "bad");
  }
  refreshLinks();
}

// History and replay ----------------------------------------------------------------------
async function refreshRuns() {
  let runs, missions;
  try {
    [runs, missions] = await Promise.all([api("GET", "/runs"), api("GET", "/missions")]);
  } catch (err) {
    return;
  }
  const names = new Map(missions.map((x) => [x.id, x.name]));
  const list = $("runs");
  list.replaceChildren();
  for (const r of runs.slice().reverse()) {
    const li = document.createElement("li");
    li.dataset.run = String(r.id);
    li.classList.toggle("current", state.replay && state.replay.run.id === r.id);
    const when = new Date(r.started_s * 1000).toLocaleString([], { hour12: false });
    const t = r.summary && r.summary.mission_time_s !== undefined ? `${r.summary.mission_time_s.toFixed(1)} s` : "";
    li.textContent = `Run #${r.id}: ${names.get(r.mission_id) || "mission"} (#${r.mission_id}), ${r.state} ${t}`;
    const small = document.createElement("small");
    const formation = r.summary && r.summary.formation ? ` — formation: ${formationText(r.summary.formation)}` : "";
    small.textContent = `${when}${r.outcome ? " — " + r.outcome : ""}${formation}`;
    li.append(small);
    li.addEventListener("click", () => startReplay(r));
    list.append(li);
  }
}

async function startReplay(run) {
  let mission, telemetry, events;
  try {
    [mission, telemetry, events] = await Promise.all([
      api("GET", `/missions/${run.mission_id}`),
      api("GET", `/runs/${run.id}/telemetry`),
      api("GET", `/missions/${run.mission_id}/events`),
    ]);
  } catch (err) {
    banner(`Could not load run #${run.id}: ${err.message}`, "bad", 8000);
    return;
  }
  const tracks = telemetry.vehicles;
  const runEvents = events.filter((e) => e.run_id === run.id);
  let T = 0;
  for (const id in tracks) T = Math.max(T, tracks[id].t[tracks[id].t.length - 1] || 0);
  for (const e of runEvents) T = Math.max(T, e.mission_time_s || 0);
  const roles = new Map(mission.mission.vehicles.map((v) => [String(v.id), v.role]));
  const extent = Object.values(tracks).flatMap((track) => track.position_m);
  state.replay = {
    run, mission: mission.mission, tracks, events: runEvents, T, t: 0, playing: false, extent,
    speed: Number($("replay-speed").value), last: null, roles, trails: new Map(), drawnT: -1,
  };
  state.mode = "replay";
  setPlacing(false);
  updateButtons();
  $("replay-bar").hidden = false;
  $("btn-live").disabled = false;
  $("map-mode").textContent = `REPLAY of run #${run.id} (${run.state})`;
  $("events-scope").textContent = `(replay, run #${run.id})`;
  $("events").replaceChildren(...runEvents.map(eventItem));
  top.fitted = false;
  replaySeek(T / 2);
  drawTimeline();
  refreshRuns();
  const s = run.summary || {};
  const pill = $("run-state");
  pill.dataset.state = run.state;
  pill.textContent = `replay #${run.id}: ${run.state}`;
  $("sep").textContent = `– / ${m(s.min_separation_m)} (safe ${mission.mission.limits.safe_distance_uav})`;
  $("clr").textContent = `– / ${m(s.min_obstacle_clearance_m)} (safe ${mission.mission.limits.safe_distance_obstacle})`;
  $("violations").textContent = s.safety_violations !== undefined ? String(s.safety_violations) : "–";
  showFormation(s.formation);
}

function stopReplay() {
  state.mode = "live";
  state.replay = null;
  updateButtons();
  $("replay-bar").hidden = true;
  $("btn-live").disabled = true;
  $("map-mode").textContent = "";
  renderEvents();
  top.fitted = false;
  refreshRuns();
}

function interpolate(track, t) {
  const ts = track.t;
  if (!ts.length || t < ts[0]) return null;
  let lo = 0, hi = ts.length - 1;
  if (t >= ts[hi]) return { pos: track.position_m[hi], i: hi };
  while (hi - lo > 1) {
    const mid = (lo + hi) >> 1;
    if (ts[mid] <= t) lo = mid;
    else hi = mid;
  }
  const a = track.position_m[lo], b = track.position_m[hi];
  const f = (t - ts[lo]) / (ts[hi] - ts[lo] || 1);
  return { pos: a.map((c, k) => c + f * (b[k] - c)), i: lo };
}

function replaySeek(t) {
  const r = state.replay;
  r.t = Math.max(0, Math.min(r.T, t));
  $("replay-slider").value = String(Math.round((r.t / (r.T || 1)) * 1000));
  $("replay-time").textContent = `${r.t.toFixed(1)} / ${r.T.toFixed(1)} s`;
  $("mission-time").textContent = `${r.t.toFixed(1)} s`;
  document.querySelectorAll("#events li").forEach((li, k) => {
    const e = r.events[k];
    li.classList.toggle("future", e && e.mission_time_s > r.t);
  });
  drawTimeline();
}

function replayAdvance(now) {
  const r = state.replay;
  if (r.playing) {
    dirty = true;
    if (r.last !== null) replaySeek(r.t + ((now - r.last) / 1000) * r.speed);
    r.last = now;
    if (r.t >= r.T) {
      r.playing = false;
      $("btn-play").textContent = "▶";
    }
  } else {
    r.last = null;
  }
}

function replayScene() {
  const r = state.replay;
  const lim = r.mission.limits;
  const lost = new Set(), avoiding = new Set(), notResponding = new Set();
  for (const e of r.events) {
    if (e.mission_time_s > r.t) break;
    if (e.kind === "vehicle_lost") lost.add(e.vehicle_id);
    if (e.kind === "avoidance_entered") avoiding.add(e.vehicle_id);
    if (e.kind === "avoidance_left") avoiding.delete(e.vehicle_id);
    if (e.kind === "vehicle_not_responding") notResponding.add(e.vehicle_id);
    if (e.kind === "vehicle_responding") notResponding.delete(e.vehicle_id);
  }
  const vehicles = [];
  for (const id in r.tracks) {
    const track = r.tracks[id];
    const at = interpolate(track, r.t);
    if (!at) continue;
    const j = Math.min(at.i + 1, track.t.length - 1), i0 = Math.max(0, j - 1);
    const a = track.position_m[i0], b = track.position_m[j];
    const vid = Number(id);
    vehicles.push({
      id: vid, role: r.roles.get(id) || "other", pos_m: at.pos,
      yaw_rad: Math.atan2(b[1] - a[1], b[0] - a[0]),
      lost: lost.has(vid), avoiding: avoiding.has(vid), notResponding: notResponding.has(vid),
    });
    if (r.drawnT !== r.t) {
      let trail = r.trails.get(vid);
      if (!trail) r.trails.set(vid, (trail = new Trail(4000)));
      trail.clear();
      for (let k = 0; k <= at.i; k++) trail.push(...track.position_m[k]);
      trail.push(...at.pos);
    }
  }
  r.drawnT = r.t;
  return {
    obstacles: r.mission.obstacles.map((o) => {
      const g = withGeometry(o, lim);
      g.center_m = o.center.map((c, k) => c + r.t * (o.velocity ? o.velocity[k] : 0));
      return g;
    }),
    zones: docZones(r.mission),
    target_m: r.mission.target,
    route: validRoute(r.mission.route),
    leg: null,
    accuracy_m: lim.target_accuracy,
    ground: r.mission.ground,
    limits: lim,
    starts: [],
    plan: null,
    vehicles,
    trails: r.trails,
    selected: null,
    editable: false,
    run: null,
    extent: r.extent,
  };
}

function drawTimeline() {
  const c = $("timeline");
  const r = state.replay;
  if (!r) return;
  const dpr = window.devicePixelRatio || 1;
  c.width = Math.max(1, Math.round(c.clientWidth * dpr));
  c.height = Math.max(1, Math.round(c.clientHeight * dpr));
  const ctx = c.getContext("2d");
  const css = getComputedStyle(document.documentElement);
  const colour = { bad: css.getPropertyValue("--bad"), warn: css.getPropertyValue("--warn"), ok: css.getPropertyValue("--ok"), info: css.getPropertyValue("--muted") };
  ctx.clearRect(0, 0, c.width, c.height);
  const X = (t) => (t / (r.T || 1)) * (c.width - 2) + 1;
  for (const e of r.events) {
    ctx.fillStyle = colour[eventLevel(e.kind)] || colour.info;
    ctx.fillRect(X(e.mission_time_s || 0) - dpr, c.height * 0.15, 2 * dpr, c.height * 0.7);
  }
  ctx.fillStyle = css.getPropertyValue("--accent");
  ctx.fillRect(X(r.t) - 1.5 * dpr, 0, 3 * dpr, c.height);
}

// Controls --------------------------------------------------------------------------------
function showDrawing(on) {
  $("btn-draw-zone").setAttribute("aria-pressed", String(on));
  $("map").classList.toggle("placing", on);
  $("map-mode").textContent = on ? "Click each corner of the no-fly zone; double-click or Enter ends it (Esc cancels)" : "";
}

function setDrawing(on) {
  if (on) {
    setPlacing(false);
    top.startDrawing();
    showDrawing(true);
  } else if (top.drawing) {
    top.finishDrawing(true);
  }
}

function setPlacing(on) {
  top.placing = on;
  $("btn-add-obstacle").setAttribute("aria-pressed", String(on));
  $("map").classList.toggle("placing", on);
  $("map-mode").textContent = on ? "Click on the map to place an obstacle (Esc cancels)" : state.mode === "replay" ? $("map-mode").textContent : "";
}

function togglePause() {
  if (state.mode === "replay") {
    const r = state.replay;
    r.playing = !r.playing;
    if (r.playing && r.t >= r.T) replaySeek(0);
    $("btn-play").textContent = r.playing ? "❚❚" : "▶";
    return;
  }
  state.paused = !state.paused;
  state.frozen = state.paused ? buildScene() : null;
  $("btn-pause").setAttribute("aria-pressed", String(state.paused));
  $("map-mode").textContent = state.paused ? "DISPLAY PAUSED (space resumes) — the run goes on" : "";
}

function toggleFollow() {
  top.follow = !top.follow;
  $("btn-follow").setAttribute("aria-pressed", String(top.follow));
}

function setTheme(theme) {
  document.documentElement.dataset.theme = theme;
  localStorage.setItem("gcs-ppf-theme", theme);
  top.refreshColours();
  side.refreshColours();
  drawTimeline();
}

function selectTab(name) {
  document.querySelectorAll(".tabs button").forEach((b) => b.setAttribute("aria-selected", String(b.dataset.tab === name)));
  for (const t of ["plan", "fleet", "history"]) $(`tab-${t}`).hidden = t !== name;
  if (name === "history") refreshRuns();
  if (name === "fleet") refreshLinks();
}

const editing = () => Boolean(state.doc) && state.mode === "live";

function bind() {
  for (const kind of ["pointerdown", "pointermove", "pointerup", "wheel", "keydown", "change", "input", "click"]) {
    document.addEventListener(kind, touch, { capture: true, passive: true });
  }
  window.addEventListener("resize", touch);
  $("file-input").addEventListener("change", (e) => {
    const file = e.target.files[0];
    if (file) loadFile(file);
    e.target.value = "";
  });
  const drop = $("drop");
  for (const target of [drop, $("map")]) {
    target.addEventListener("dragover", (e) => {
      e.preventDefault();
      drop.classList.add("over");
    });
    target.addEventListener("dragleave", () => drop.classList.remove("over"));
    target.addEventListener("drop", (e) => {
      e.preventDefault();
      drop.classList.remove("over");
      const file = e.dataTransfer.files[0];
      if (file) loadFile(file);
    });
  }
  $("btn-validate").addEventListener("click", () => {
    if (state.storedId && !state.missionDirty && !state.obstaclesDirty) {
      message(`Mission #${state.storedId} is stored and valid; nothing changed since.`, "ok");
      return;
    }
    store();
  });
  $("btn-preview").addEventListener("click", preview);
  $("btn-start").addEventListener("click", start);
  $("btn-resume").addEventListener("click", resume);
  $("btn-abort").addEventListener("click", abort);
  $("btn-zoom-in").addEventListener("click", () => zoomBy(1.4));
  $("btn-zoom-out").addEventListener("click", () => zoomBy(1 / 1.4));
  $("btn-fit").addEventListener("click", () => top.fit());
  $("btn-follow").addEventListener("click", toggleFollow);
  $("btn-pause").addEventListener("click", togglePause);
  $("btn-add-obstacle").addEventListener("click", () => setPlacing(!top.placing));
  $("btn-draw-zone").addEventListener("click", () => setDrawing(!top.drawing));
  $("btn-add-link").addEventListener("click", addLink);
  $("btn-refresh-runs").addEventListener("click", refreshRuns);
  $("btn-live").addEventListener("click", stopReplay);
  $("btn-play").addEventListener("click", togglePause);
  $("replay-slider").addEventListener("input", (e) => state.replay && replaySeek((Number(e.target.value) / 1000) * state.replay.T));
  $("replay-speed").addEventListener("change", (e) => state.replay && (state.replay.speed = Number(e.target.value)));
  $("timeline").addEventListener("pointerdown", (e) => {
    const r = state.replay;
    if (!r) return;
    const rect = e.target.getBoundingClientRect();
    replaySeek(((e.clientX - rect.left) / rect.width) * r.T);
  });
  document.querySelectorAll(".tabs button").forEach((b) => b.addEventListener("click", () => selectTab(b.dataset.tab)));
  $("theme").addEventListener("click", () => setTheme(document.documentElement.dataset.theme === "dark" ? "light" : "dark"));
  $("help-btn").addEventListener("click", () => $("help").showModal());
  document.addEventListener("keydown", (e) => {
    if (e.target.closest && e.target.closest("input, select, textarea") || e.ctrlKey || e.metaKey || e.altKey) return;
    const k = e.key;
    const act = {
      "+": () => zoomBy(1.4), "=": () => zoomBy(1.4), "-": () => zoomBy(1 / 1.4),
      "0": () => top.fit(), f: toggleFollow, F: toggleFollow, " ": togglePause,
      o: () => editing() && setPlacing(!top.placing), O: () => editing() && setPlacing(!top.placing),
      z: () => editing() && setDrawing(!top.drawing), Z: () => editing() && setDrawing(!top.drawing),
      Enter: () => top.drawing && top.finishDrawing(),
      Escape: () => { setPlacing(false); setDrawing(false); },
      Delete: () => editing() && state.selected !== null && deleteObstacle(state.selected),
      Backspace: () => editing() && state.selected !== null && deleteObstacle(state.selected),
      p: () => state.doc && !isRunning() && preview(), P: () => state.doc && !isRunning() && preview(),
      t: () => $("theme").click(), T: () => $("theme").click(),
      "1": () => selectTab("plan"), "2": () => selectTab("fleet"), "3": () => selectTab("history"),
      "?": () => $("help").showModal(),
    }[k];
    if (act) {
      e.preventDefault();
      act();
    }
  });
}

const saved = localStorage.getItem("gcs-ppf-theme");
setTheme(saved || (matchMedia("(prefers-color-scheme: dark)").matches ? "dark" : "light"));
bind();
updateButtons();
stream.view(null);
setInterval(refreshLinks, 3000);
refreshLinks();
requestAnimationFrame(draw);

// Read-only handles for the browser tests and the benchmark.
window.gcs = { state, perf, influenceRadius, top, side };
