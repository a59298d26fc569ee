// The top view (east/north, metres about the mission origin) and the side view, on canvas.

/** A vehicle's recent track: a ring buffer of (x, y, z), fixed size, so memory stays flat. */
export class Trail {
  constructor(capacity = 600) {
    this.xyz = new Float32Array(capacity * 3);
    this.capacity = capacity;
    this.start = 0;
    this.length = 0;
  }
  push(x, y, z) {
    if (this.length) {
      const j = ((this.start + this.length - 1) % this.capacity) * 3;
      if (Math.abs(this.xyz[j] - x) + Math.abs(this.xyz[j + 1] - y) + Math.abs(this.xyz[j + 2] - z) < 0.5) return;
    }
    const i = ((this.start + this.length) % this.capacity) * 3;
    this.xyz[i] = x;
    this.xyz[i + 1] = y;
    this.xyz[i + 2] = z;
    if (this.length < this.capacity) this.length += 1;
    else this.start = (this.start + 1) % this.capacity;
  }
  clear() {
    this.start = 0;
    this.length = 0;
  }
  /** Adds the trail to the canvas path as a polyline through project(x, y, z) → [sx, sy],
   * every `step`-th point (and the newest). */
  trace(ctx, px, py, step = 1) {
    const { xyz, capacity, start, length } = this;
    for (let k = 0; k < length; k += k + step < length || k === length - 1 ? step : length - 1 - k) {
      const i = ((start + k) % capacity) * 3;
      const x = px(xyz[i], xyz[i + 1], xyz[i + 2]);
      const y = py(xyz[i], xyz[i + 1], xyz[i + 2]);
      if (k) ctx.lineTo(x, y);
      else ctx.moveTo(x, y);
    }
  }
}

const NICE = [1, 2, 5];
function niceLength(metres) {
  const p = 10 ** Math.floor(Math.log10(metres));
  let best = p;
  for (const n of NICE) if (n * p <= metres) best = n * p;
  for (const n of NICE) if (n * p * 10 <= metres) best = n * p * 10;
  return best;
}
const label = (m) => (m >= 1000 ? `${m / 1000} km` : `${m} m`);

function colours() {
  const s = getComputedStyle(document.documentElement);
  const c = (n) => s.getPropertyValue(n).trim();
  return {
    fg: c("--fg"), muted: c("--muted"), grid: c("--grid"), map: c("--map"), bad: c("--bad"),
    warn: c("--warn"), ok: c("--ok"), s1: c("--s1"), s2: c("--s2"), s3: c("--s3"),
    lost: c("--lost"), obstacle: c("--obstacle"), keepout: c("--keepout"), inclusion: c("--inclusion"),
    influence: c("--influence"), plan: c("--plan"), target: c("--target"), accent: c("--accent"),
    font: c("--font"), mono: c("--mono"),
    // Marks and text on the canvases grow with the page's font (larger on a 4K screen).
    scale: Math.max(1, parseFloat(s.fontSize) / 13),
  };
}

/** Colour of a vehicle: its PPF state, grey when lost, the warning colour when not
 * responding. */
export function vehicleColour(col, v) {
  if (v.lost) return col.lost;
  if (v.notResponding) return col.warn;
  return col[v.ppf_state] || col.fg;
}

/** Whether rectangle r ({x, y, w, h}) overlaps any of `rects`. */
function overlaps(rects, r) {
  return rects.some((p) => r.x < p.x + p.w && p.x < r.x + r.w && r.y < p.y + p.h && p.y < r.y + r.h);
}

/** Every corner of the zones' footprints (a circle's bounding square's). */
function zoneOutline(zones) {
  return (zones || []).flatMap((z) => {
    if (z.vertices_m) return z.vertices_m;
    const [x, y] = z.center_m, r = z.radius_m;
    return [[x - r, y - r], [x + r, y + r]];
  });
}

function zoneCentre(z) {
  if (!z.vertices_m) return z.center_m;
  const n = z.vertices_m.length;
  return [0, 1].map((k) => z.vertices_m.reduce((a, p) => a + p[k], 0) / n);
}

/** A zone's extent along the side view's line, [lowest, highest]. */
function zoneAlong(z, along) {
  if (!z.vertices_m) {
    const u = along(z.center_m[0], z.center_m[1]);
    return [u - z.radius_m, u + z.radius_m];
  }
  const us = z.vertices_m.map((p) => along(p[0], p[1]));
  return [Math.min(...us), Math.max(...us)];
}

function zoneBand(z) {
  const h = (v) => (v === null || v === undefined ? "∞" : `${Math.round(v)}`);
  return `${z.floor_m === null || z.floor_m === undefined ? "ground" : h(z.floor_m)}–${h(z.ceiling_m)} m`;
}

function fitCanvas(canvas) {
  const dpr = window.devicePixelRatio || 1;
  const w = Math.max(1, Math.round(canvas.clientWidth * dpr));
  const h = Math.max(1, Math.round(canvas.clientHeight * dpr));
  if (canvas.width !== w || canvas.height !== h) {
    canvas.width = w;
    canvas.height = h;
  }
  return dpr;
}

