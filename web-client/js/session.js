// The scene session: the document as the daemon has it, our edits on their way to it and its answers
// (frames and errors) on the WebSocket, the scene's loading and replacing, and keyframes played into the
// view.
//
// Flow control: at most one request is in flight on the WebSocket, or two when the first is an
// interactive one: the daemon renders the newest request after the frame it is on (latest wins), so a
// second edit sent while a preview renders keeps its render thread busy instead of idle for the
// frame's delivery, decode and our answer. A still request may follow two previews (see slotFree).
// Edits made meanwhile are coalesced into one pending merge patch, sent when a request slot frees (a
// frame, or an error, answers it).
// Dragging sends "interactive" requests; releasing asks for a "still" (full quality) frame.

import { checkExample, refreshCatalog } from './catalog.js';
import { HttpError, api, fetchHealth, patchCurrent } from './connection.js';
import { $ } from './dom.js';
import { clearComplaints, controls, reportError } from './panel.js';
import * as S from './scene.js';
import { hooks, later, panel, params, sentDocument, state, view } from './state.js';
import { noteOtherEdit, playedNote, showDevice, showGlobalError, showViewers, updateProgress } from './status.js';
import { desiredImageSize, drawFrame, updateLightMarker } from './viewport.js';

const REQUEST_TIMEOUT_MS = 180_000;  // a lost answer: give up on it and reconnect
const QUALITY_RANK = { interactive: 0, still: 1 };
const MAX_IN_FLIGHT = 2;  // requests on the WebSocket at once, the first an interactive one (see above)
// A played animation's frames: interactive ones (the daemon keeps up with more of them) given a budget
// that lets them grow to this viewer's own size; the drag's budget comes back with the next request.
const PLAY_BUDGET_MS = 1000;
const DRAG_BUDGET_MS = 100;

let sentSeq = 0;               // the last request's (or play's, stop's) sequence number
let forceFrame = false;        // request a frame even if nothing changed (connect, Refine)
let retryNext = false;         // the next send re-sends what was left of a rejected patch
let pendingSelection = null;   // `state.selected` as it was before the edits now pending
let watchdog = null;
let frameMeta = null;          // text header of the frame whose PNG comes next
let lastFrame = null;          // { revision, quality }
let viewUpdateQueued = false;
const TEMPORAL = params.get('temporal') === '1';
let restoreBudget = false;     // the last play set the session's budget_ms: the next request sets it back

// The panel and the light marker show the document as it is now; `force` also overwrites the values the
// daemon refused that the user has not fixed yet.
export function showDocument(force = false) {
  controls.update(panel(), { force });
  updateLightMarker();
}

// ---- edits on their way ----------------------------------------------------------------------------

// Queues an edit (or, with a null patch, just a frame) and sends it when the link is free. A camera
// edit moves this viewer's own camera (its view, never stored) unless it follows the scene's camera.
export function edit(patch, final) {
  if (S.isObject(patch) && patch.camera && !state.follow && state.ownCamera) {
    state.ownCamera = S.applyMergePatch(state.ownCamera, patch.camera);
    const { camera, ...rest } = patch;
    patch = Object.keys(rest).length ? rest : null;
    scheduleViewUpdate();
  }
  pendingSelection ??= { ...state.selected };
  if (patch) state.pending = S.composePatches(state.pending, S.memberPatch(patch, view(), state.selected));
  state.pendingQuality = final ? 'still' : 'interactive';
  if (patch) scheduleViewUpdate();
  pump();
}

// Controls and the light marker follow the edited document, at most once per animation frame.
function scheduleViewUpdate() {
  if (viewUpdateQueued) return;
  viewUpdateQueued = true;
  requestAnimationFrame(() => {
    viewUpdateQueued = false;
    showDocument();
    checkExample();
  });
}

export function requestFrame(quality = 'still') {
  forceFrame = true;
  if (!state.pendingQuality || QUALITY_RANK[quality] > QUALITY_RANK[state.pendingQuality]) state.pendingQuality = quality;
  pump();
}

