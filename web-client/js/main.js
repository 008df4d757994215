// Refract browser client: shows frames streamed by refractd and edits the scene with merge patches.
//
// Flow control: at most one request is in flight on the WebSocket, or two when the first is an
// interactive one: the daemon renders the newest request after the frame it is on (latest wins), so a
// second edit sent while a preview renders keeps its render thread busy instead of idle for the
// frame's delivery, decode and our answer. A still request may follow two previews (see slotFree).
// Edits made meanwhile are coalesced into one pending merge patch, sent when a request slot frees (a
// frame, or an error, answers it).
// Dragging sends "interactive" requests; releasing asks for a "still" (full quality) frame.
// Frames are drawn scaled to the canvas with smooth filtering: interactive ones arrive smaller.

import { buildControls } from './controls.js';
import * as S from './scene.js';

const params = new URLSearchParams(location.search);
const MAX_SIDE = Math.max(64, Math.min(768, Number(params.get('maxpx')) || 768));
const MIN_SIDE = 64;
const TOKEN = params.get('token') || '';  // only for daemons started with an API token
const REQUEST_TIMEOUT_MS = 180_000;  // a lost answer: give up on it and reconnect
const QUALITY_RANK = { interactive: 0, still: 1 };
const MAX_IN_FLIGHT = 2;  // requests on the WebSocket at once, the first an interactive one (see above)
const ORBIT_STEP = 5 * Math.PI / 180;  // arrow keys
const ZOOM_STEP = 1.1;
const MAX_CANVAS = 2048;  // canvas backing store, per side
const DIM_AFTER_MS = 300;  // a frame pending this long (not while dragging) dims the one shown
const OBJECT_SIZE = 2;  // metres: the built-in meshes span [-1, 1]; uploads are fitted to this
// Bounds of the built-in meshes in their own units (server/mesh/mesh.cpp); uploads report theirs.
const BUILTIN_BOUNDS = {
  sphere: { min: [-1, -1, -1], max: [1, 1, 1] },
  cube: { min: [-1, -1, -1], max: [1, 1, 1] },
  torus: { min: [-1.35, -0.35, -1.35], max: [1.35, 0.35, 1.35] },
  prism: { min: [-0.866, -0.5, -1], max: [0.866, 1, 1] },
  bunny: { min: [-0.96883, -1, -0.56078], max: [0.96883, 1, 0.56078] },
};

const $ = (id) => document.getElementById(id);
const canvas = $('view');
const ctx = canvas.getContext('2d', { willReadFrequently: true, alpha: false });
const stage = $('stage');

const state = {
  sceneId: null,
  confirmed: null,        // the scene document as the daemon last told us (plus our accepted patches)
  confirmedRevision: null,
  inflight: [],           // requests sent and not yet answered, oldest first: { seq, patch, quality, sentAt, retry }
  pending: null,          // coalesced merge patch not yet sent
  pendingQuality: null,   // 'interactive' | 'still' | null: a frame is wanted
  forceFrame: false,      // request a frame even if nothing changed (connect, Refine)
  retryNext: false,       // the next send re-sends what was left of a rejected patch
  seq: 0,
  ws: null,
  wsPort: null,
  connected: false,
  attempt: 0,
  reconnectTimer: null,
  watchdog: null,
  frameMeta: null,        // text header of the frame whose PNG comes next
  lastFrame: null,        // { revision, quality }
  drawToken: 0,
  drawnToken: 0,
  frameTimes: [],
  lightMode: false,
  drag: null,
  pointers: new Map(),
  replacing: false,       // the scene is being replaced over HTTP (example, import): hold the WebSocket
  newScene: false,        // the scene was replaced and its first frame is not drawn yet
  frame: null,            // { bitmap, width, height }: the frame shown, kept to redraw on resize
  lastPng: null,          // the PNG of the frame shown, for "Save PNG"
  example: null,          // { name, doc }: the example the scene still is
  meshBounds: {},         // uploaded mesh name -> bounds in its own units
  ticker: null,
  playing: null,          // { seq, name, field, at }: keyframes playing into this view (at: the last frame's place)
  selected: { light: null, object: null },  // the light and object the panel edits (null: the first by name)
  pendingSelection: null, // `selected` as it was before the edits now pending
};

// Named one-shot timers (debounces); `settled` below waits for all of them.
const timers = new Map();
function later(name, fn, ms) {
  clearTimeout(timers.get(name));
  timers.set(name, setTimeout(() => { timers.delete(name); fn(); }, ms));
}

// Test and debugging hooks: plain data, read by the end-to-end test via page.evaluate.
const hooks = {
  framesReceived: 0,
  lastRevision: null,
  lastSeq: null,
  lastMeta: null,
  lastError: null,
  errors: 0,
  sceneId: null,
  connected: false,
  reconnects: 0,
  connects: 0,
  meshUploads: 0,
  lastUpload: null,
  device: null,
  requestsSent: 0,
  sent: { interactive: 0, still: 0 },  // requests by quality
  maxInFlight: 0,
  doc: () => view(),
  lastQuality: null,
  example: null,       // name of the example the scene still is
  lastDraw: null,      // how the last frame was drawn: source and canvas sizes, smoothing
  lastInteractiveDraw: null,
  dims: 0,             // times the frame shown was dimmed for a pending one
  downloads: 0,
  playedFrames: 0,     // frames of played animations drawn
  playing: () => state.playing?.name ?? null,
  busy: () => Boolean(state.inflight.length || state.pendingQuality || state.replacing),
  // Connected, nothing in flight or queued or about to be, and the last frame is a decoded still.
  settled: () => hooks.connected && !state.inflight.length && !state.pendingQuality && !state.replacing &&
    timers.size === 0 && state.drawnToken === state.drawToken && hooks.lastQuality === 'still',
};
window.refract = hooks;

// ---- the document as the user sees it ------------------------------------------------------------

function view() {
  let doc = sentDocument();
  if (state.pending) doc = S.applyMergePatch(doc, state.pending);
  return doc;
}

// The document as the panel shows it: the selected light and object as `light` and `object`.
function panel() {
  return S.panelDocument(view(), state.selected);
}

const controls = buildControls($('controls'), (patch, final) => edit(patch, final), {
  upload: uploadMesh, uploadEnvironment, meshPatch, loadExample, importScene, exportScene, playKeyframes, stopPlay,
  members: { selected: selectedMember, select: selectMember, add: addMember, remove: removeMember, rename: renameMember },
});

// ---- the outliner: which light and object the panel edits; adding, removing, renaming them ------------

// What Add puts in the scene, by kind: a point light beside the others; a small sphere beside the chosen
// object (so it is in view), sharing its Abbe number as the daemon requires.
const NEW_MEMBER = {
  light: () => ({ type: 'point', position: [-2, 2.5, 1.5], intensity: 10 }),
  object: (doc) => {
    const chosen = doc.object || {};
    const placed = S.placedBounds(boundsOf(chosen.mesh) || BUILTIN_BOUNDS.sphere, chosen);
    return { mesh: 'sphere', ...S.besideObject(placed, cameraOf(doc)), abbe: chosen.abbe ?? 0 };
  },
};
const ARTICLE = { light: 'a', object: 'an' };