/**
 * The top view. `scene` (set by the page) holds what to draw:
 *   obstacles [{center_m, radius_m, keep_out_m, influence_m}], target_m, accuracy_m,
 *   starts [{id, role, pos, yaw}], plan {id: {position_m}}, vehicles [...], trails Map,
 *   selected (obstacle index or null), editable (bool).
 */
export class TopView {
  constructor(canvas, handlers) {
    this.canvas = canvas;
    this.ctx = canvas.getContext("2d");
    this.h = handlers; // onPlace(x, y), onObstacleEdit(index, obstacle, done), onSelect(index), onZoneDrawn(vertices)
    this.view = { x: 0, y: 0, scale: 0.05 };
    this.col = colours();
    this.follow = false;
    this.placing = false;
    this.drawing = null; // the corners of a no-fly polygon being drawn (ICS m), or null
    this.drawCursor = null;
    this.drag = null;
    this.scene = null;
    this.fitted = false;
    this.bindPointer();
  }

  refreshColours() {
    this.col = colours();
  }

  toScreen(x, y) {
    const c = this.canvas;
    return [c.width / 2 + (x - this.view.x) * this.view.scale, c.height / 2 - (y - this.view.y) * this.view.scale];
  }

  toWorld(sx, sy) {
    const c = this.canvas;
    return [this.view.x + (sx - c.width / 2) / this.view.scale, this.view.y - (sy - c.height / 2) / this.view.scale];
  }

  /** Zooms about a screen point (the centre by default); a view not yet framed is framed first. */
  zoom(factor, sx, sy) {
    if (!this.fitted) this.fit();
    const c = this.canvas;
    const [wx, wy] = this.toWorld(sx ?? c.width / 2, sy ?? c.height / 2);
    this.view.scale = Math.min(50, Math.max(1e-4, this.view.scale * factor));
    const [nx, ny] = this.toWorld(sx ?? c.width / 2, sy ?? c.height / 2);
    this.view.x += wx - nx;
    this.view.y += wy - ny;
  }

  /** Frames everything in the scene. */
  fit() {
    const s = this.scene;
    if (!s) return;
    let x0 = Infinity, y0 = Infinity, x1 = -Infinity, y1 = -Infinity;
    const add = (x, y, r = 0) => {
      x0 = Math.min(x0, x - r); y0 = Math.min(y0, y - r);
      x1 = Math.max(x1, x + r); y1 = Math.max(y1, y + r);
    };
    for (const o of s.obstacles || []) add(o.center_m[0], o.center_m[1], o.keep_out_m || o.radius_m);
    for (const p of zoneOutline(s.zones)) add(p[0], p[1]);
    if (s.target_m) add(s.target_m[0], s.target_m[1], 100);
    for (const w of s.route || []) add(w.position[0], w.position[1], w.acceptance_radius || 100);
    for (const v of s.starts || []) add(v.pos[0], v.pos[1], 100);
    for (const v of s.vehicles || []) if (v.pos_m) add(v.pos_m[0], v.pos_m[1], 100);
    for (const id in s.plan || {}) for (const p of s.plan[id].position_m) add(p[0], p[1]);
    for (const p of s.extent || []) add(p[0], p[1]); // a replayed run's whole tracks
    if (!Number.isFinite(x0)) return;
    const dpr = fitCanvas(this.canvas) * this.col.scale;
    const c = this.canvas;
    const top = 44 * dpr; // the toolbar
    const margin = 16 * dpr;
    const w = c.width - 2 * margin, h = c.height - top - 2 * margin;
    this.view.scale = Math.min(w / Math.max(x1 - x0, 1), h / Math.max(y1 - y0, 1));
    this.view.x = (x0 + x1) / 2;
    this.view.y = (y0 + y1) / 2 + top / 2 / this.view.scale;
    this.fitted = true;
  }

  /** A new path through the points (world m) on the canvas, not yet stroked or filled. */
  tracePath(points) {
    const ctx = this.ctx;
    ctx.beginPath();
    points.forEach((p, j) => {
      const [x, y] = this.toScreen(p[0], p[1]);
      if (j) ctx.lineTo(x, y);
      else ctx.moveTo(x, y);
    });
  }

  /** Starts drawing a no-fly polygon: each click a corner, a double click (or Enter) ends it. */
  startDrawing() {
    this.drawing = [];
    this.drawCursor = null;
  }

  /** Ends the polygon being drawn: handed on with three corners or more (``cancel``: dropped). */
  finishDrawing(cancel = false) {
    const corners = this.drawing;
    this.drawing = null;
    this.drawCursor = null;
    this.h.onZoneDrawn(!cancel && corners && corners.length >= 3 ? corners : null);
  }

