// The mission document on the page: reading a file, the form, the API's field errors.

/** Parses a mission file's text; throws an Error whose message says what is wrong, in words. */
export function parseMission(text, fileName) {
  let doc;
  try {
    doc = JSON.parse(text);
  } catch (err) {
    const where = /position (\d+)/.exec(err.message);
    let at = "";
    if (where) {
      const before = text.slice(0, Number(where[1]));
      const line = before.split("\n").length;
      const col = Number(where[1]) - before.lastIndexOf("\n");
      at = ` (line ${line}, column ${col})`;
    }
    throw new Error(`${fileName} is not a JSON document${at}: ${err.message}. Nothing was sent to the service.`);
  }
  if (doc === null || typeof doc !== "object" || Array.isArray(doc)) {
    throw new Error(`${fileName} is JSON but not a mission: a mission is an object with "target" and "vehicles" (CONVENTIONS §3). Nothing was sent to the service.`);
  }
  return doc;
}

/** The influence radius the planner uses (gcs_ppf/ppf/primitives.py, erratum 4):
 * R = √((keep_out + ρ)² − ρ²), ρ = v/ω. */
export function influenceRadius(speed, turnRate, keepOut) {
  const rho = speed / turnRate;
  return Math.sqrt((keepOut + rho) ** 2 - rho ** 2);
}

/** "vehicles[3].id" → "vehicles.3.id" */
export function normalisePath(path) {
  return path.replace(/\[(\d+)\]/g, ".$1").replace(/^\./, "");
}

/** The API's errors → [{path, message}]: a 422's pydantic list (`loc` names the field; a
 * whole-document check names it at the start of its message), or a message string. */