function selectedMember(kind) {
  return S.selectedName(view(), kind, state.selected[kind]);
}

function selectMember(kind, name) {
  state.selected[kind] = name;
  controls.clearErrors();
  controls.update(panel(), { force: true });
  updateLightMarker();
}

function addMember(kind) {
  const name = S.freeName(view(), kind, kind);
  edit({ [S.COLLECTIONS[kind]]: { [name]: NEW_MEMBER[kind](panel()) } }, true);
  selectMember(kind, name);
  announce(`Added ${ARTICLE[kind]} ${kind}, ${name}`);
}

function removeMember(kind) {
  const name = selectedMember(kind);
  if (!name || S.memberNames(view(), kind).length < 2) return;
  edit({ [S.COLLECTIONS[kind]]: { [name]: null } }, true);
  selectMember(kind, null);
  announce(`Removed the ${kind} ${name}`);
}

// A rename is one patch: the member under its new name, null under its old one.
function renameMember(kind, to, field) {
  const from = selectedMember(kind);
  if (!from || to === from) return;
  if (!S.validName(to)) return void refuseName(field, `“${to}” is not a name: use 1 to 64 letters, digits, “_”, “.” or “-” (not “.” or “..”).`);
  if (S.memberNames(view(), kind).includes(to)) return void refuseName(field, `There is already ${ARTICLE[kind]} ${kind} named “${to}”.`);
  const plural = S.COLLECTIONS[kind];
  edit({ [plural]: { [from]: null, [to]: view()[plural][from] } }, true);
  selectMember(kind, to);
  announce(`Renamed the ${kind} ${from} to ${to}`);
}

// A name the daemon would refuse: said at the outliner, and nothing is sent.
function refuseName(field, message) {
  field.setError(message);
  hooks.lastError = { error: message, pointer: field.ptrs[0], seq: null };
  hooks.errors++;
  announce(message);
}

// Queues an edit (or, with a null patch, just a frame) and sends it when the link is free.
function edit(patch, final) {
  state.pendingSelection ??= { ...state.selected };
  if (patch) state.pending = S.composePatches(state.pending, S.memberPatch(patch, view(), state.selected));
  state.pendingQuality = final ? 'still' : 'interactive';
  if (patch) scheduleViewUpdate();
  pump();
}

// Controls and the light marker follow the edited document, at most once per animation frame.
let viewUpdateQueued = false;
function scheduleViewUpdate() {
  if (viewUpdateQueued) return;
  viewUpdateQueued = true;
  requestAnimationFrame(() => {
    viewUpdateQueued = false;
    controls.update(panel());
    updateLightMarker();
    checkExample();
  });
}

// The example's name stays shown while the scene is that example (the image size aside).
const withoutImageSize = (doc) => S.applyMergePatch(doc, { image: { width: null, height: null } });
function checkExample() {
  if (state.example && !S.deepEqual(withoutImageSize(view()), state.example.doc)) state.example = null;
  hooks.example = state.example?.name ?? null;
  controls.example.showLoaded(hooks.example);
}

function requestFrame(quality = 'still') {
  state.forceFrame = true;
  if (!state.pendingQuality || QUALITY_RANK[quality] > QUALITY_RANK[state.pendingQuality]) state.pendingQuality = quality;
  pump();
}

// Whether another request may go now: none is in flight, or only interactive ones, fewer than
// MAX_IN_FLIGHT of them (see the top). A still frame (a drag's release) goes even past that: at the
// daemon it takes the place of the preview still queued there (latest wins), so the full-quality frame
// comes after the preview rendering, not after two.
function slotFree() {
  const n = state.inflight.length;
  const previews = state.inflight.every((inf) => inf.quality === 'interactive');
  return n === 0 || (previews && (n < MAX_IN_FLIGHT || (n === MAX_IN_FLIGHT && state.pendingQuality === 'still')));
}

function pump() {
  const ws = state.ws;
  if (!ws || ws.readyState !== WebSocket.OPEN || !slotFree() || state.replacing || !state.pendingQuality ||
      !state.confirmed) return;
  const patch = state.pending ? S.prunePatch(sentDocument(), state.pending) : null;
  const quality = state.pendingQuality;
  const force = state.forceFrame;
  const selection = state.pendingSelection ?? { ...state.selected };
  state.pending = null;
  state.pendingSelection = null;
  state.pendingQuality = null;
  state.forceFrame = false;
  const retry = state.retryNext;
  state.retryNext = false;
  // Nothing changed and we already show (or the answer in flight will show) this quality or better.
  const last = state.lastFrame;
  const covered = state.inflight.length ? quality === 'interactive'
    : last && last.revision === state.confirmedRevision && QUALITY_RANK[last.quality] >= QUALITY_RANK[quality];
  if (!patch && !force && covered) return;

  const seq = ++state.seq;
  const message = { seq, quality };
  if (patch) message.patch = patch;
  ws.send(JSON.stringify(message));
  // errorsBefore: an error shown after this request was sent is newer than its edit and must outlive it.
  // selection: what the outliner had chosen before the edits sent; a rejected Add or Rename goes back to it.
  state.inflight.push({ seq, patch, quality, sentAt: performance.now(), retry, errorsBefore: hooks.errors, selection });
  hooks.requestsSent++;
  hooks.sent[quality]++;
  hooks.maxInFlight = Math.max(hooks.maxInFlight, state.inflight.length);
  clearTimeout(state.watchdog);
  state.watchdog = setTimeout(() => {
    // No answer: assume the connection is wedged; reconnecting re-sends the edit.
    if (state.inflight.some((inf) => inf.seq === seq) && state.ws === ws) ws.close(4000, 'request timed out');
  }, REQUEST_TIMEOUT_MS);
  updateProgress();
}

// The document as the daemon will have it once the requests in flight are applied: what a new patch
// is pruned against.
function sentDocument() {
  let doc = state.confirmed || {};
  for (const inf of state.inflight) if (inf.patch) doc = S.applyMergePatch(doc, inf.patch);
  return doc;
}

// Takes the requests an answer with `seq` covers out of those in flight and returns them, oldest first:
// a frame answers its own request and every older one (latest wins: the daemon rendered the newest).
function answered(seq) {
  if (seq === undefined) return state.inflight.splice(0, 1);  // an older daemon: one request at a time
  if (seq === null) return [];                                // pushed for someone else's edit
  const n = state.inflight.filter((inf) => inf.seq <= seq).length;
  const done = state.inflight.splice(0, n);
  if (!state.inflight.length) clearTimeout(state.watchdog);
  return done;
}

// ---- WebSocket messages --------------------------------------------------------------------------