  hit(sx, sy) {
    const s = this.scene;
    if (!s || !s.editable) return null;
    const obs = s.obstacles || [];
    for (let i = obs.length - 1; i >= 0; i--) {
      const [cx, cy] = this.toScreen(obs[i].center_m[0], obs[i].center_m[1]);
      const r = obs[i].radius_m * this.view.scale;
      const d = Math.hypot(sx - cx, sy - cy);
      if (Math.abs(d - r) < 8 * (window.devicePixelRatio || 1)) return { index: i, part: "rim" };
      if (d < r) return { index: i, part: "centre" };
    }
    return null;
  }

  bindPointer() {
    const c = this.canvas;
    const pos = (e) => {
      const r = c.getBoundingClientRect();
      const dpr = c.width / r.width;
      return [(e.clientX - r.left) * dpr, (e.clientY - r.top) * dpr];
    };
    c.addEventListener("wheel", (e) => {
      e.preventDefault();
      const [sx, sy] = pos(e);
      this.zoom(e.deltaY < 0 ? 1.2 : 1 / 1.2, sx, sy);
    }, { passive: false });
    c.addEventListener("pointerdown", (e) => {
      c.focus();
      const [sx, sy] = pos(e);
      if (this.drawing) {
        const last = this.drawing[this.drawing.length - 1];
        const [lx, ly] = last ? this.toScreen(last[0], last[1]) : [Infinity, Infinity];
        const near = 4 * (window.devicePixelRatio || 1);
        if (Math.hypot(sx - lx, sy - ly) > near) this.drawing.push(this.toWorld(sx, sy));
        return; // (a double click's second press puts no corner: the dblclick ends it)
      }
      if (this.placing) {
        const [x, y] = this.toWorld(sx, sy);
        this.h.onPlace(x, y);
        return;
      }
      const hit = this.hit(sx, sy);
      if (hit) {
        const o = this.scene.obstacles[hit.index];
        this.h.onSelect(hit.index);
        this.drag = { kind: hit.part, index: hit.index, sx, sy, center: [...o.center_m], radius: o.radius_m };
      } else {
        this.drag = { kind: "pan", sx, sy, x: this.view.x, y: this.view.y };
        this.follow = false;
      }
      c.setPointerCapture(e.pointerId);
      c.classList.add("dragging");
    });
    c.addEventListener("pointermove", (e) => {
      const [sx, sy] = pos(e);
      if (this.drawing) {
        this.drawCursor = this.toWorld(sx, sy);
        return;
      }
      const d = this.drag;
      if (!d) {
        const hit = this.placing ? null : this.hit(sx, sy);
        c.style.cursor = hit ? (hit.part === "rim" ? "ew-resize" : "move") : "";
        return;
      }
      if (d.kind === "pan") {
        this.view.x = d.x - (sx - d.sx) / this.view.scale;
        this.view.y = d.y + (sy - d.sy) / this.view.scale;
      } else if (d.kind === "centre") {
        const dx = (sx - d.sx) / this.view.scale;
        const dy = -(sy - d.sy) / this.view.scale;
        this.h.onObstacleEdit(d.index, { center: [d.center[0] + dx, d.center[1] + dy, d.center[2]] }, false);
      } else if (d.kind === "rim") {
        const [x, y] = this.toWorld(sx, sy);
        const r = Math.max(1, Math.hypot(x - d.center[0], y - d.center[1]));
        this.h.onObstacleEdit(d.index, { radius: r }, false);
      }
    });
    const up = (e) => {
      const d = this.drag;
      this.drag = null;
      c.classList.remove("dragging");
      if (d && d.kind !== "pan") {
        const [sx, sy] = pos(e);
        if (Math.hypot(sx - d.sx, sy - d.sy) > 2) this.h.onObstacleEdit(d.index, {}, true);
      }
    };
    c.addEventListener("dblclick", () => this.drawing && this.finishDrawing());
    c.addEventListener("pointerup", up);
    c.addEventListener("pointercancel", up);
  }