// Whether another request may go now: fewer than MAX_IN_FLIGHT are in flight (see the top; a still
// frame in flight gives way at the daemon to the next request, which answers it too), or a still frame
// (a drag's release) follows two previews: at the daemon it takes the place of the preview queued there
// (latest wins), so the full-quality frame comes after the preview rendering, not after two.
function slotFree() {
  const n = state.inflight.length;
  if (n > 0 && state.previewFirst) return false;
  const previews = state.inflight.every((inf) => inf.quality === 'interactive');
  return n < MAX_IN_FLIGHT || (previews && n === MAX_IN_FLIGHT && state.pendingQuality === 'still');
}

// The view setting this viewer asks for: its canvas's image size, and its own camera or (null) the scene's.
function currentView() {
  return { ...desiredImageSize(), camera: state.follow ? null : state.ownCamera };
}

// Makes this viewer's camera the scene's (the document's camera: what new viewers, exports and
// `refract render` start from).
export function saveView() {
  if (state.follow || !state.ownCamera) return;
  state.pending = S.composePatches(state.pending, { camera: state.ownCamera });
  state.pendingQuality = 'still';
  showDocument();
  pump();
}

// Presenter mode on (`on`): this viewer looks through the scene's camera, and its orbit moves that camera
// for every viewer following it; off: it looks through a camera of its own, starting where the scene's is.
export function setFollow(on) {
  state.follow = on;
  state.ownCamera = on ? null : S.deepClone(S.cameraOf(view()));
  showDocument();
  requestFrame('still');
}

function pump() {
  const ws = state.ws;
  if (!ws || ws.readyState !== WebSocket.OPEN || !slotFree() || state.replacing || !state.pendingQuality ||
      !state.confirmed) return;
  const patch = state.pending ? S.prunePatch(sentDocument(), state.pending) : null;
  const quality = state.pendingQuality;
  const force = forceFrame;
  const selection = pendingSelection ?? { ...state.selected };
  state.pending = null;
  pendingSelection = null;
  state.pendingQuality = null;
  forceFrame = false;
  const retry = retryNext;
  retryNext = false;
  // Nothing changed and we already show (or the answer in flight will show) this quality or better.
  const last = lastFrame;
  const covered = state.inflight.length ? quality === 'interactive'
    : last && last.revision === state.confirmedRevision && QUALITY_RANK[last.quality] >= QUALITY_RANK[quality];
  const viewNow = JSON.stringify(currentView());
  const viewChanged = viewNow !== state.viewSent;
  if (!patch && !force && !viewChanged && covered) return;

  const seq = ++sentSeq;
  const message = { seq, quality };
  if (patch) message.patch = patch;
  if (patch) state.otherEdit = null;  // what the line says next is about our own edit
  if (viewChanged) message.view = JSON.parse(viewNow);
  state.viewSent = viewNow;
  if (restoreBudget) message.budget_ms = DRAG_BUDGET_MS;
  restoreBudget = false;
  // ?temporal=1: previews at the view's full size by temporal reuse (docs/interactive.md), asked with
  // every message so that a reconnected session asks too.
  if (TEMPORAL) message.temporal = true;
  ws.send(JSON.stringify(message));
  // errorsBefore: an error shown after this request was sent is newer than its edit and must outlive it.
  // selection: what the outliner had chosen before the edits sent; a rejected Add or Rename goes back to it.
  state.inflight.push({ seq, patch, quality, sentAt: performance.now(), retry, errorsBefore: hooks.errors, selection });
  hooks.requestsSent++;
  hooks.sent[quality]++;
  hooks.maxInFlight = Math.max(hooks.maxInFlight, state.inflight.length);
  clearTimeout(watchdog);
  watchdog = setTimeout(() => {
    // No answer: assume the connection is wedged; reconnecting re-sends the edit.
    if (state.inflight.some((inf) => inf.seq === seq) && state.ws === ws) ws.close(4000, 'request timed out');
  }, REQUEST_TIMEOUT_MS);
  updateProgress();
}

