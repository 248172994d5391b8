// The server's REST API and WebSocket stream: the bearer token (kept in sessionStorage), which
// optional routes this server has (read from its OpenAPI document, so that probing never causes a
// 404), JSON requests whose errors carry the server's message, and a WebSocket that reconnects by
// itself.

const TOKEN_KEY = "harrier.token";
export const API = "api/v1";

/** The API token entered on this tab (sessionStorage), or "". */
export function getToken() {
  try {
    return sessionStorage.getItem(TOKEN_KEY) || "";
  } catch {
    return "";
  }
}

export function setToken(token) {
  try {
    if (token) sessionStorage.setItem(TOKEN_KEY, token);
    else sessionStorage.removeItem(TOKEN_KEY);
  } catch {
    /* storage disabled: the token lives only as long as the page */
  }
}

/** An API error: HTTP status (0 for a network error) and the server's message. */
export class ApiError extends Error {
  constructor(status, message) {
    super(message);
    this.status = status;
  }
  /** One line for the operator. */
  describe() {
    if (this.status === 0) return `no answer from the server (${this.message})`;
    if (this.status === 401) return `401 token refused: ${this.message}`;
    return `${this.status}: ${this.message}`;
  }
}

/**
 * A JSON request. Mutating methods (and every method once a token is set) send the token.
 * Resolves with the parsed body (null for 204), rejects with an ApiError.
 */
export async function request(method, path, body) {
  const headers = { Accept: "application/json" };
  const token = getToken();
  if (token) headers.Authorization = `Bearer ${token}`;
  if (body !== undefined) headers["Content-Type"] = "application/json";
  let res;
  try {
    res = await fetch(`${API}/${path}`, {
      method,
      headers,
      body: body === undefined ? undefined : JSON.stringify(body),
      cache: "no-store",
    });
  } catch (e) {
    throw new ApiError(0, e.message || String(e));
  }
  const text = await res.text();
  let json = null;
  if (text) {
    try {
      json = JSON.parse(text);
    } catch {
      json = null;
    }
  }
  if (!res.ok) {
    // Errors are {"error": …}; a command that timed out (504) answers its outcome instead.
    const msg = (json && (json.error || (json.result && `${json.command || "command"}: ${json.result}${json.attempts ? ` after ${json.attempts} attempts` : ""}`))) || text || res.statusText || "error";
    const err = new ApiError(res.status, msg);
    err.body = json;
    throw err;
  }
  return json;
}

export const get = (path) => request("GET", path);

/** GET returning text (Prometheus metrics). */
export async function getText(path) {
  const headers = {};
  const token = getToken();
  if (token) headers.Authorization = `Bearer ${token}`;
  let res;
  try {
    res = await fetch(`${API}/${path}`, { headers, cache: "no-store" });
  } catch (e) {
    throw new ApiError(0, e.message || String(e));
  }
  const text = await res.text();
  if (!res.ok) throw new ApiError(res.status, text);
  return text;
}

/**
 * The optional routes this server serves, from `/api/openapi.json` (missing routes would answer
 * 404; asking the document instead keeps the console clean).
 */
export async function features() {
  const f = { truth: false, world: false, aircraft: false, map: false, assignments: false, commands: false, estimator: true, metrics: true };
  try {
    const res = await fetch("api/openapi.json", { cache: "no-store" });
    if (!res.ok) return f;
    const doc = await res.json();
    const paths = Object.keys(doc.paths || {});
    const has = (p) => paths.includes(p);
    f.truth = has("/api/v1/truth");
    f.world = has("/api/v1/world");
    f.aircraft = has("/api/v1/aircraft");
    f.map = has("/api/v1/map");
    f.assignments = has("/api/v1/assignments");
    f.commands = paths.some((p) => /^\/api\/v1\/vehicles\/\{[^}]+\}\/commands$/.test(p));
    f.estimator = has("/api/v1/estimator");
    f.metrics = has("/api/v1/metrics");
  } catch {
    /* the defaults: only what every server has */
  }
  return f;
}

/**
 * The WebSocket stream with automatic reconnection (backoff 0.5 → 5 s). `onMessage(msg)` gets each
 * parsed message; `onState(state)` "connecting" | "open" | "closed".
 */
export class Stream {
  constructor(onMessage, onState) {
    this.onMessage = onMessage;
    this.onState = onState;
    this.state = "connecting";
    this.reconnects = 0;
    this.opened = 0;
    this.messages = 0;
    this.lastMessageAt = 0;
    this.delay = 500;
    this.ws = null;
    this.timer = null;
    this.watchdog = setInterval(() => this.checkAlive(), 2000);
  }

  url() {
    const scheme = location.protocol === "https:" ? "wss:" : "ws:";
    const base = new URL(`${API}/ws`, location.href);
    let url = `${scheme}//${base.host}${base.pathname}`;
    const token = getToken();
    if (token) url += `?token=${encodeURIComponent(token)}`;
    return url;
  }

  connect() {
    clearTimeout(this.timer);
    this.setState("connecting");
    let ws;
    try {
      ws = new WebSocket(this.url());
    } catch {
      this.retry();
      return;
    }
    this.ws = ws;
    ws.onopen = () => {
      if (this.ws !== ws) return;
      this.delay = 500;
      this.opened += 1;
      if (this.opened > 1) this.reconnects += 1;
      this.lastMessageAt = performance.now();
      this.setState("open");
    };
    ws.onmessage = (ev) => {
      if (this.ws !== ws) return;
      this.messages += 1;
      this.lastMessageAt = performance.now();
      let msg;
      try {
        msg = JSON.parse(ev.data);
      } catch {
        return;
      }
      this.onMessage(msg);
    };
    ws.onclose = () => {
      if (this.ws !== ws) return;
      this.ws = null;
      this.setState("closed");
      this.retry();
    };
    ws.onerror = () => {
      /* onclose follows and reconnects */
    };
  }

  retry() {
    clearTimeout(this.timer);
    this.timer = setTimeout(() => this.connect(), this.delay);
    this.delay = Math.min(this.delay * 2, 5000);
  }

  /** A connection that is open but silent for 15 s (a half-open TCP link) is replaced. */
  checkAlive() {
    if (this.state === "open" && performance.now() - this.lastMessageAt > 15000 && this.ws) {
      const ws = this.ws;
      this.ws = null;
      ws.close();
      this.setState("closed");
      this.retry();
    }
  }

  /** Reconnects now (e.g. after the token changed, for servers whose reads need it). */
  restart() {
    if (this.ws) {
      const ws = this.ws;
      this.ws = null;
      ws.close();
    }
    this.delay = 500;
    this.connect();
  }

  setState(s) {
    if (this.state === s) return;
    this.state = s;
    this.onState(s);
  }
}
