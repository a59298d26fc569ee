// The service's REST API and the page's WebSocket (/ws/view), with reconnection.
//
// A service started with API tokens answers 401 without one: the page then asks for a token
// once (or takes it from the address's fragment, `/#token=…`, which no request carries) and
// keeps it in sessionStorage; requests send it as `Authorization: Bearer …`, the WebSocket
// as its subprotocol `bearer.…` (a browser cannot set headers on a WebSocket).

const TOKEN_KEY = "gcs-ppf-token";
let asking = null; // the one prompt shown while several requests wait for a token

function takeFragmentToken() {
  const m = /(?:^#|&)token=([^&]+)/.exec(location.hash);
  if (!m) return;
  sessionStorage.setItem(TOKEN_KEY, decodeURIComponent(m[1]));
  history.replaceState(null, "", location.pathname + location.search);
}
takeFragmentToken();

/** The token the page holds (null: none; an open service needs none). */
export function token() {
  return sessionStorage.getItem(TOKEN_KEY);
}

/** Ask the operator for a token (once for all requests waiting); resolves to it or null. */
export function askToken(why) {
  if (!asking) {
    asking = Promise.resolve().then(() => {
      const given = window.prompt(`${why}\nAPI token (gcs-ppf token NAME makes one):`, "");
      if (given && given.trim()) sessionStorage.setItem(TOKEN_KEY, given.trim());
      else sessionStorage.removeItem(TOKEN_KEY);
      asking = null;
      return token();
    });
  }
  return asking;
}

/** A failed request, in words a person reads: `message`, the HTTP `status` (0: no answer),
 * and the API's `detail` (a string, or pydantic's list of field errors for a 422). */
export class ApiError extends Error {
  constructor(message, status, detail) {
    super(message);
    this.status = status;
    this.detail = detail;
  }
}

function send(method, path, body) {
  const headers = body === undefined ? {} : { "Content-Type": "application/json" };
  const held = token();
  if (held) headers.Authorization = `Bearer ${held}`;
  return fetch(path, {
    method,
    headers,
    body: body === undefined ? undefined : JSON.stringify(body),
  });
}

/** Calls the API; resolves to the JSON body (null for 204), throws ApiError otherwise.
 * A 401 asks for a token once and sends the request again with it. */
export async function api(method, path, body) {
  let response;
  try {
    response = await send(method, path, body);
    if (response.status === 401) {
      const why = token() ? "The service does not know this token." : "The service needs a token.";
      if (await askToken(why)) response = await send(method, path, body);
    }
  } catch (err) {
    throw new ApiError(`The service did not answer ${method} ${path} (is it running?)`, 0, null);
  }
  if (response.status === 204) return null;
  let data = null;
  try {
    data = await response.json();
  } catch (err) {
    data = null;
  }
  if (!response.ok) {
    const detail = data && data.detail !== undefined ? data.detail : response.statusText;
    const text = typeof detail === "string" ? detail : `${detail.length} field error(s)`;
    throw new ApiError(`${method} ${path}: ${text}`, response.status, detail);
  }
  return data;
}

const clock = () => new Date().toLocaleTimeString([], { hour12: false });

/**
 * The view stream: calls `onFrame(frame)` for every frame and `onState(state, words)` when
 * the connection changes (state: "connecting" | "live" | "lost"). Reconnects by itself with
 * a growing delay (0.5 s … 5 s); a stream silent for STALE_MS is treated as lost.
 */
export class ViewStream {
  static STALE_MS = 4000;

  constructor(onFrame, onState) {
    this.onFrame = onFrame;
    this.onState = onState;
    this.missionId = null;
    this.ws = null;
    this.attempt = 0;
    this.lostAt = null;
    this.lastFrameAt = 0;
    this.timer = null;
    this.watchdog = setInterval(() => this.checkStale(), 1000);
  }

  /** Show `missionId` (null: whatever the service runs); reconnects if it changed. */
  view(missionId) {
    if (missionId === this.missionId && this.ws) return;
    this.missionId = missionId;
    this.reconnect(0);
  }

  url() {
    const scheme = location.protocol === "https:" ? "wss" : "ws";
    const query = this.missionId ? `?mission_id=${this.missionId}` : "";
    return `${scheme}://${location.host}/ws/view${query}`;
  }

  reconnect(delayMs) {
    clearTimeout(this.timer);
    if (this.ws) {
      const old = this.ws;
      this.ws = null;
      old.onclose = old.onerror = old.onmessage = null;
      old.close();
    }
    this.timer = setTimeout(() => this.open(), delayMs);
  }

  open() {
    this.attempt += 1;
    if (!this.lostAt) this.onState("connecting", "Connecting to the service…");
    const held = token();
    const ws = held
      ? new WebSocket(this.url(), ["gcs-ppf", `bearer.${held}`])
      : new WebSocket(this.url());
    this.ws = ws;
    this.opened = false;
    ws.onopen = () => {
      this.opened = true;
      const was = this.lostAt;
      this.attempt = 0;
      this.lostAt = null;
      this.lastFrameAt = performance.now();
      const words = was
        ? `Reconnected to the service at ${clock()}, after ${((Date.now() - was) / 1000).toFixed(0)} s without it.`
        : "Connected to the service.";
      this.onState("live", words, Boolean(was));
    };
    ws.onmessage = (msg) => {
      this.lastFrameAt = performance.now();
      let frame;
      try {
        frame = JSON.parse(msg.data);
      } catch (err) {
        return;
      }
      this.onFrame(frame);
    };
    ws.onclose = (ev) => {
      if (this.ws !== ws) return;
      this.ws = null;
      if (!this.opened) {
        // A refused handshake looks like a service that is down: ask the API which it is
        // (a 401 there asks for a token).
        api("GET", "/vehicles").catch(() => {});
      }
      this.lost(`the connection closed (code ${ev.code}${ev.reason ? ": " + ev.reason : ""})`);
    };
    ws.onerror = () => {};
  }

  lost(why) {
    if (!this.lostAt) this.lostAt = Date.now();
    const delay = Math.min(5000, 500 * 2 ** Math.min(this.attempt, 4));
    const since = new Date(this.lostAt).toLocaleTimeString([], { hour12: false });
    this.onState(
      "lost",
      `Connection to the service lost at ${since}: ${why}. The vehicles keep flying what they` +
        ` were last told; the display is frozen. Retrying in ${(delay / 1000).toFixed(1)} s` +
        ` (attempt ${this.attempt + 1}).`,
    );
    this.reconnect(delay);
  }

  checkStale() {
    if (this.ws && this.ws.readyState === WebSocket.OPEN &&
        performance.now() - this.lastFrameAt > ViewStream.STALE_MS) {
      this.lost(`no data from the service for ${ViewStream.STALE_MS / 1000} s`);
    }
  }
}