  draw() {
    const dpr = fitCanvas(this.canvas) * this.col.scale;
    const { ctx, col } = this;
    const s = this.scene;
    const c = this.canvas;
    ctx.setTransform(1, 0, 0, 1, 0, 0);
    ctx.fillStyle = col.map;
    ctx.fillRect(0, 0, c.width, c.height);
    if (!s) return;
    if (!this.fitted) this.fit();
    if (this.follow) {
      const leader = (s.vehicles || []).find((v) => v.role === "leader" && v.pos_m);
      if (leader) {
        this.view.x = leader.pos_m[0];
        this.view.y = leader.pos_m[1];
      }
    }
    const k = this.view.scale;
    const font = (px, mono) => `${Math.round(px * dpr)}px ${mono ? col.mono : col.font}`;
    this.drawGrid(dpr, font);

    // Obstacles: the sphere to scale, its keep-out (dashed) and influence radius (dotted).
    (s.obstacles || []).forEach((o, i) => {
      const [x, y] = this.toScreen(o.center_m[0], o.center_m[1]);
      ctx.beginPath();
      ctx.arc(x, y, o.radius_m * k, 0, 2 * Math.PI);
      ctx.fillStyle = col.obstacle;
      ctx.fill();
      ctx.lineWidth = (s.selected === i ? 3 : 1) * dpr;
      ctx.strokeStyle = s.selected === i ? col.accent : col.muted;
      ctx.stroke();
      ctx.lineWidth = 1 * dpr;
      if (o.keep_out_m) {
        ctx.setLineDash([6 * dpr, 4 * dpr]);
        ctx.strokeStyle = col.keepout;
        ctx.beginPath();
        ctx.arc(x, y, o.keep_out_m * k, 0, 2 * Math.PI);
        ctx.stroke();
      }
      if (o.influence_m) {
        ctx.setLineDash([1.5 * dpr, 4 * dpr]);
        ctx.strokeStyle = col.influence;
        ctx.beginPath();
        ctx.arc(x, y, o.influence_m * k, 0, 2 * Math.PI);
        ctx.stroke();
      }
      ctx.setLineDash([]);
      if (o.radius_m * k > 45 * dpr) {
        ctx.fillStyle = col.fg;
        ctx.font = font(11);
        ctx.textAlign = "center";
        ctx.fillText(`#${i}`, x, y - 3 * dpr);
        ctx.fillText(`r ${Math.round(o.radius_m)}, z ${Math.round(o.center_m[2])}`, x, y + 11 * dpr);
      }
    });

    // Zones: the footprint (exclusion filled as an obstacle, inclusion a dashed green line).
    for (const z of s.zones || []) {
      if (z.vertices_m) {
        this.tracePath(z.vertices_m);
        ctx.closePath();
      } else {
        ctx.beginPath();
        const [x, y] = this.toScreen(z.center_m[0], z.center_m[1]);
        ctx.arc(x, y, z.radius_m * k, 0, 2 * Math.PI);
      }
      ctx.lineWidth = 1.5 * dpr;
      if (z.inclusion) {
        ctx.setLineDash([6 * dpr, 4 * dpr]);
        ctx.strokeStyle = col.inclusion;
      } else {
        ctx.fillStyle = col.obstacle;
        ctx.fill();
        ctx.strokeStyle = col.muted;
      }
      ctx.stroke();
      ctx.setLineDash([]);
      const [cx, cy] = zoneCentre(z);
      const [x, y] = this.toScreen(cx, cy);
      ctx.fillStyle = col.fg;
      ctx.font = font(11);
      ctx.textAlign = "center";
      ctx.fillText(`${z.name || z.kind} ${zoneBand(z)}`, x, y);
    }

    // A no-fly polygon being drawn: its corners, the edge to the pointer, closed dashed.
    if (this.drawing && this.drawing.length) {
      this.tracePath([...this.drawing, ...(this.drawCursor ? [this.drawCursor] : [])]);
      ctx.closePath();
      ctx.setLineDash([6 * dpr, 4 * dpr]);
      ctx.lineWidth = 2 * dpr;
      ctx.strokeStyle = col.bad;
      ctx.stroke();
      ctx.setLineDash([]);
      ctx.fillStyle = col.bad;
      for (const p of this.drawing) {
        const [x, y] = this.toScreen(p[0], p[1]);
        ctx.fillRect(x - 3 * dpr, y - 3 * dpr, 6 * dpr, 6 * dpr);
      }
    }

    // The planned paths (preview), thin.
    ctx.lineWidth = 1.5 * dpr;
    for (const id in s.plan || {}) {
      ctx.strokeStyle = col.plan;
      this.tracePath(s.plan[id].position_m);
      ctx.stroke();
    }

    // The leader's route: its waypoints with their acceptance radii, joined up to the
    // target; the leg flown now drawn bold.
    const route = s.route || [];
    if (route.length && s.target_m) {
      const pts = [...route.map((w) => w.position), s.target_m];
      ctx.strokeStyle = col.target;
      pts.slice(1).forEach((p, j) => {
        const [ax, ay] = this.toScreen(pts[j][0], pts[j][1]);
        const [bx, by] = this.toScreen(p[0], p[1]);
        ctx.lineWidth = (s.leg === j + 1 ? 3 : 1) * dpr;
        ctx.setLineDash([6 * dpr, 4 * dpr]);
        ctx.beginPath(); ctx.moveTo(ax, ay); ctx.lineTo(bx, by); ctx.stroke();
      });
      ctx.setLineDash([]);
      route.forEach((w, j) => {
        const [x, y] = this.toScreen(w.position[0], w.position[1]);
        ctx.lineWidth = (s.leg === j ? 3 : 1.5) * dpr;
        ctx.beginPath();
        ctx.arc(x, y, Math.max(5 * dpr, (w.acceptance_radius || 100) * k), 0, 2 * Math.PI);
        ctx.stroke();
        ctx.fillStyle = col.target;
        ctx.font = font(12);
        ctx.textAlign = "left";
        ctx.fillText(`WP${j + 1}`, x + 8 * dpr, y - 6 * dpr);
        if (w.loiter && w.loiter.radius_m > 0) { // its loiter circle (as asked; flown no tighter than the formation turns)
          ctx.lineWidth = (s.leg === j ? 2 : 1) * dpr;
          ctx.setLineDash([2 * dpr, 4 * dpr]);
          ctx.beginPath();
          ctx.arc(x, y, w.loiter.radius_m * k, 0, 2 * Math.PI);
          ctx.stroke();
          ctx.setLineDash([]);
        }
      });
    }

    // The turn point the leader flies straight on to before turning onto a waypoint that
    // lies inside its formation's turn (the run's leg.turn_point_m).
    if (s.turnPoint) {
      const [x, y] = this.toScreen(s.turnPoint[0], s.turnPoint[1]);
      ctx.strokeStyle = col.target;
      ctx.lineWidth = 1.5 * dpr;
      ctx.beginPath();
      ctx.moveTo(x, y - 7 * dpr); ctx.lineTo(x + 7 * dpr, y); ctx.lineTo(x, y + 7 * dpr);
      ctx.lineTo(x - 7 * dpr, y); ctx.closePath();
      ctx.stroke();
      ctx.fillStyle = col.target;
      ctx.font = font(12);
      ctx.textAlign = "left";
      ctx.fillText("turn point", x + 10 * dpr, y + 4 * dpr);
    }

    // The leader's target and its accuracy.
    if (s.target_m) {
      const [x, y] = this.toScreen(s.target_m[0], s.target_m[1]);
      ctx.strokeStyle = col.target;
      ctx.lineWidth = 2 * dpr;
      ctx.beginPath();
      ctx.arc(x, y, Math.max(6 * dpr, (s.accuracy_m || 10) * k), 0, 2 * Math.PI);
      ctx.moveTo(x - 12 * dpr, y); ctx.lineTo(x + 12 * dpr, y);
      ctx.moveTo(x, y - 12 * dpr); ctx.lineTo(x, y + 12 * dpr);
      ctx.stroke();
      ctx.fillStyle = col.target;
      ctx.font = font(12);
      ctx.textAlign = "left";
      ctx.fillText(`target z ${Math.round(s.target_m[2])} m`, x + 14 * dpr, y - 6 * dpr);
    }

    // Start positions (hollow) before a run.
    for (const v of s.starts || []) {
      const [x, y] = this.toScreen(v.pos[0], v.pos[1]);
      this.arrow(x, y, v.yaw, 9 * dpr, col.muted, false);
      ctx.fillStyle = col.muted;
      ctx.font = font(11);
      ctx.textAlign = "left";
      ctx.fillText(`${v.id}${v.role === "leader" ? " L" : ""}`, x + 10 * dpr, y + 12 * dpr);
    }

    // Trails (every other point or fewer when there are many: a point is 0.1 s of flight).
    ctx.lineWidth = 1.5 * dpr;
    let points = 0;
    for (const t of (s.trails || new Map()).values()) points += t.length;
    const step = Math.max(1, Math.ceil(points / 15000));
    for (const v of s.vehicles || []) {
      const trail = s.trails && s.trails.get(v.id);
      if (!trail || trail.length < 2) continue;
      ctx.strokeStyle = vehicleColour(col, v);
      ctx.globalAlpha = 0.6;
      ctx.beginPath();
      const cx = c.width / 2 - this.view.x * k, cy = c.height / 2 + this.view.y * k;
      trail.trace(ctx, (tx) => cx + tx * k, (_tx, ty) => cy - ty * k, step);
      ctx.stroke();
      ctx.globalAlpha = 1;
    }

    // Each wingman's local target point and the line to it with its distance (written for
    // up to 12 wingmen; beyond, the Fleet tab lists them).
    ctx.font = font(11, true);
    const withSlots = (s.vehicles || []).filter((v) => v.local_target_m).length;
    const slotLabels = [];
    for (const v of s.vehicles || []) {
      if (!v.pos_m || !v.local_target_m || v.lost) continue;
      const [x, y] = this.toScreen(v.pos_m[0], v.pos_m[1]);
      const [gx, gy] = this.toScreen(v.local_target_m[0], v.local_target_m[1]);
      ctx.strokeStyle = col.muted;
      ctx.lineWidth = 1 * dpr;
      ctx.setLineDash([3 * dpr, 3 * dpr]);
      ctx.beginPath();
      ctx.moveTo(x, y);
      ctx.lineTo(gx, gy);
      ctx.stroke();
      ctx.setLineDash([]);
      ctx.strokeRect(gx - 4 * dpr, gy - 4 * dpr, 8 * dpr, 8 * dpr);
      const d = v.local_target_distance_m ?? Math.hypot(...v.pos_m.map((p, j) => p - v.local_target_m[j]));
      if (withSlots > 12) continue;
      slotLabels.push({ text: `${d.toFixed(0)} m`, x: (x + gx) / 2, y: (y + gy) / 2,
                        colour: d <= (s.accuracy_m || 10) ? col.ok : col.muted });
    }

    // Vehicles: heading, id, role, PPF state; lost crossed out, not responding ringed.
    const labels = [];
    for (const v of s.vehicles || []) {
      if (!v.pos_m) continue;
      const [x, y] = this.toScreen(v.pos_m[0], v.pos_m[1]);
      const colour = vehicleColour(col, v);
      const size = (v.role === "leader" ? 13 : 10) * dpr;
      this.arrow(x, y, v.yaw_rad ?? Math.PI / 2, size, colour, true);
      if (v.lost) {
        ctx.strokeStyle = col.bad;
        ctx.lineWidth = 2 * dpr;
        ctx.beginPath();
        ctx.moveTo(x - size, y - size); ctx.lineTo(x + size, y + size);
        ctx.moveTo(x + size, y - size); ctx.lineTo(x - size, y + size);
        ctx.stroke();
      } else if (v.notResponding || v.avoiding) {
        ctx.strokeStyle = v.notResponding ? col.warn : colour;
        ctx.lineWidth = 1.5 * dpr;
        ctx.setLineDash(v.notResponding ? [4 * dpr, 3 * dpr] : []);
        ctx.beginPath();
        ctx.arc(x, y, size * 1.6, 0, 2 * Math.PI);
        ctx.stroke();
        ctx.setLineDash([]);
      }
      labels.push({ v, x, y, size, colour });
    }
    const placed = this.drawLabels(labels, dpr, font);
    // The distances to the slots, where they overlap no other label.
    ctx.font = font(11, true);
    ctx.textAlign = "left";
    for (const l of slotLabels) {
      const w = ctx.measureText(l.text).width, h = 13 * dpr;
      const spot = [[l.x + 4 * dpr, l.y - h], [l.x + 4 * dpr, l.y + 2 * dpr], [l.x - w - 4 * dpr, l.y - h]]
        .map(([x, y]) => ({ x, y, w, h })).find((r) => !overlaps(placed, r));
      if (!spot) continue;
      placed.push(spot);
      ctx.fillStyle = l.colour;
      ctx.fillText(l.text, spot.x, spot.y + h - 3 * dpr);
    }
    this.drawScale(dpr, font);
  }