function onText(data) {
  let msg;
  try { msg = JSON.parse(data); } catch { return; }
  if (msg.type === 'frame') state.frameMeta = msg;
  else if (msg.type === 'error' && state.playing && msg.seq === state.playing.seq) playFailed(msg);
  else if (msg.type === 'error') onServerError(msg);
  else if (msg.type === 'stopped') endPlay(`Stopped after ${msg.frames} frame${msg.frames === 1 ? '' : 's'}.`);
}

function onBinary(blob) {
  const meta = state.frameMeta || {};
  state.frameMeta = null;
  // The requests this frame answers (its own and older ones); a frame with a null seq answers nobody
  // here: the daemon pushed it for another client's edit.
  const done = answered(meta.seq);
  const inf = done[done.length - 1];
  const quality = meta.quality || (inf ? inf.quality : 'still');
  let ours = 0;  // edits this frame holds: each may have made a revision
  for (const req of done) {
    if (!req.patch) continue;
    state.confirmed = S.applyMergePatch(state.confirmed, req.patch);
    ours++;
  }
  if (inf) {
    hooks.latencyMs = Math.round(performance.now() - inf.sentAt);
    // An accepted edit makes earlier complaints stale: a failed upload, a refused Add, Remove or Rename, a
    // frame that could not render.
    if (inf.patch && !inf.retry && hooks.errors === inf.errorsBefore) {
      for (const outliner of controls.outliners) outliner.clearError();
      controls.mesh.clearError();
      controls.file.clearError();
      controls.file.status.textContent = '';
      $('global-error').hidden = true;
    }
  }
  if (typeof meta.revision === 'number') {
    const expected = state.confirmedRevision;
    const consistent = meta.revision === expected ||
      (expected !== null && meta.revision > expected && meta.revision <= expected + ours);
    state.confirmedRevision = meta.revision;
    if (!consistent && expected !== null) resync();  // someone else edited the scene
  }
  if (meta.play && state.playing) {
    hooks.playedFrames++;
    state.playing.at = meta.play;
    if (meta.play.last) endPlay(`Played ${state.playing.name}: ${meta.play.frames} frames.`);
  }
  state.lastFrame = { revision: state.confirmedRevision, quality };
  state.lastPng = blob;
  $('save-png').disabled = false;
  const token = ++state.drawToken;
  drawFrame(blob, meta, token, quality).catch((e) => console.warn('frame decode failed', e));
  pump();
}

async function drawFrame(blob, meta, token, quality) {
  const bitmap = await createImageBitmap(blob.type ? blob : new Blob([blob], { type: 'image/png' }));
  if (token < state.drawnToken) { bitmap.close(); return; }
  state.drawnToken = token;
  if (state.newScene && meta.revision >= state.confirmedRevision) state.newScene = false;
  state.frame?.bitmap.close();
  // The header says what this frame is; interactive frames (and, later, frames the daemon scales to
  // meet its time budget) are smaller than the image the canvas shows.
  state.frame = { bitmap, width: meta.width || bitmap.width, height: meta.height || bitmap.height };
  paintFrame();
  if (quality === 'interactive') hooks.lastInteractiveDraw = hooks.lastDraw;
  stage.classList.add('has-frame');
  const now = performance.now();
  // fps of a stream of frames: a pause of a second starts a new measurement.
  if (state.frameTimes.length && now - state.frameTimes[state.frameTimes.length - 1] > 1000) state.frameTimes = [];
  state.frameTimes.push(now);
  while (state.frameTimes.length > 1 && now - state.frameTimes[0] > 3000) state.frameTimes.shift();
  hooks.framesReceived++;
  hooks.lastRevision = typeof meta.revision === 'number' ? meta.revision : hooks.lastRevision;
  hooks.lastSeq = meta.seq ?? null;
  hooks.lastMeta = meta;
  hooks.lastQuality = quality;
  showStats(meta, quality);
  updateProgress();
  updateLightMarker();
}

// The canvas backing store follows its CSS size (times devicePixelRatio), whatever size frames come in.
function sizeCanvas() {
  const r = canvas.getBoundingClientRect();
  const dpr = window.devicePixelRatio || 1;
  const k = Math.min(dpr, MAX_CANVAS / Math.max(1, r.width, r.height));
  const w = Math.max(1, Math.round(r.width * k));
  const h = Math.max(1, Math.round(r.height * k));
  if (canvas.width === w && canvas.height === h) return false;
  canvas.width = w;
  canvas.height = h;
  return true;
}

// Draws the frame shown, scaled to fit the canvas (letterboxed) with smooth filtering.
function paintFrame() {
  sizeCanvas();
  ctx.fillStyle = '#07090d';
  ctx.fillRect(0, 0, canvas.width, canvas.height);
  const f = state.frame;
  if (!f) return;
  const k = Math.min(canvas.width / f.width, canvas.height / f.height);
  const w = f.width * k;
  const h = f.height * k;
  ctx.imageSmoothingEnabled = true;
  ctx.imageSmoothingQuality = 'high';
  ctx.drawImage(f.bitmap, 0, 0, f.bitmap.width, f.bitmap.height, (canvas.width - w) / 2, (canvas.height - h) / 2, w, h);
  hooks.lastDraw = {
    frame: [f.width, f.height], bitmap: [f.bitmap.width, f.bitmap.height], canvas: [canvas.width, canvas.height],
    drawn: [Math.round(w), Math.round(h)], smoothing: ctx.imageSmoothingEnabled ? ctx.imageSmoothingQuality : 'off',
  };
}

function onServerError(msg) {
  // A refused edit answers its own request; an error without a seq (or of a frame) all up to it.
  const own = state.inflight.findIndex((req) => req.seq === msg.seq);
  const done = own >= 0 && msg.pointer ? state.inflight.splice(own, 1)
    : answered(msg.seq === undefined || msg.seq === null ? Infinity : msg.seq);
  if (!state.inflight.length) clearTimeout(state.watchdog);
  const inf = done[done.length - 1];
  const answers = Boolean(inf);
  // What the rejection takes back: the pointer, or all of a refused Add, Remove or Rename.
  const pointer = answers && inf.patch && msg.pointer ? S.rejectedScope(inf.patch, msg.pointer, sentDocument()) : msg.pointer;
  if (answers) {
    // Re-send the rest of a rejected patch once: edits coalesced with the bad value are not lost.
    if (inf.patch && !inf.retry && pointer && S.patchTouches(inf.patch, pointer)) {
      const rest = S.removeFromPatch(inf.patch, pointer);
      if (rest) {
        state.pending = S.composePatches(rest, state.pending);
        state.retryNext = true;
        if (!state.pendingQuality) state.pendingQuality = inf.quality;
      }
    }
    // A member chosen by the rejected edit (added, renamed) is gone again: choose what was chosen before it.
    for (const kind of Object.keys(S.COLLECTIONS)) {
      const names = S.memberNames(view(), kind);
      if (state.selected[kind] !== null && !names.includes(state.selected[kind])) state.selected[kind] = inf.selection[kind];
    }
  }
  // A refused Add, Remove or Rename is reported at its outliner, naming the member the daemon blames.
  const message = msg.error || 'The daemon rejected the edit.';
  const named = message.includes(msg.pointer) ? message : `${msg.pointer}: ${message}`;
  if (pointer !== msg.pointer) reportError(`The daemon refused the change: ${named}`, pointer, msg.seq);
  else reportError(message, msg.pointer, msg.seq);
  // Without a pointer it was not a validation error (e.g. the frame could not be rendered): the edit
  // may have been stored, so ask the daemon what the scene is now.
  if (msg.pointer === undefined || msg.pointer === null) resync();
  controls.update(panel());
  updateLightMarker();
  updateProgress();
  pump();
}

