// The view: the canvas and the frames drawn on it, scaled to fit with smooth filtering (previews arrive
// smaller than the image), the light marker over it, and the image size it asks the daemon for.

import { $ } from './dom.js';
import * as S from './scene.js';
import { hooks, panel, params, state } from './state.js';
import { noteFrame, showStats, updateProgress } from './status.js';

const MAX_SIDE = Math.max(64, Math.min(768, Number(params.get('maxpx')) || 768));
const MIN_SIDE = 64;
const MAX_CANVAS = 2048;  // canvas backing store, per side
const MARKER_RADIUS = 11;  // the light marker's, CSS pixels (style.css)

export const canvas = $('view');
const ctx = canvas.getContext('2d', { willReadFrequently: true, alpha: false });
export const stage = $('stage');

// The canvas backing store follows its CSS size (times devicePixelRatio), whatever size frames come in.
export function sizeCanvas() {
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

// Where a frame of aspect `aspect` goes in a box `width` x `height`: all of it when the aspects agree
// within the rounding of the view's size to whole pixels (no sliver of a letterbox), else letterboxed.
function fitted(width, height, aspect) {
  if (Math.abs(aspect / (width / height) - 1) < 0.02) return { w: width, h: height };
  return width / height > aspect ? { w: height * aspect, h: height } : { w: width, h: width / aspect };
}

// Draws the frame shown, scaled to fit the canvas with smooth filtering (letterboxed only while its
// aspect is not the canvas's, as after a resize, until the frame of the new size comes).
export function paintFrame() {
  sizeCanvas();
  ctx.fillStyle = '#07090d';
  ctx.fillRect(0, 0, canvas.width, canvas.height);
  const f = state.frame;
  if (!f) return;
  const { w, h } = fitted(canvas.width, canvas.height, f.width / f.height);
  ctx.imageSmoothingEnabled = true;
  ctx.imageSmoothingQuality = 'high';
  ctx.drawImage(f.bitmap, 0, 0, f.bitmap.width, f.bitmap.height, (canvas.width - w) / 2, (canvas.height - h) / 2, w, h);
  hooks.lastDraw = {
    frame: [f.width, f.height], bitmap: [f.bitmap.width, f.bitmap.height], canvas: [canvas.width, canvas.height],
    drawn: [Math.round(w), Math.round(h)], smoothing: ctx.imageSmoothingEnabled ? ctx.imageSmoothingQuality : 'off',
  };
}

// Decodes a frame's PNG and shows it, unless a newer frame (a higher `token`) was drawn meanwhile.
export async function drawFrame(blob, meta, token, quality) {
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
  noteFrame(quality);
  hooks.framesReceived++;
  hooks.lastRevision = typeof meta.revision === 'number' ? meta.revision : hooks.lastRevision;
  hooks.lastSeq = meta.seq ?? null;
  hooks.lastMeta = meta;
  hooks.lastQuality = quality;
  hooks.drawn = [...hooks.drawn.slice(-15), { quality, revision: meta.revision }];
  showStats(meta, quality);
  updateProgress();
  updateLightMarker();
}

// The aspect (width / height) of the frames this view shows: the frame shown's, else the size asked for.
export function frameAspect() {
  const size = desiredImageSize();
  return state.frame ? state.frame.width / state.frame.height : size.width / size.height;
}

// Where the image sits inside the canvas element (CSS pixels; letterboxed as paintFrame draws it).
export function imageRect() {
  const r = canvas.getBoundingClientRect();
  const { w, h } = fitted(r.width, r.height, frameAspect());
  return { left: (r.width - w) / 2, top: (r.height - h) / 2, width: w, height: h };
}

export function updateLightMarker() {
  const marker = $('light-marker');
  const doc = panel();
  if (!doc.camera || !doc.light?.position) { marker.hidden = true; return; }
  const rect = imageRect();
  const p = S.project(S.cameraOf(doc), rect.width / Math.max(1, rect.height), doc.light.position);
  if (!p) { marker.hidden = true; return; }
  // Off the image: pin the marker to the image border, in the light's direction.
  const out = Math.max(Math.abs(p.x), Math.abs(p.y));
  const edge = out > 1;
  if (edge) { p.x = (p.x / out) * 0.96; p.y = (p.y / out) * 0.96; }
  marker.classList.toggle('edge', edge);
  marker.hidden = false;
  const x = rect.left + ((p.x + 1) / 2) * rect.width;
  let y = rect.top + ((1 - p.y) / 2) * rect.height;
  // Never under the progress line: a marker there goes just below it, at the same x.
  const s = stage.getBoundingClientRect();
  const hud = $('hud-status').getBoundingClientRect();
  const half = MARKER_RADIUS + 2;
  if (x + half > hud.left - s.left && x - half < hud.right - s.left && y - half < hud.bottom - s.top && y + half > hud.top - s.top) {
    y = hud.bottom - s.top + half;
  }
  marker.style.left = `${x}px`;
  marker.style.top = `${y}px`;
}

// The progress line grows and shrinks with what it says: the light marker keeps out from under it.
new ResizeObserver(() => updateLightMarker()).observe($('hud-status'));

// The image size the stage asks for: its CSS size × devicePixelRatio, at most MAX_SIDE (?maxpx=) a side.
export function desiredImageSize() {
  const rect = stage.getBoundingClientRect();
  const dpr = window.devicePixelRatio || 1;
  let w = Math.max(1, rect.width * dpr);
  let h = Math.max(1, rect.height * dpr);
  const k = Math.min(1, MAX_SIDE / Math.max(w, h));
  w = Math.max(MIN_SIDE, Math.round((w * k) / 2) * 2);
  h = Math.max(MIN_SIDE, Math.round((h * k) / 2) * 2);
  return { width: w, height: h };
}