  /** Each vehicle's label (id, role, state; height below) where it overlaps no label
   * already placed: right of the mark, else below, above or left of it; else only its id
   * if that fits. The leader, then lost and not-responding vehicles, are placed first. */
  drawLabels(labels, dpr, font) {
    const { ctx, col } = this;
    const rank = (l) => (l.v.role === "leader" ? 0 : l.v.lost || l.v.notResponding ? 1 : 2);
    labels.sort((a, b) => rank(a) - rank(b));
    const placed = [];
    const free = (r) => !overlaps(placed, r);
    const line = 13 * dpr;
    for (const { v, x, y, size, colour } of labels) {
      const role = v.role === "leader" ? "L" : v.role === "wingman" ? "W" : "?";
      const tag = v.lost ? "LOST" : v.notResponding ? "NOT RESP." : v.ppf_state || v.mode || "";
      const main = `${v.id} ${role} ${tag}`;
      const sub = `z ${v.pos_m[2].toFixed(0)}`;
      ctx.font = font(12, true);
      const w = Math.max(ctx.measureText(main).width, ctx.measureText(sub).width * 0.85);
      const gap = size + 3 * dpr;
      const spots = [[x + gap, y - line], [x - w / 2, y + gap], [x - w / 2, y - gap - 2 * line], [x - gap - w, y - line]];
      const spot = spots.map(([sx, sy]) => ({ x: sx, y: sy, w, h: 2 * line })).find(free);
      ctx.textAlign = "left";
      if (spot) {
        placed.push(spot);
        ctx.fillStyle = colour;
        ctx.fillText(main, spot.x, spot.y + line - 3 * dpr);
        ctx.fillStyle = col.muted;
        ctx.font = font(10, true);
        ctx.fillText(sub, spot.x, spot.y + 2 * line - 3 * dpr);
        continue;
      }
      const id = { x: x + gap, y: y - line, w: ctx.measureText(String(v.id)).width, h: line };
      if (free(id)) {
        placed.push(id);
        ctx.fillStyle = colour;
        ctx.fillText(String(v.id), id.x, id.y + line - 3 * dpr);
      }
    }
    return placed;
  }