function reportError(message, daemonPointer, seq = null) {
  const pointer = daemonPointer && S.panelPointer(daemonPointer, view(), state.selected);
  hooks.lastError = { error: message, pointer: pointer ?? null, seq };
  hooks.errors++;
  const field = controls.fieldFor(pointer);
  if (field) {
    field.setError(message);
    if (field.el.getBoundingClientRect().height > 0) field.el.scrollIntoView({ block: 'nearest' });
  } else {
    showGlobalError(pointer ? `${message} (${pointer})` : message);
  }
  announce(`Error${pointer ? ` in ${pointer}` : ''}: ${message}`);
}

function showGlobalError(text) {
  const box = $('global-error');
  box.replaceChildren();
  const span = document.createElement('span');
  span.textContent = text;
  const close = document.createElement('button');
  close.type = 'button';
  close.className = 'dismiss';
  close.textContent = 'Dismiss';
  close.addEventListener('click', () => { box.hidden = true; });
  box.append(span, close);
  box.hidden = false;
}

function announce(text) {
  const el = $('announcer');
  el.textContent = '';
  requestAnimationFrame(() => { el.textContent = text; });
}

// ---- progress and stats ------------------------------------------------------------------------

function fps() {
  const t = state.frameTimes;
  if (t.length < 2) return null;
  const span = t[t.length - 1] - t[0];
  return span > 0 ? ((t.length - 1) * 1000) / span : null;
}

const duration = (ms) => (ms >= 1000 ? `${(ms / 1000).toFixed(ms < 10_000 ? 1 : 0)} s` : `${Math.round(ms)} ms`);

// The line over the image: what the client is waiting for, or what the last frame was. Runs on events
// and, while a frame is pending, a few times a second (elapsed time, dimming).
function updateProgress() {
  const el = $('hud-status');
  const inf = state.inflight[0];  // the longest waiting
  const now = performance.now();
  const f = fps();
  const streaming = f !== null && now - state.frameTimes[state.frameTimes.length - 1] < 1000;
  let text;
  if (!hooks.connected) {
    text = $('conn').textContent;
  } else if (state.replacing) {
    text = 'Loading the scene…';
  } else if (state.playing) {
    const at = state.playing.at;
    text = at ? `Playing ${at.frame + 1}/${at.frames} · ${at.time.toFixed(2)} s` : 'Starting the animation…';
  } else if (inf) {
    const waited = now - inf.sentAt;
    text = inf.quality === 'still' ? `Rendering still… ${duration(waited)}` : `Rendering preview… ${duration(waited)}`;
    // A stream of previews (dragging, wheel, keys): how many arrive per second.
    if (streaming && inf.quality === 'interactive') text = `${f.toFixed(f < 10 ? 1 : 0)} fps · ${text}`;
  } else if (hooks.lastQuality) {
    const took = hooks.latencyMs ? `, ${duration(hooks.latencyMs)}` : '';
    const meta = hooks.lastMeta || {};
    // The daemon keeps refining a still frame (more photons, then anti-aliasing) until its cap.
    text = hooks.lastQuality === 'still' ? `Still frame${took}` : `Preview frame${took}`;
    if (hooks.lastQuality === 'still' && meta.level >= 1 && meta.refine > meta.level) {
      text += ` · refining ${meta.level}/${meta.refine}`;
    } else if (hooks.lastQuality === 'still' && meta.level > 1) {
      text += ` · refined (level ${meta.level})`;
    }
  } else {
    text = 'Waiting for the first frame…';
  }
  el.textContent = text;
  el.dataset.state = !hooks.connected ? 'offline' : inf || state.replacing ? 'busy' : 'idle';
  const dim = Boolean((inf && !state.drag && now - inf.sentAt > DIM_AFTER_MS) || state.replacing || state.newScene);
  const dimmed = dim && Boolean(state.frame);
  if (dimmed && !stage.classList.contains('pending')) hooks.dims++;
  stage.classList.toggle('pending', dimmed);
  if ((inf || state.replacing) && !state.ticker) {
    state.ticker = setInterval(updateProgress, 200);
  } else if (!inf && !state.replacing && state.ticker) {
    clearInterval(state.ticker);
    state.ticker = null;
  }
}

const passClass = (name) => `pass pass-${String(name).replace(/[^a-z_]/g, '')}`;

// The strip under the image: the last frame, and the time each pass took (the last frame that ran any).
function showStats(meta, quality) {
  const size = meta.width && meta.height ? `${meta.width}×${meta.height}` : '';
  const what = quality === 'interactive' ? 'Preview' : 'Still';
  const parts = [`${what} ${size}`.trim(), `revision ${meta.revision ?? '—'}`];
  if (quality === 'still' && meta.level > 1) {
    const photons = typeof meta.photons === 'number' ? `${(meta.photons / 1e6).toFixed(2)} M photons` : '';
    parts.push(`level ${meta.level}: ${photons}, ${meta.samples_per_pixel} sample${meta.samples_per_pixel > 1 ? 's' : ''}/pixel`);
  }
  if (meta.cached) parts.push('already rendered: timings of its render');
  const timings = meta.timings && typeof meta.timings === 'object' ? meta.timings : {};
  if (meta.cached && Object.keys(timings).length === 0) {
    $('frame-summary').textContent = `${parts.join(' · ')}`;
    return;
  }
  let names = [];
  if (Array.isArray(meta.passes)) names = meta.passes.map((p) => (typeof p === 'string' ? p : p?.name)).filter(Boolean);
  for (const k of Object.keys(timings)) if (!names.includes(k)) names.push(k);
  const ms = (name) => (typeof timings[name] === 'number' ? timings[name] : null);
  const total = names.reduce((sum, n) => sum + (ms(n) || 0), 0);
  if (names.length) parts.push(`passes ${duration(total)}`);
  $('frame-summary').textContent = parts.join(' · ');
  const segments = [];
  const items = names.map((name) => {
    const v = ms(name);
    const share = total > 0 && v ? (100 * v) / total : 0;
    const seg = document.createElement('span');
    seg.className = passClass(name);
    seg.style.width = `${share}%`;
    seg.title = `${name}: ${v === null ? '—' : duration(v)}`;
    segments.push(seg);
    const li = document.createElement('li');
    li.className = passClass(name);
    li.dataset.pass = name;
    li.textContent = `${name} ${v === null ? '—' : duration(v)}`;
    return li;
  });
  $('passbar').replaceChildren(...segments);
  $('timings').replaceChildren(...items);
}