// Takes the requests an answer with `seq` covers out of those in flight and returns them, oldest first:
// a frame answers its own request and every older one (latest wins: the daemon rendered the newest).
function answered(seq) {
  if (seq === undefined) return state.inflight.splice(0, 1);  // an older daemon: one request at a time
  if (seq === null) return [];                                // pushed for someone else's edit
  const n = state.inflight.filter((inf) => inf.seq <= seq).length;
  const done = state.inflight.splice(0, n);
  if (!state.inflight.length) {
    clearTimeout(watchdog);
    state.previewFirst = false;
  }
  return done;
}

// The view's image size follows the canvas: a new size asks for a still frame at it (the scene's own
// image size, its saved view's, is not touched).
export function checkImageSize() {
  if (!state.confirmed || !state.viewSent) return;
  const want = desiredImageSize();
  const have = JSON.parse(state.viewSent);
  if (Math.abs(have.width - want.width) <= 2 && Math.abs(have.height - want.height) <= 2) return;
  requestFrame('still');
}

// ---- answers: frames and errors ----------------------------------------------------------------------

function onText(data) {
  let msg;
  try { msg = JSON.parse(data); } catch { return; }
  if (msg.type === 'frame') frameMeta = msg;
  else if (msg.type === 'viewers') showViewers(msg.count);
  else if (msg.type === 'edited') { noteOtherEdit(msg.revision); refreshDocument(); }
  else if (msg.type === 'error' && state.playing && msg.seq === state.playing.seq) playFailed(msg);
  else if (msg.type === 'error') onServerError(msg);
  else if (msg.type === 'stopped' && state.playing) endPlay(`Stopped: ${playedNote(state.playing, PLAY_FPS, false)}`);
}

function onBinary(blob) {
  const meta = frameMeta || {};
  frameMeta = null;
  // The requests this frame answers (its own and older ones); a frame with a null seq answers nobody
  // here: the daemon pushed it for another client's edit.
  const done = answered(meta.seq);
  const inf = done[done.length - 1];
  const quality = meta.quality || (inf ? inf.quality : 'still');
  // Pushed unasked for an edit made elsewhere (not a refinement of our own frame, which echoes our seq).
  state.pushed = meta.seq === null && !meta.play;
  if (state.pushed) hooks.pushedFrames++;
  let ours = 0;  // edits this frame holds: each may have made a revision
  for (const req of done) {
    if (!req.patch) continue;
    state.confirmed = S.applyMergePatch(state.confirmed, req.patch);
    ours++;
  }
  if (inf) {
    hooks.latencyMs = Math.round(performance.now() - inf.sentAt);
  } else if (state.pushed) {
    hooks.latencyMs = null;  // nobody here waited for it
  }
  if (inf?.patch && !inf.retry && hooks.errors === inf.errorsBefore) clearComplaints();
  // A frame of the scene before a replacement over HTTP (which does not wait for frames in flight)
  // answers its requests, but is not shown.
  const stale = typeof meta.revision === 'number' && meta.revision < (state.confirmedRevision ?? -1);
  if (stale && !ours && !meta.play) { pump(); return; }
  if (typeof meta.revision === 'number') {
    const expected = state.confirmedRevision;
    const consistent = meta.revision === expected ||
      (expected !== null && meta.revision > expected && meta.revision <= expected + ours);
    state.confirmedRevision = meta.revision;
    if (!consistent && expected !== null) resync();  // someone else edited the scene
  }
  if (meta.play && state.playing) {
    hooks.playedFrames++;
    hooks.playedSizes.push([meta.width, meta.height]);
    state.playing.shown++;
    state.playing.at = meta.play;
    if (meta.play.last) endPlay(playedNote(state.playing, PLAY_FPS));
  }
  lastFrame = { revision: state.confirmedRevision, quality };
  state.lastPng = blob;
  $('save-png').disabled = false;
  const token = ++state.drawToken;
  drawFrame(blob, meta, token, quality).catch((e) => console.warn('frame decode failed', e));
  pump();
}