  arrow(x, y, yaw, size, colour, filled) {
    const { ctx } = this;
    const dpr = window.devicePixelRatio || 1;
    ctx.save();
    ctx.translate(x, y);
    ctx.rotate(-yaw); // ENU yaw, counter-clockwise from east; the canvas' y points down
    ctx.beginPath();
    ctx.moveTo(size, 0);
    ctx.lineTo(-size * 0.7, size * 0.6);
    ctx.lineTo(-size * 0.35, 0);
    ctx.lineTo(-size * 0.7, -size * 0.6);
    ctx.closePath();
    if (filled) {
      ctx.fillStyle = colour;
      ctx.fill();
      ctx.strokeStyle = this.col.map;
      ctx.lineWidth = 1 * dpr;
      ctx.stroke();
    } else {
      ctx.strokeStyle = colour;
      ctx.lineWidth = 1.5 * dpr;
      ctx.stroke();
    }
    ctx.restore();
  }

  drawGrid(dpr, font) {
    const { ctx, col, canvas: c } = this;
    const step = niceLength(120 * dpr / this.view.scale);
    const [wx0, wy1] = this.toWorld(0, 0);
    const [wx1, wy0] = this.toWorld(c.width, c.height);
    ctx.strokeStyle = col.grid;
    ctx.lineWidth = 1;
    ctx.beginPath();
    for (let gx = Math.ceil(wx0 / step) * step; gx <= wx1; gx += step) {
      const [x] = this.toScreen(gx, 0);
      ctx.moveTo(x, 0); ctx.lineTo(x, c.height);
    }
    for (let gy = Math.ceil(wy0 / step) * step; gy <= wy1; gy += step) {
      const [, y] = this.toScreen(0, gy);
      ctx.moveTo(0, y); ctx.lineTo(c.width, y);
    }
    ctx.stroke();
    const [ox, oy] = this.toScreen(0, 0);
    ctx.fillStyle = col.muted;
    ctx.font = font(10);
    ctx.textAlign = "left";
    ctx.fillText("origin", ox + 3 * dpr, oy - 3 * dpr);
    ctx.fillText("N ↑  E →", 8 * dpr, c.height - 30 * dpr);
  }

