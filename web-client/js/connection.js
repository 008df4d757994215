// The ways to the daemon: HTTP requests (`api`) and the scene's WebSocket, opened again with exponential
// back-off whenever it drops. What goes over the socket is session.js's business.

import { hooks, params, state } from './state.js';
import { setConn, stageMessage } from './status.js';

const TOKEN = params.get('token') || '';  // only for daemons started with an API token

export class HttpError extends Error {
  constructor(status, body) {
    super(body?.error || `HTTP ${status}`);
    this.status = status;
    this.pointer = body?.pointer ?? null;
  }
}

export async function api(method, path, body, contentType = 'application/json', headers = {}) {
  const init = { method, headers: { ...headers }, cache: 'no-store' };
  if (TOKEN) init.headers.Authorization = `Bearer ${TOKEN}`;
  if (body !== undefined) {
    init.body = typeof body === 'string' || body instanceof ArrayBuffer ? body : JSON.stringify(body);
    init.headers['Content-Type'] = contentType;
  }
  const res = await fetch(path, init);
  const text = await res.text();
  let json = null;
  try { json = text ? JSON.parse(text) : null; } catch { json = { error: text }; }
  if (!res.ok) throw new HttpError(res.status, json);
  return json;
}

// PATCHes the resource at `path` with the merge patch `patchFor(current)` makes of it as it is now, applied
// only to that revision (If-Match): edited meanwhile (412), the patch is made again. Answers the PATCH's body.
export async function patchCurrent(path, patchFor) {
  for (let attempt = 1; ; attempt++) {
    const current = await api('GET', path);
    try {
      return await api('PATCH', path, patchFor(current), 'application/merge-patch+json',
        { 'If-Match': `"${current.revision}"` });
    } catch (e) {
      if (!(e instanceof HttpError) || e.status !== 412 || attempt >= 3) throw e;
    }
  }
}

let wsPort = null;
let attempt = 0;
let reconnectTimer = null;

// The daemon's health, which also says where its WebSocket listens.
export async function fetchHealth() {
  const health = await api('GET', '/api/health');
  // Behind a proxy the daemon says so: upgrades then go through the page's own port.
  const pagePort = Number(location.port || (location.protocol === 'https:' ? 443 : 80));
  wsPort = health?.ws_on_http_port ? pagePort : Number(health?.ws_port) || pagePort + 1;
  return health;
}

function scheduleReconnect(link) {
  clearTimeout(reconnectTimer);
  const delay = Math.min(10_000, 400 * 2 ** attempt) * (0.8 + 0.4 * Math.random());
  attempt = Math.min(attempt + 1, 10);
  const seconds = Math.max(1, Math.round(delay / 1000));
  setConn('reconnecting', `Reconnecting in ${seconds} s…`);
  stageMessage(hooks.connects === 0 ? 'Waiting for refractd…' : 'Connection to refractd lost; reconnecting…');
  reconnectTimer = setTimeout(() => connect(link), delay);
}

// Opens the scene's WebSocket (state.ws), and opens it again whenever it drops. `link` says what to do
// around it: `prepare()` before each opening (over HTTP: it fetches the health and picks the scene;
// failing, it is tried again later), then `opened()`, `text(data)` and `binary(blob)` for the messages,
// and `closed()`.
export async function connect(link) {
  clearTimeout(reconnectTimer);
  setConn('connecting', 'Connecting…');
  try {
    await link.prepare();
  } catch (e) {
    console.warn('refractd not reachable', e);
    if (e instanceof HttpError && e.status !== 404 && e.status < 500 && hooks.connects === 0) {
      stageMessage(`Could not load the scene: ${e.message}`);
    }
    scheduleReconnect(link);
    return;
  }
  const proto = location.protocol === 'https:' ? 'wss:' : 'ws:';
  const url = `${proto}//${location.hostname}:${wsPort}/api/scenes/${encodeURIComponent(state.sceneId)}/ws` +
    (TOKEN ? `?token=${encodeURIComponent(TOKEN)}` : '');
  let ws;
  try {
    ws = new WebSocket(url);
  } catch (e) {
    scheduleReconnect(link);
    return;
  }
  ws.binaryType = 'blob';
  state.ws = ws;
  ws.addEventListener('open', () => {
    if (state.ws !== ws) return;
    attempt = 0;
    hooks.connects++;
    if (hooks.connects > 1) hooks.reconnects++;
    setConn('live', 'Live');
    stageMessage('');
    link.opened();
  });
  ws.addEventListener('message', (ev) => {
    if (state.ws !== ws) return;
    if (typeof ev.data === 'string') link.text(ev.data);
    else link.binary(ev.data);
  });
  ws.addEventListener('close', () => {
    if (state.ws !== ws) return;
    state.ws = null;
    link.closed();
    scheduleReconnect(link);
  });
}