function onServerError(msg) {
  // A refused edit answers its own request; an error without a seq (or of a frame) all up to it.
  const own = state.inflight.findIndex((req) => req.seq === msg.seq);
  const done = own >= 0 && msg.pointer ? state.inflight.splice(own, 1)
    : answered(msg.seq === undefined || msg.seq === null ? Infinity : msg.seq);
  if (!state.inflight.length) {
    clearTimeout(watchdog);
    state.previewFirst = false;
  }
  const inf = done[done.length - 1];
  const answers = Boolean(inf);
  if (String(msg.pointer || '').startsWith('/view')) state.viewSent = null;  // the daemon kept the view it had
  // What the rejection takes back: the pointer, or all of a refused Add, Remove or Rename.
  const pointer = answers && inf.patch && msg.pointer ? S.rejectedScope(inf.patch, msg.pointer, sentDocument()) : msg.pointer;
  if (answers) {
    // Re-send the rest of a rejected patch once: edits coalesced with the bad value are not lost.
    if (inf.patch && !inf.retry && pointer && S.patchTouches(inf.patch, pointer)) {
      const rest = S.removeFromPatch(inf.patch, pointer);
      if (rest) {
        state.pending = S.composePatches(rest, state.pending);
        retryNext = true;
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
  else reportError(message, msg.pointer, msg.seq, msg.rule);
  // Without a pointer it was not a validation error (e.g. the frame could not be rendered): the edit
  // may have been stored, so ask the daemon what the scene is now.
  if (msg.pointer === undefined || msg.pointer === null) resync();
  showDocument();
  updateProgress();
  pump();
}

// ---- the scene: loading, re-reading, replacing ---------------------------------------------------

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
  // A new viewer starts from the scene's saved view.
  if (!state.follow) state.ownCamera = S.deepClone(S.cameraOf(got.scene));
  showDocument(true);
}

function resync() {
  later('resync', async () => {
    try {
      const got = await api('GET', `/api/scenes/${encodeURIComponent(state.sceneId)}`);
      if (state.inflight.length) return;  // our edit is under way; its answer will tell us the revision
      state.confirmed = got.scene;
      state.confirmedRevision = got.revision;
      showDocument();
      if (lastFrame?.revision !== got.revision) requestFrame('still');
    } catch { /* the next frame or reconnect tries again */ }
  }, 150);
}

// Another viewer made a revision: the controls show the scene as it is now. The daemon pushes a frame
// of it only when this view shows a change (not for the scene's camera under a camera of our own), so
// the frame shown stands for the new revision unless one comes.
function refreshDocument() {
  later('refresh', async () => {
    try {
      const got = await api('GET', `/api/scenes/${encodeURIComponent(state.sceneId)}`);
      if (state.inflight.length || state.pending || !(got.revision > state.confirmedRevision)) return;
      state.confirmed = got.scene;
      state.confirmedRevision = got.revision;
      if (lastFrame) lastFrame = { ...lastFrame, revision: got.revision };
      showDocument();
    } catch { /* the next frame or reconnect tells */ }
  }, 300);
}

// Until no request in flight matches `busy` (default: any).
const untilIdle = async (busy = () => true) => {
  const deadline = performance.now() + REQUEST_TIMEOUT_MS;
  while (state.inflight.some(busy) && performance.now() < deadline) await new Promise((r) => setTimeout(r, 30));
};

// Makes the scene the document `getDoc()` gives (a whole document; members it leaves out take their
// defaults); this viewer then looks through its camera. Goes over HTTP (PATCH), which answers the full
// document; the WebSocket is held meanwhile, and edits not yet sent are dropped (the new scene replaces
// them). Throws what `getDoc` throws, or HttpError.
export async function replaceScene(getDoc) {
  state.replacing = true;
  updateProgress();
  try {
    const doc = await getDoc();
    // Our edits on their way land first; a frame in flight does not hold the load: it gives way at the
    // daemon to the new scene's revision.
    await untilIdle((inf) => inf.patch);
    // Against the scene as the daemon has it now: our copy may lag behind another viewer's edit.
    const got = await patchCurrent(`/api/scenes/${encodeURIComponent(state.sceneId)}`,
      (current) => S.replacementPatch(current.scene, doc) || {});
    state.pending = null;
    state.newScene = true;
    state.confirmed = got.scene;
    state.confirmedRevision = got.revision;
    if (!state.follow) state.ownCamera = S.deepClone(S.cameraOf(got.scene));
    controls.clearErrors();
    showDocument(true);
    return got;
  } finally {
    state.replacing = false;
    previewThenStill();
    updateProgress();
  }
}

// A quick preview first (the daemon sizes it to its frame budget, and builds a new volume at half the
// voxels per axis), then the still: a new scene's still takes seconds on two CPU cores, and until it
// came the old scene stood there dimmed. The still is sent once the preview is answered: sent at once,
// it would take the preview's place in the daemon's queue whenever the daemon was busy.
export function previewThenStill() {
  state.pendingQuality = null;
  requestFrame('interactive');
  stillAfterPreview();
}

// The still of an edit just sent as a preview (edit(patch, false)), once that preview is answered.
export function stillAfterPreview() {
  state.previewFirst = state.inflight.length > 0;
  requestFrame('still');
}

// ---- keyframes played into the view --------------------------------------------------------------

// Plays `keyframes` (named `name`) over the WebSocket once nothing is in flight: the daemon renders the
// animation's frames in real time without changing the scene. Any edit (or stopPlay) ends it, calling
// `ended(note)`, or `failed(msg)` after it for the daemon's error; the live scene's frame then comes back.
// False when not connected.
export async function play(name, keyframes, { ended, failed }) {
  await untilIdle();
  const ws = state.ws;
  if (!ws || ws.readyState !== WebSocket.OPEN) return false;
  const seq = ++sentSeq;
  const message = { seq, type: 'play', fps: PLAY_FPS, keyframes, quality: 'interactive', budget_ms: PLAY_BUDGET_MS };
  const viewNow = JSON.stringify(currentView());
  if (viewNow !== state.viewSent) message.view = JSON.parse(viewNow);
  state.viewSent = viewNow;
  ws.send(JSON.stringify(message));
  restoreBudget = true;
  state.playing = { seq, name, at: null, shown: 0, ended, failed };
  return true;
}

const PLAY_FPS = 24;

export function stopPlay() {
  if (!state.playing || state.ws?.readyState !== WebSocket.OPEN) return;
  state.ws.send(JSON.stringify({ seq: ++sentSeq, type: 'stop' }));
}

function endPlay(note) {
  const playing = state.playing;
  if (!playing) return;
  state.playing = null;
  playing.ended(note);
  requestFrame('still');  // back to the scene as it is
  updateProgress();
}

function playFailed(msg) {
  const playing = state.playing;
  endPlay('');
  playing.failed(msg);
}

// ---- around each WebSocket (connection.js) ---------------------------------------------------------

export const link = {
  async prepare() {
    // Neither needs the other's answer: both round trips at once, the first frame waits for the later.
    await Promise.all([fetchHealth().then((health) => {
      showDevice(health);
      controls.setLimits(health?.limits || {});
    }), loadScene()]);
    refreshCatalog();
  },
  opened() {
    frameMeta = null;
    state.viewSent = null;  // a new session: its first message carries the view
    // A still asked for before the socket opened (the first resize settling) comes second too, or it
    // would be the first frame.
    previewThenStill();
  },
  text: onText,
  binary: onBinary,
  closed() {
    clearTimeout(watchdog);
    state.previewFirst = false;
    // Whatever was in flight goes again after reconnecting (merge patches are idempotent).
    const lost = state.inflight.splice(0);
    if (lost.length) {
      const patch = lost.reduce((sum, req) => S.composePatches(sum, req.patch), null);
      state.pending = S.composePatches(patch, state.pending);
      pendingSelection = lost[0].selection;
      if (!state.pendingQuality) state.pendingQuality = lost[lost.length - 1].quality;
    }
  },
};