  drawScale(dpr, font) {
    const { ctx, col, canvas: c } = this;
    const len = niceLength(150 * dpr / this.view.scale);
    const px = len * this.view.scale;
    const x = c.width - px - 16 * dpr;
    const y = c.height - 16 * dpr;
    ctx.strokeStyle = col.fg;
    ctx.lineWidth = 2 * dpr;
    ctx.beginPath();
    ctx.moveTo(x, y - 5 * dpr); ctx.lineTo(x, y); ctx.lineTo(x + px, y); ctx.lineTo(x + px, y - 5 * dpr);
    ctx.stroke();
    ctx.fillStyle = col.fg;
    ctx.font = font(12);
    ctx.textAlign = "center";
    ctx.fillText(label(len), x + px / 2, y - 6 * dpr);
  }
}

/**
 * The side view: altitude (z, up) against the distance along the horizontal line from the
 * leader's start to the target; obstacles drawn as their spheres' sections through that
 * line's vertical plane would be if they sat on it (their true radius), lateral offset
 * written beside them.
 */
export class SideView {
  constructor(canvas) {
    this.canvas = canvas;
    this.ctx = canvas.getContext("2d");
    this.col = colours();
    this.scene = null;
  }

  refreshColours() {
    this.col = colours();
  }

  axis() {
    const s = this.scene;
    const leader = (s.starts || []).find((v) => v.role === "leader") ||
      (s.vehicles || []).find((v) => v.role === "leader" && v.pos_m);
    const from = leader ? leader.pos || leader.pos_m : [0, 0, 0];
    const to = s.target_m || [from[0] + 1, from[1], from[2]];
    const dx = to[0] - from[0], dy = to[1] - from[1];
    const n = Math.hypot(dx, dy) || 1;
    return { x: from[0], y: from[1], ux: dx / n, uy: dy / n };
  }

