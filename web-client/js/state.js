// What the client's modules share: the scene as the daemon has it and as the user sees it, the requests
// on their way, the frame shown; the URL's parameters, named timers and the test hooks. State that one
// module alone uses stays in that module.

import * as S from './scene.js';

export const params = new URLSearchParams(location.search);

export const state = {
  sceneId: null,
  confirmed: null,        // the scene document as the daemon last told us (plus our accepted patches)
  confirmedRevision: null,
  inflight: [],           // requests sent and not yet answered, oldest first: { seq, patch, quality, sentAt, retry }
  pending: null,          // coalesced merge patch not yet sent
  pendingQuality: null,   // 'interactive' | 'still' | null: a frame is wanted
  ws: null,
  replacing: false,       // the scene is being replaced over HTTP (example, import): hold the WebSocket
  newScene: false,        // the scene was replaced and its first frame is not drawn yet
  previewFirst: false,    // a new scene's preview is in flight: the still is asked for once it is answered
  drawToken: 0,           // frames handed to the viewport to decode, and the newest of them drawn
  drawnToken: 0,
  drag: null,
  frame: null,            // { bitmap, width, height }: the frame shown, kept to redraw on resize
  lastPng: null,          // the PNG of the frame shown, for "Save PNG"
  playing: null,          // { seq, name, at, ended, failed }: keyframes playing into this view (at: the last frame's place)
  selected: { light: null, object: null, medium_volume: null },  // the light and object the panel edits (null: the first by name)
  // This viewer's own view (the WebSocket session's `view` setting; never stored): its camera, or, when
  // following, the scene's camera, which its orbit then edits for every follower (presenter mode).
  ownCamera: null,
  follow: false,
  viewSent: null,         // the view setting last sent on this socket, as JSON (null: none yet)
  viewers: 1,             // sessions viewing the scene on the daemon, this one included
  otherEdit: null,        // { revision, at }: the last edit another viewer made, for the progress line
  pushed: false,          // the frame shown was pushed for someone else's edit, not asked for here
};

// Named one-shot timers (debounces); `settled` below waits for all of them.
const timers = new Map();
export function later(name, fn, ms) {
  clearTimeout(timers.get(name));
  timers.set(name, setTimeout(() => { timers.delete(name); fn(); }, ms));
}

// The document as the daemon will have it once the requests in flight are applied: what a new patch
// is pruned against.
export function sentDocument() {
  let doc = state.confirmed || {};
  for (const inf of state.inflight) if (inf.patch) doc = S.applyMergePatch(doc, inf.patch);
  return doc;
}

// The document as the user sees it: with the edits not sent yet.
export function view() {
  let doc = sentDocument();
  if (state.pending) doc = S.applyMergePatch(doc, state.pending);
  return doc;
}

// The document as this viewer sees it: its own camera in place of the scene's, unless it follows that.
export function seenDocument() {
  const doc = view();
  return state.follow || !state.ownCamera ? doc : { ...doc, camera: state.ownCamera };
}

// The document as the panel shows it: the selected light and object as `light` and `object`, and the
// camera this viewer looks through.
export function panel() {
  return S.panelDocument(seenDocument(), state.selected);
}

// Test and debugging hooks: plain data, read by the end-to-end test via page.evaluate (main.js puts them
// on window.refract).
export const hooks = {
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
  drawn: [],  // the last 16 frames drawn: { quality, revision }
  maxInFlight: 0,
  doc: () => view(),
  // This viewer's view as last sent to the daemon, and whether it follows the scene's camera.
  view: () => (state.viewSent ? JSON.parse(state.viewSent) : null),
  follow: () => state.follow,
  viewers: () => state.viewers,
  otherEdits: 0,       // notices of another viewer's edit received
  pushedFrames: 0,     // frames drawn that were pushed for someone else's edit
  lastQuality: null,
  example: null,       // name of the example the scene still is
  lastDraw: null,      // how the last frame was drawn: source and canvas sizes, smoothing
  lastInteractiveDraw: null,
  dims: 0,             // times the frame shown was dimmed for a pending one
  downloads: 0,
  playedFrames: 0,     // frames of played animations drawn
  playedSizes: [],     // [width, height] of each played frame drawn
  playing: () => state.playing?.name ?? null,
  inflight: () => state.inflight.map((inf) => inf.quality),  // the requests in flight, oldest first
  busy: () => Boolean(state.inflight.length || state.pendingQuality || state.replacing),
  // Connected, nothing in flight or queued or about to be, and the last frame is a decoded still.
  settled: () => hooks.connected && !state.inflight.length && !state.pendingQuality && !state.replacing &&
    timers.size === 0 && state.drawnToken === state.drawToken && hooks.lastQuality === 'still',
};