export function fieldErrors(detail, prefix = "") {
  const out = [];
  const fromText = (text) => {
    const m = /^(?:Value error, )?([A-Za-z_][\w.\[\]]*): (.+)$/s.exec(text.trim());
    return m ? { path: normalisePath(m[1]), message: m[2] } : { path: "", message: text };
  };
  if (typeof detail === "string") {
    const lines = detail.split("\n").filter((l) => /Value error|^\s*\S+\[\d+\]/.test(l));
    for (const line of lines) out.push(fromText(line.replace(/^.*Value error, /, "").replace(/ \[type=.*$/, "")));
    if (!out.length) out.push({ path: "", message: detail });
    return out;
  }
  for (const d of detail || []) {
    const loc = (d.loc || []).slice(1).join(".");
    const msg = (d.msg || "").replace(/^Value error, /, "");
    if (!loc && /^[A-Za-z_][\w.\[\]]*: /.test(msg)) out.push(fromText(msg));
    else out.push({ path: normalisePath((prefix && loc ? prefix + "." : prefix) + loc), message: msg });
  }
  return out;
}

const asNumber = (raw) => {
  const t = raw.trim();
  if (t === "") return null;
  const n = Number(t);
  return Number.isFinite(n) ? n : raw; // the service names the field if it is not a number
};

function setAt(doc, path, value) {
  const keys = path.split(".");
  let o = doc;
  for (const k of keys.slice(0, -1)) o = o[k];
  o[keys[keys.length - 1]] = value;
}

function getAt(doc, path) {
  return path.split(".").reduce((o, k) => (o == null ? undefined : o[k]), doc);
}

const fmt = (v) => (v === null || v === undefined ? "" : typeof v === "number" ? String(Math.round(v * 1e6) / 1e6) : String(v));

/** Builds the form for `doc` in `form`; `onChange(path, kind)` after each edit (kind:
 * "obstacles" for an obstacle field, "mission" otherwise). Deleting an obstacle calls
 * `onDelete(index)`. */
export function renderForm(form, doc, onChange, onDelete) {
  form.replaceChildren();
  const input = (path, opts = {}) => {
    const el = document.createElement(opts.select ? "select" : "input");
    el.dataset.path = path;
    if (opts.select) {
      for (const o of opts.select) el.add(new Option(o, o));
      el.value = getAt(doc, path) ?? opts.select[0];
    } else {
      el.value = fmt(getAt(doc, path));
      el.inputMode = opts.text ? "text" : "decimal";
    }
    el.setAttribute("aria-label", path);
    el.addEventListener("change", () => {
      const value = opts.select || opts.text ? el.value : asNumber(el.value);
      setAt(doc, path, value === null && !opts.nullable ? el.value : value);
      onChange(path, path.startsWith("obstacles") ? "obstacles" : "mission");
    });
    return el;
  };
  const field = (parent, label, path, opts = {}) => {
    const row = document.createElement("div");
    row.className = "field";
    row.dataset.path = path;
    const l = document.createElement("label");
    l.textContent = label;
    row.append(l);
    const value = getAt(doc, path);
    if (Array.isArray(value)) {
      const vec = document.createElement("div");
      vec.className = "vec";
      value.forEach((_, i) => vec.append(input(`${path}.${i}`)));
      row.append(vec);
    } else {
      row.append(input(path, opts));
    }
    parent.append(row);
  };
  const fieldset = (title, open = true) => {
    const fs = document.createElement("fieldset");
    const lg = document.createElement("legend");
    lg.textContent = title;
    fs.append(lg);
    if (!open) fs.classList.add("closed");
    form.append(fs);
    return fs;
  };

  const general = fieldset("Mission");
  if ("name" in doc) field(general, "name", "name", { text: true });
  if (Array.isArray(doc.target)) field(general, "target x, y, z (m)", "target");
  field(general, "ground z (m)", "ground", { nullable: true });
  if (doc.planner && typeof doc.planner === "object") {
    if ("method" in doc.planner) field(general, "method", "planner.method", { select: ["ppf", "apf"] });
    for (const k of ["dt", "max_time"]) if (k in doc.planner) field(general, `planner ${k}`, `planner.${k}`);
  }

  if (Array.isArray(doc.vehicles)) {
    const fs = fieldset(`Vehicles (${doc.vehicles.length})`);
    const table = document.createElement("table");
    table.className = "grid";
    table.innerHTML = "<thead><tr><th>id</th><th>role</th><th>position x, y, z</th><th>yaw</th><th>slot x, y, z</th></tr></thead>";
    const body = document.createElement("tbody");
    doc.vehicles.forEach((v, i) => {
      const tr = document.createElement("tr");
      tr.dataset.path = `vehicles.${i}`;
      const cell = (...els) => {
        const td = document.createElement("td");
        td.append(...els);
        tr.append(td);
      };
      cell(input(`vehicles.${i}.id`));
      cell(input(`vehicles.${i}.role`, { select: ["leader", "wingman"] }));
      cell(...(Array.isArray(v.position) ? v.position.map((_, k) => input(`vehicles.${i}.position.${k}`)) : []));
      cell(input(`vehicles.${i}.yaw`));
      cell(...(Array.isArray(v.slot) ? v.slot.map((_, k) => input(`vehicles.${i}.slot.${k}`)) : []));
      body.append(tr);
    });
    table.append(body);
    fs.append(table);
  }

  const obstacles = Array.isArray(doc.obstacles) ? doc.obstacles : [];
  const fs = fieldset(`Obstacles (${obstacles.length})`);
  fs.dataset.path = "obstacles";
  const table = document.createElement("table");
  table.className = "grid";
  table.id = "obstacle-table";
  table.innerHTML = "<thead><tr><th>#</th><th>centre x, y, z (m)</th><th>radius</th><th></th></tr></thead>";
  const body = document.createElement("tbody");
  obstacles.forEach((o, i) => {
    const tr = document.createElement("tr");
    tr.dataset.path = `obstacles.${i}`;
    tr.dataset.index = String(i);
    const td = (...els) => {
      const c = document.createElement("td");
      c.append(...els);
      tr.append(c);
      return c;
    };
    td(String(i));
    td(...(Array.isArray(o.center) ? o.center.map((_, k) => input(`obstacles.${i}.center.${k}`)) : []));
    td(input(`obstacles.${i}.radius`));
    const del = document.createElement("button");
    del.type = "button";
    del.textContent = "✕";
    del.title = `Remove obstacle ${i}`;
    del.addEventListener("click", () => onDelete(i));
    td(del);
    body.append(tr);
  });
  table.append(body);
  fs.append(table);

  if (doc.limits && typeof doc.limits === "object") {
    const lim = fieldset("Limits");
    for (const k of Object.keys(doc.limits)) field(lim, k, `limits.${k}`);
  }
  if (doc.origin && typeof doc.origin === "object") {
    const o = fieldset("Origin (WGS-84)");
    for (const k of Object.keys(doc.origin)) field(o, k, `origin.${k}`);
  }
}

/** Puts each error next to its field in `form` (the closest enclosing path that has one);
 * returns the errors that have no place there. */
export function showFieldErrors(form, errors) {
  clearFieldErrors(form);
  const loose = [];
  for (const e of errors) {
    let path = e.path;
    let el = null;
    while (path) {
      const sel = `[data-path="${CSS.escape(path)}"]`;
      el = form.querySelector(`input${sel}, select${sel}`) || form.querySelector(sel);
      if (el) break;
      path = path.includes(".") ? path.slice(0, path.lastIndexOf(".")) : "";
    }
    if (!el) {
      loose.push(e);
      continue;
    }
    const text = `${e.path}: ${e.message}`;
    if (el.matches("input, select")) el.classList.add("invalid");
    const row = el.closest("tr");
    if (row) {
      const er = document.createElement("tr");
      er.className = "error-row field-error";
      const td = document.createElement("td");
      td.colSpan = row.children.length;
      td.textContent = text;
      er.append(td);
      row.after(er);
      continue;
    }
    const box = el.closest(".field") || el.closest("fieldset") || el;
    const div = document.createElement("div");
    div.className = "field-error";
    div.textContent = text;
    box.append(div);
  }
  return loose;
}

export function clearFieldErrors(form) {
  form.querySelectorAll(".field-error").forEach((e) => e.remove());
  form.querySelectorAll(".invalid").forEach((e) => e.classList.remove("invalid"));
}