  draw() {
    const dpr = fitCanvas(this.canvas) * this.col.scale;
    const { ctx, col, canvas: c } = this;
    ctx.setTransform(1, 0, 0, 1, 0, 0);
    ctx.fillStyle = col.map;
    ctx.fillRect(0, 0, c.width, c.height);
    const s = this.scene;
    if (!s) return;
    const a = this.axis();
    const along = (x, y) => (x - a.x) * a.ux + (y - a.y) * a.uy;
    const across = (x, y) => -(x - a.x) * a.uy + (y - a.y) * a.ux;
    let u0 = Infinity, u1 = -Infinity, z0 = Infinity, z1 = -Infinity;
    const add = (u, z, r = 0) => {
      u0 = Math.min(u0, u - r); u1 = Math.max(u1, u + r);
      z0 = Math.min(z0, z - r); z1 = Math.max(z1, z + r);
    };
    for (const o of s.obstacles || []) add(along(o.center_m[0], o.center_m[1]), o.center_m[2], o.radius_m);
    for (const z of s.zones || []) {
      const [lo, hi] = zoneAlong(z, along);
      for (const h of [z.floor_m, z.ceiling_m]) if (h !== null && h !== undefined) { add(lo, h); add(hi, h); }
    }
    if (s.target_m) add(along(s.target_m[0], s.target_m[1]), s.target_m[2]);
    for (const v of s.starts || []) add(along(v.pos[0], v.pos[1]), v.pos[2]);
    for (const v of s.vehicles || []) if (v.pos_m) add(along(v.pos_m[0], v.pos_m[1]), v.pos_m[2]);
    if (!Number.isFinite(u0)) return;
    if (s.ground !== null && s.ground !== undefined) add(u0, s.ground);
    const pad = 30 * dpr;
    const left = 48 * dpr;
    const su = (c.width - left - pad) / Math.max(u1 - u0, 1);
    const sz = (c.height - 2 * pad) / Math.max(z1 - z0, 1);
    const X = (u) => left + (u - u0) * su;
    const Z = (z) => c.height - pad - (z - z0) * sz;
    const font = (px) => `${Math.round(px * dpr)}px ${col.font}`;

    ctx.strokeStyle = col.grid;
    ctx.fillStyle = col.muted;
    ctx.font = font(10);
    ctx.textAlign = "right";
    const zs = niceLength(Math.max(z1 - z0, 1) / 3);
    ctx.beginPath();
    for (let z = Math.ceil(z0 / zs) * zs; z <= z1; z += zs) {
      ctx.moveTo(left, Z(z)); ctx.lineTo(c.width - pad, Z(z));
      ctx.fillText(`${z} m`, left - 4 * dpr, Z(z) + 3 * dpr);
    }
    ctx.stroke();
    ctx.textAlign = "left";
    ctx.fillText("side view: altitude along the leader's start → target line (vertical scale stretched)", left, 12 * dpr);
    if (s.ground !== null && s.ground !== undefined) {
      ctx.strokeStyle = col.fg;
      ctx.beginPath();
      ctx.moveTo(left, Z(s.ground)); ctx.lineTo(c.width - pad, Z(s.ground));
      ctx.stroke();
    }
    for (const z of s.zones || []) { // its extent along the line, floor to ceiling
      const [lo, hi] = zoneAlong(z, along);
      const top = z.ceiling_m === null || z.ceiling_m === undefined ? pad : Z(z.ceiling_m);
      const bottom = z.floor_m === null || z.floor_m === undefined ? c.height - pad : Z(z.floor_m);
      if (z.inclusion) {
        ctx.setLineDash([6 * dpr, 4 * dpr]);
        ctx.strokeStyle = col.inclusion;
        ctx.strokeRect(X(lo), top, X(hi) - X(lo), bottom - top);
        ctx.setLineDash([]);
      } else {
        ctx.fillStyle = col.obstacle;
        ctx.fillRect(X(lo), top, X(hi) - X(lo), bottom - top);
      }
    }
    for (const o of s.obstacles || []) {
      const u = along(o.center_m[0], o.center_m[1]);
      ctx.beginPath();
      ctx.ellipse(X(u), Z(o.center_m[2]), o.radius_m * su, o.radius_m * sz, 0, 0, 2 * Math.PI);
      ctx.fillStyle = col.obstacle;
      ctx.fill();
      ctx.fillStyle = col.muted;
      ctx.textAlign = "center";
      ctx.fillText(`${Math.round(across(o.center_m[0], o.center_m[1]))} m off`, X(u), Z(o.center_m[2]));
    }
    ctx.lineWidth = 1.2 * dpr;
    for (const id in s.plan || {}) {
      ctx.strokeStyle = col.plan;
      ctx.beginPath();
      s.plan[id].position_m.forEach((p, j) => {
        const x = X(along(p[0], p[1])), y = Z(p[2]);
        if (j) ctx.lineTo(x, y);
        else ctx.moveTo(x, y);
      });
      ctx.stroke();
    }
    for (const v of s.vehicles || []) {
      const trail = s.trails && s.trails.get(v.id);
      if (!trail || trail.length < 2) continue;
      ctx.strokeStyle = vehicleColour(col, v);
      ctx.globalAlpha = 0.6;
      ctx.beginPath();
      trail.trace(ctx, (tx, ty) => X(along(tx, ty)), (_tx, _ty, tz) => Z(tz), 4);
      ctx.stroke();
      ctx.globalAlpha = 1;
    }
    if (s.target_m) {
      const x = X(along(s.target_m[0], s.target_m[1])), y = Z(s.target_m[2]);
      ctx.strokeStyle = col.target;
      ctx.lineWidth = 2 * dpr;
      ctx.beginPath();
      ctx.moveTo(x - 8 * dpr, y); ctx.lineTo(x + 8 * dpr, y);
      ctx.moveTo(x, y - 8 * dpr); ctx.lineTo(x, y + 8 * dpr);
      ctx.stroke();
    }
    for (const v of s.starts || []) {
      ctx.strokeStyle = col.muted;
      ctx.beginPath();
      ctx.arc(X(along(v.pos[0], v.pos[1])), Z(v.pos[2]), 4 * dpr, 0, 2 * Math.PI);
      ctx.stroke();
    }
    for (const v of s.vehicles || []) {
      if (!v.pos_m) continue;
      ctx.fillStyle = vehicleColour(col, v);
      ctx.beginPath();
      ctx.arc(X(along(v.pos_m[0], v.pos_m[1])), Z(v.pos_m[2]), (v.role === "leader" ? 5 : 4) * dpr, 0, 2 * Math.PI);
      ctx.fill();
    }
  }
}