// ---- HTTP ----------------------------------------------------------------------------------------

class HttpError extends Error {
  constructor(status, body) {
    super(body?.error || `HTTP ${status}`);
    this.status = status;
    this.pointer = body?.pointer ?? null;
  }
}

async function api(method, path, body, contentType = 'application/json') {
  const init = { method, headers: {}, cache: 'no-store' };
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

function deviceText(health) {
  const d = health?.device;
  if (typeof d === 'string') return { name: d, detail: '' };
  if (!d) return { name: health?.device_error ? `no device: ${health.device_error}` : 'no device', detail: '' };
  const name = d.name || 'unknown device';
  const driver = [d.driver_name ?? d.driver, d.driver_info].filter(Boolean).join(' ');
  const detail = [d.type, driver].filter(Boolean).join(', ');
  return { name, detail };
}

async function fetchHealth() {
  const health = await api('GET', '/api/health');
  const { name, detail } = deviceText(health);
  const type = health?.device?.type;
  $('device-name').textContent = type ? `${name} · ${type}` : name;
  $('device-name').parentElement.title = detail ? `Render device: ${name} (${detail})` : `Render device: ${name}`;
  hooks.device = name;
  // Behind a proxy the daemon says so: upgrades then go through the page's own port.
  const pagePort = Number(location.port || (location.protocol === 'https:' ? 443 : 80));
  state.wsPort = health?.ws_on_http_port ? pagePort : Number(health?.ws_port) || pagePort + 1;
  const limits = health?.limits || {};
  controls.setMax('/volume/resolution', Number(limits.max_resolution));
  controls.setMax('/object/resolution', Number(limits.max_resolution));
  controls.setMax('/photons/count', Number(limits.max_photons));
  return health;
}

function setSceneId(id) {
  state.sceneId = id;
  hooks.sceneId = id;
  $('scene-id').textContent = id;
  const url = new URL(location.href);
  if (url.searchParams.get('scene') !== id) {
    url.searchParams.set('scene', id);
    history.replaceState(null, '', url);
  }
}

// Loads the scene named in the URL (or our current one, or else the daemon's `default`, framed to show
// the object and its caustic); creates one if there is none, restoring our last view of it when the
// daemon lost it.
async function loadScene() {
  const named = state.sceneId || params.get('scene');
  const id = named || 'default';
  try {
    const got = await api('GET', `/api/scenes/${encodeURIComponent(id)}`);
    adoptScene(got.id || id, got);
    return;
  } catch (e) {
    if (!(e instanceof HttpError) || e.status !== 404) throw e;
    if (named) showGlobalError(`Scene “${id}” does not exist on this daemon; started a new one.`);
  }
  let created;
  try {
    created = await api('POST', '/api/scenes', state.confirmed ? view() : {});
  } catch (e) {
    if (!(e instanceof HttpError) || !state.confirmed) throw e;
    created = await api('POST', '/api/scenes', {});
  }
  state.pending = null;
  adoptScene(created.id, created);
}

function adoptScene(id, got) {
  setSceneId(id);
  state.confirmed = got.scene;
  state.confirmedRevision = typeof got.revision === 'number' ? got.revision : null;
  controls.update(panel(), { force: true });
  updateLightMarker();
}

function resync() {
  later('resync', async () => {
    try {
      const got = await api('GET', `/api/scenes/${encodeURIComponent(state.sceneId)}`);
      if (state.inflight.length) return;  // our edit is under way; its answer will tell us the revision
      state.confirmed = got.scene;
      state.confirmedRevision = got.revision;
      controls.update(panel());
      updateLightMarker();
      if (state.lastFrame?.revision !== got.revision) requestFrame('still');
    } catch { /* the next frame or reconnect tries again */ }
  }, 150);
}

async function refreshMeshes() {
  try {
    const list = await api('GET', '/api/meshes');
    const items = Array.isArray(list) ? list : (list?.meshes || []);
    const names = items.map((m) => (typeof m === 'string' ? m : m?.name)).filter(Boolean).sort();
    for (const m of items) if (m?.name && m.bounds) state.meshBounds[m.name] = m.bounds;
    controls.mesh.setMeshes(names);
    controls.mesh.update(panel());
  } catch { /* the built-in meshes still work */ }
}

async function refreshEnvironments() {
  try {
    const list = await api('GET', '/api/environments');
    controls.environment.setImages((list?.environments || []).map((e) => e?.name).filter(Boolean));
    controls.environment.update(view());
  } catch { /* the sky and a uniform colour still work */ }
}

// Uploads an .hdr or .exr file as an environment named after it, and lights the scene with it.
async function uploadEnvironment(file, field) {
  const name = meshNameFor(file.name);
  field.clearError();
  field.setStatus(`Uploading ${file.name}…`);
  try {
    const info = await api('PUT', `/api/environments/${encodeURIComponent(name)}`, await file.arrayBuffer(),
      'application/octet-stream');
    await refreshEnvironments();
    field.setStatus(`Uploaded “${name}” (${info?.width} x ${info?.height}).`);
    edit({ environment: { type: 'image', image: name } }, true);
    controls.environment.update(view());
  } catch (e) {
    field.setStatus('');
    const message = `${file.name}: ${e.message}`;
    field.setError(message);
    hooks.lastError = { error: message, pointer: '/environment/image', seq: null };
    hooks.errors++;
    announce(`Upload failed: ${message}`);
  }
}

function meshNameFor(fileName) {
  const base = fileName.replace(/\.[^.]*$/, '').toLowerCase().replace(/[^a-z0-9_-]+/g, '-').replace(/^-+|-+$/g, '');
  return (base || 'mesh').slice(0, 48);
}

// Bounds of a mesh reference in its own units, when known.
function boundsOf(mesh) {
  if (typeof mesh !== 'string') return null;
  return mesh.startsWith('upload:') ? state.meshBounds[mesh.slice(7)] || null : BUILTIN_BOUNDS[mesh] || null;
}

// The edit that picks `mesh`: unless the user keeps its own units, it is fitted to the default object
// size with its centre where the object's origin is (object.position [0, 0, 0]).
function meshPatch(mesh) {
  const bounds = boundsOf(mesh);
  if (controls.mesh.keepUnits.checked || !bounds) return { object: { mesh } };
  const { scale, position } = S.fitObject(bounds, OBJECT_SIZE, panel().object?.rotation_deg);
  return { object: { mesh, scale, position } };
}

async function uploadMesh(file, field) {
  const name = meshNameFor(file.name);
  field.clearError();
  field.setStatus(`Uploading ${file.name}…`);
  try {
    const text = await file.text();
    const info = await api('PUT', `/api/meshes/${encodeURIComponent(name)}`, text, 'model/obj');
    const facts = [];
    if (typeof info?.triangles === 'number') facts.push(`${info.triangles} triangles`);
    if (typeof info?.vertices === 'number') facts.push(`${info.vertices} vertices`);
    if (info?.watertight === false) facts.push(`not watertight: ${info.boundary_edges ?? 'some'} open edges`);
    else if (info?.watertight === true) facts.push('watertight');
    if (info?.bounds) {
      state.meshBounds[name] = info.bounds;
      const size = Number(Math.max(...[0, 1, 2].map((i) => info.bounds.max[i] - info.bounds.min[i])).toPrecision(3));
      facts.push(`${size} unit${size === 1 ? '' : 's'} across`);
    }
    hooks.meshUploads++;
    hooks.lastUpload = { name, info };
    await refreshMeshes();
    const patch = meshPatch(`upload:${name}`);
    const fitted = patch.object.scale !== undefined;
    field.setStatus(`Uploaded “${name}”${facts.length ? ` (${facts.join(', ')})` : ''}` +
      (fitted ? `; scaled by ${patch.object.scale} to fit ${OBJECT_SIZE} m and centred.` : '; in its own units.'),
    patch.object.mesh);
    edit(patch, true);
    controls.mesh.update(panel());
  } catch (e) {
    field.setStatus('');
    const message = `${file.name}: ${e.message}`;
    field.setError(message);
    field.el.scrollIntoView({ block: 'nearest' });
    hooks.lastError = { error: message, pointer: '/object/mesh', seq: null };
    hooks.errors++;
    announce(`Upload failed: ${message}`);
  }
}

// ---- whole scenes: examples, import, export, the frame as PNG ------------------------------------

async function refreshExamples() {
  try {
    const list = await api('GET', '/api/examples');
    controls.example.setExamples(Array.isArray(list?.examples) ? list.examples : []);
    checkExample();
  } catch { /* an older daemon: no examples */ }
}

const untilIdle = async () => {
  const deadline = performance.now() + REQUEST_TIMEOUT_MS;
  while (state.inflight.length && performance.now() < deadline) await new Promise((r) => setTimeout(r, 30));
};

// Makes the scene the document `getDoc()` gives (a whole document; members it leaves out take their
// defaults), keeping the image size the canvas asks for. Goes over HTTP (PATCH), which answers the full
// document; the WebSocket is held meanwhile, and edits not yet sent are dropped (the new scene replaces
// them). Throws what `getDoc` throws, or HttpError.
async function replaceScene(getDoc) {
  state.replacing = true;
  updateProgress();
  try {
    const doc = await getDoc();
    await untilIdle();
    const wanted = S.applyMergePatch(doc, { image: desiredImageSize() });
    const patch = S.replacementPatch(state.confirmed, wanted) || {};
    const got = await api('PATCH', `/api/scenes/${encodeURIComponent(state.sceneId)}`, patch,
      'application/merge-patch+json');
    state.pending = null;
    state.newScene = true;
    state.confirmed = got.scene;
    state.confirmedRevision = got.revision;
    controls.clearErrors();
    controls.update(panel(), { force: true });
    updateLightMarker();
    return got;
  } finally {
    state.replacing = false;
    requestFrame('still');
    updateProgress();
  }
}

// A scene-level failure (a file that is not JSON, a document the daemon refuses) is shown at `field`.
function sceneError(field, what, e) {
  const where = e?.pointer ? ` (${e.pointer})` : '';
  const message = `${what}: ${e?.message || e}${where}`;
  field.setError(message);
  hooks.lastError = { error: message, pointer: e?.pointer ?? null, seq: null };
  hooks.errors++;
  announce(message);
}

async function loadExample(name, field) {
  field.clearError();
  try {
    const got = await replaceScene(() => api('GET', `/api/examples/${encodeURIComponent(name)}`));
    state.example = { name, doc: withoutImageSize(got.scene) };
    checkExample();
    announce(`Loaded the example ${name}`);
  } catch (e) {
    sceneError(field, `Example “${name}”`, e);
  }
}

async function importScene(file, field) {
  field.clearError();
  field.status.textContent = `Reading ${file.name}…`;
  try {
    await replaceScene(async () => {
      let doc;
      try { doc = JSON.parse(await file.text()); } catch (e) { throw new Error(`not JSON (${e.message})`); }
      if (!S.isObject(doc)) throw new Error('not a scene document (a JSON object)');
      return doc;
    });
    field.status.textContent = `Imported ${file.name}.`;
    hooks.imports = (hooks.imports || 0) + 1;
    checkExample();
  } catch (e) {
    field.status.textContent = '';
    sceneError(field, file.name, e);
  }
}

// Plays keyframes into this view over the WebSocket: the daemon renders the animation's frames in real
// time without changing the scene. Any edit (or Stop) ends it; the live scene's frame then comes back.
async function playKeyframes(file, field) {
  field.clearError();
  let keyframes;
  try { keyframes = JSON.parse(await file.text()); } catch (e) {
    return sceneError(field, file.name, new Error(`not JSON (${e.message})`));
  }
  await untilIdle();
  const ws = state.ws;
  if (!ws || ws.readyState !== WebSocket.OPEN) return sceneError(field, file.name, new Error('not connected'));
  const seq = ++state.seq;
  ws.send(JSON.stringify({ seq, type: 'play', fps: 24, keyframes, quality: 'interactive' }));
  state.playing = { seq, name: file.name, field, at: null };
  field.status.textContent = `Playing ${file.name}…`;
  field.stopButton.hidden = false;
  updateProgress();
}

function stopPlay() {
  if (!state.playing || state.ws?.readyState !== WebSocket.OPEN) return;
  state.ws.send(JSON.stringify({ seq: ++state.seq, type: 'stop' }));
}

function endPlay(note) {
  const play = state.playing;
  if (!play) return;
  state.playing = null;
  play.field.stopButton.hidden = true;
  play.field.status.textContent = note;
  requestFrame('still');  // back to the scene as it is
  updateProgress();
}

function playFailed(msg) {
  const play = state.playing;
  endPlay('');
  sceneError(play.field, play.name, { message: msg.error, pointer: msg.pointer });
}

function download(blob, fileName) {
  const url = URL.createObjectURL(blob);
  const a = document.createElement('a');
  a.href = url;
  a.download = fileName;
  document.body.append(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(url), 1000);
  hooks.downloads++;
}

function exportScene(field) {
  const doc = view();
  download(new Blob([JSON.stringify(doc, null, 2) + '\n'], { type: 'application/json' }), `refract-${state.sceneId}.json`);
  field.status.textContent = `Exported revision ${state.confirmedRevision} as refract-${state.sceneId}.json.`;
}

function savePng() {
  if (!state.lastPng) return;
  const blob = state.lastPng.type ? state.lastPng : new Blob([state.lastPng], { type: 'image/png' });
  download(blob, `refract-${state.sceneId}-r${hooks.lastRevision ?? 0}.png`);
}

// ---- connection ----// ---- connection ----------------------------------------------------------------------------------

function setConn(kind, text) {
  const el = $('conn');
  el.dataset.state = kind;
  el.textContent = text;
  hooks.connected = kind === 'live';
  stage.classList.toggle('offline', kind !== 'live');
  updateProgress();
}

function stageMessage(text) {
  const el = $('stage-msg');
  el.textContent = text || '';
  el.hidden = !text;
}

function scheduleReconnect() {
  clearTimeout(state.reconnectTimer);
  const delay = Math.min(10_000, 400 * 2 ** state.attempt) * (0.8 + 0.4 * Math.random());
  state.attempt = Math.min(state.attempt + 1, 10);
  const seconds = Math.max(1, Math.round(delay / 1000));
  setConn('reconnecting', `Reconnecting in ${seconds} s…`);
  stageMessage(hooks.connects === 0 ? 'Waiting for refractd…' : 'Connection to refractd lost; reconnecting…');
  state.reconnectTimer = setTimeout(connect, delay);
}

async function connect() {
  clearTimeout(state.reconnectTimer);
  setConn('connecting', 'Connecting…');
  try {
    // Neither needs the other's answer: both round trips at once, the first frame waits for the later.
    await Promise.all([fetchHealth(), loadScene()]);
  } catch (e) {
    console.warn('refractd not reachable', e);
    if (e instanceof HttpError && e.status !== 404 && e.status < 500 && hooks.connects === 0) {
      stageMessage(`Could not load the scene: ${e.message}`);
    }
    scheduleReconnect();
    return;
  }
  refreshMeshes();
  refreshEnvironments();
  refreshExamples();
  const proto = location.protocol === 'https:' ? 'wss:' : 'ws:';
  const url = `${proto}//${location.hostname}:${state.wsPort}/api/scenes/${encodeURIComponent(state.sceneId)}/ws` +
    (TOKEN ? `?token=${encodeURIComponent(TOKEN)}` : '');
  let ws;
  try {
    ws = new WebSocket(url);
  } catch (e) {
    scheduleReconnect();
    return;
  }
  ws.binaryType = 'blob';
  state.ws = ws;
  ws.addEventListener('open', () => {
    if (state.ws !== ws) return;
    state.attempt = 0;
    hooks.connects++;
    if (hooks.connects > 1) hooks.reconnects++;
    setConn('live', 'Live');
    stageMessage('');
    state.frameMeta = null;
    checkImageSize(true);
    // A quick preview first (the daemon sizes it to its frame budget), then the still: on two CPU cores
    // the still of a fresh scene takes seconds. A still asked for before the socket opened (the first
    // resize settling) comes second too, or it would be the first frame.
    state.pendingQuality = null;
    requestFrame('interactive');
    requestFrame('still');
  });
  ws.addEventListener('message', (ev) => {
    if (state.ws !== ws) return;
    if (typeof ev.data === 'string') onText(ev.data);
    else onBinary(ev.data);
  });
  ws.addEventListener('close', () => {
    if (state.ws !== ws) return;
    state.ws = null;
    clearTimeout(state.watchdog);
    // Whatever was in flight goes again after reconnecting (merge patches are idempotent).
    const lost = state.inflight.splice(0);
    if (lost.length) {
      const patch = lost.reduce((sum, req) => S.composePatches(sum, req.patch), null);
      state.pending = S.composePatches(patch, state.pending);
      state.pendingSelection = lost[0].selection;
      if (!state.pendingQuality) state.pendingQuality = lost[lost.length - 1].quality;
    }
    scheduleReconnect();
  });
}

// ---- image size follows the canvas ---------------------------------------------------------------

function desiredImageSize() {
  const rect = stage.getBoundingClientRect();
  const dpr = window.devicePixelRatio || 1;
  let w = Math.max(1, rect.width * dpr);
  let h = Math.max(1, rect.height * dpr);
  const k = Math.min(1, MAX_SIDE / Math.max(w, h));
  w = Math.max(MIN_SIDE, Math.round((w * k) / 2) * 2);
  h = Math.max(MIN_SIDE, Math.round((h * k) / 2) * 2);
  return { width: w, height: h };
}

function checkImageSize(silent = false) {
  if (!state.confirmed) return;
  const want = desiredImageSize();
  const have = view().image || {};
  if (Math.abs((have.width || 0) - want.width) <= 2 && Math.abs((have.height || 0) - want.height) <= 2) return;
  if (silent) state.pending = S.composePatches(state.pending, { image: want });
  else edit({ image: want }, true);
}

new ResizeObserver(() => {
  if (sizeCanvas()) paintFrame();
  updateLightMarker();
  later('resize', () => checkImageSize(), 250);
}).observe(stage);

// ---- camera and light interaction ----------------------------------------------------------------

function cameraOf(doc) {
  const c = doc.camera || {};
  return {
    position: c.position || [0, 0.5, 5], target: c.target || [0, -0.35, 0], up: c.up || [0, 1, 0], fov_deg: c.fov_deg || 35,
  };
}

function orbitCamera(dAz, dEl, final) {
  const cam = cameraOf(view());
  const position = S.roundVec(S.orbit(cam.position, cam.target, dAz, dEl, 4));
  edit({ camera: { position } }, final);
}

function zoomCamera(factor, final) {
  const cam = cameraOf(view());
  edit({ camera: { position: S.roundVec(S.dolly(cam.position, cam.target, factor)) } }, final);
}

// Aims the camera at the object and sets its distance so the whole object fits the view.
function frameObject() {
  const doc = panel();
  const object = doc.object || {};
  const bounds = boundsOf(object.mesh) || BUILTIN_BOUNDS.sphere;
  const { center, radius } = S.placedBounds(bounds, object);
  const image = doc.image || {};
  const cam = cameraOf(doc);
  const target = S.roundVec(center, 5);
  const position = S.roundVec(S.framePosition(cam, center, radius, (image.width || 1) / (image.height || 1)), 5);
  edit({ camera: { target, position } }, true);
}

function moveLight(dAz, dEl, final) {
  const doc = panel();
  const target = cameraOf(doc).target;
  const light = doc.light || {};
  const position = S.roundVec(S.orbit(light.position || [2, 3, 1], target, dAz, dEl, 3));
  const direction = S.roundVec(S.normalize(S.sub(target, position)));
  edit({ light: { position, direction } }, final);
}

// Moves the chosen object by a pointer's motion (CSS pixels) across the view, at the object's depth.
function moveObject(dxPixels, dyPixels) {
  const doc = panel();
  const rect = imageRect();
  if (!(rect.width > 0 && rect.height > 0)) return;
  const position = doc.object?.position || [0, 0, 0];
  const moved = S.panInView(cameraOf(doc), rect.width / rect.height, position,
    (2 * dxPixels) / rect.width, (-2 * dyPixels) / rect.height);
  edit({ object: { position: S.roundVec(moved, 4) } }, false);
}

function setLightMode(on) {
  state.lightMode = on;
  const btn = $('mode-light');
  btn.setAttribute('aria-pressed', String(on));
  stage.classList.toggle('light-mode', on);
  canvas.setAttribute('aria-label', on
    ? 'Rendered scene, light mode: drag or arrow keys move the light'
    : 'Rendered scene: drag or arrow keys orbit the camera');
  updateLightMarker();
}

// Where the image sits inside the canvas element (CSS pixels; letterboxed as paintFrame draws it).
function imageRect() {
  const r = canvas.getBoundingClientRect();
  const image = view().image || {};
  const aspect = state.frame ? state.frame.width / state.frame.height : (image.width || 1) / (image.height || 1);
  let w = r.width;
  let h = r.height;
  if (w / h > aspect) w = h * aspect; else h = w / aspect;
  return { left: (r.width - w) / 2, top: (r.height - h) / 2, width: w, height: h };
}

function updateLightMarker() {
  const marker = $('light-marker');
  const doc = panel();
  if (!doc.camera || !doc.light?.position) { marker.hidden = true; return; }
  const image = doc.image || {};
  const aspect = (image.width || canvas.width) / (image.height || canvas.height);
  const p = S.project(cameraOf(doc), aspect, doc.light.position);
  const rect = imageRect();
  if (!p) { marker.hidden = true; return; }
  // Off the image: pin the marker to the image border, in the light's direction.
  const out = Math.max(Math.abs(p.x), Math.abs(p.y));
  const edge = out > 1;
  if (edge) { p.x = (p.x / out) * 0.96; p.y = (p.y / out) * 0.96; }
  marker.classList.toggle('edge', edge);
  marker.hidden = false;
  marker.style.left = `${rect.left + ((p.x + 1) / 2) * rect.width}px`;
  marker.style.top = `${rect.top + ((1 - p.y) / 2) * rect.height}px`;
}

function dragAngles(dx, dy) {
  const h = Math.max(100, canvas.getBoundingClientRect().height);
  return [dx * Math.PI / h, dy * Math.PI / h];
}

canvas.addEventListener('pointerdown', (e) => {
  if (e.pointerType === 'mouse' && e.button !== 0) return;
  canvas.focus({ preventScroll: true });
  canvas.setPointerCapture(e.pointerId);
  state.pointers.set(e.pointerId, { x: e.clientX, y: e.clientY });
  if (state.pointers.size === 1) {
    // Alt+drag moves the chosen object across the view, Shift+drag (or light mode) the chosen light.
    const object = e.altKey;
    state.drag = { x: e.clientX, y: e.clientY, object, light: !object && (e.shiftKey || state.lightMode), moved: false };
    stage.classList.toggle('dragging-light', state.drag.light);
  } else if (state.pointers.size === 2) {
    const [a, b] = [...state.pointers.values()];
    state.drag = { pinch: Math.hypot(a.x - b.x, a.y - b.y), moved: false };
  }
  e.preventDefault();
});

canvas.addEventListener('pointermove', (e) => {
  if (!state.pointers.has(e.pointerId) || !state.drag) return;
  state.pointers.set(e.pointerId, { x: e.clientX, y: e.clientY });
  const drag = state.drag;
  if (drag.pinch !== undefined) {
    if (state.pointers.size < 2) return;
    const [a, b] = [...state.pointers.values()];
    const d = Math.hypot(a.x - b.x, a.y - b.y);
    if (d > 0 && drag.pinch > 0) zoomCamera(drag.pinch / d, false);
    drag.pinch = d;
    drag.moved = true;
    return;
  }
  const dx = e.clientX - drag.x;
  const dy = e.clientY - drag.y;
  if (dx === 0 && dy === 0) return;
  drag.x = e.clientX;
  drag.y = e.clientY;
  drag.moved = true;
  if (drag.object) return void moveObject(dx, dy);
  const [ax, ay] = dragAngles(dx, dy);
  if (drag.light) moveLight(ax, -ay, false);
  else orbitCamera(-ax, ay, false);
});

function endPointer(e) {
  if (!state.pointers.delete(e.pointerId)) return;
  if (state.pointers.size > 0) return;
  const moved = state.drag?.moved;
  state.drag = null;
  stage.classList.remove('dragging-light');
  if (moved) edit(null, true);  // released: ask for the full-quality still
}
canvas.addEventListener('pointerup', endPointer);
canvas.addEventListener('pointercancel', endPointer);

canvas.addEventListener('wheel', (e) => {
  e.preventDefault();
  const delta = e.deltaMode === 1 ? e.deltaY * 16 : e.deltaY;
  zoomCamera(Math.exp(Math.max(-200, Math.min(200, delta)) * 0.0015), false);
  later('wheel', () => edit(null, true), 300);
}, { passive: false });

canvas.addEventListener('keydown', (e) => {
  const arrows = { ArrowLeft: [-1, 0], ArrowRight: [1, 0], ArrowUp: [0, -1], ArrowDown: [0, 1] };
  let handled = true;
  if (arrows[e.key]) {
    const [x, y] = arrows[e.key];
    if (e.shiftKey || state.lightMode) moveLight(x * ORBIT_STEP, -y * ORBIT_STEP, false);
    else orbitCamera(-x * ORBIT_STEP, y * ORBIT_STEP, false);
  } else if (e.key === '+' || e.key === '=' || e.key === 'PageUp') {
    zoomCamera(1 / ZOOM_STEP, false);
  } else if (e.key === '-' || e.key === '_' || e.key === 'PageDown') {
    zoomCamera(ZOOM_STEP, false);
  } else if ((e.key === 'f' || e.key === 'F') && !e.ctrlKey && !e.metaKey && !e.altKey) {
    frameObject();
    return void e.preventDefault();
  } else if ((e.key === 'l' || e.key === 'L') && !e.ctrlKey && !e.metaKey && !e.altKey) {
    setLightMode(!state.lightMode);
    announce(state.lightMode ? 'Light mode on' : 'Light mode off');
    return void e.preventDefault();
  } else {
    handled = false;
  }
  if (!handled) return;
  e.preventDefault();
  later('keys', () => edit(null, true), 350);  // settled: refine
});

$('mode-light').addEventListener('click', () => setLightMode(!state.lightMode));
$('zoom-in').addEventListener('click', () => zoomCamera(1 / ZOOM_STEP, true));
$('zoom-out').addEventListener('click', () => zoomCamera(ZOOM_STEP, true));
$('still-btn').addEventListener('click', () => requestFrame('still'));
$('frame-object').addEventListener('click', frameObject);
$('save-png').addEventListener('click', savePng);

window.addEventListener('keydown', (e) => {
  if (e.key === 'Shift') stage.classList.add('shift');
});
window.addEventListener('keyup', (e) => {
  if (e.key === 'Shift') stage.classList.remove('shift');
});

// ---- start ---------------------------------------------------------------------------------------

setLightMode(false);
paintFrame();
stageMessage('Connecting to refractd…');
connect();
