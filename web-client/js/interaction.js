// What the view does with input: a drag orbits the camera around its target (Shift, or light mode: the
// chosen light; Alt: the chosen object), the wheel and a pinch zoom, keys do the same on the focused view,
// and the toolbar; and the image size follows the view's.

import { placedObject } from './catalog.js';
import { $ } from './dom.js';
import * as S from './scene.js';
import { checkImageSize, edit, requestFrame } from './session.js';
import { later, panel, seenDocument, state } from './state.js';
import { announce } from './status.js';
import { canvas, desiredImageSize, imageRect, paintFrame, sizeCanvas, stage, updateLightMarker } from './viewport.js';

const ORBIT_STEP = 5 * Math.PI / 180;  // arrow keys
const ZOOM_STEP = 1.1;

let lightMode = false;
const pointers = new Map();

function orbitCamera(dAz, dEl, final) {
  const cam = S.cameraOf(seenDocument());
  const position = S.roundVec(S.orbit(cam.position, cam.target, dAz, dEl, 4));
  edit({ camera: { position } }, final);
}

function zoomCamera(factor, final) {
  const cam = S.cameraOf(seenDocument());
  edit({ camera: { position: S.roundVec(S.dolly(cam.position, cam.target, factor)) } }, final);
}

// Aims the camera at the object and sets its distance so the whole object fits the view.
function frameObject() {
  const doc = panel();
  const { center, radius } = placedObject(doc.object || {});
  const size = desiredImageSize();
  const cam = S.cameraOf(doc);
  const target = S.roundVec(center, 5);
  const position = S.roundVec(S.framePosition(cam, center, radius, size.width / size.height), 5);
  edit({ camera: { target, position } }, true);
}

function moveLight(dAz, dEl, final) {
  const doc = panel();
  const target = S.cameraOf(doc).target;
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
  const moved = S.panInView(S.cameraOf(doc), rect.width / rect.height, position,
    (2 * dxPixels) / rect.width, (-2 * dyPixels) / rect.height);
  edit({ object: { position: S.roundVec(moved, 4) } }, false);
}

function setLightMode(on) {
  lightMode = on;
  const btn = $('mode-light');
  btn.setAttribute('aria-pressed', String(on));
  stage.classList.toggle('light-mode', on);
  canvas.setAttribute('aria-label', on
    ? 'Rendered scene, light mode: drag or arrow keys move the light'
    : 'Rendered scene: drag or arrow keys orbit the camera');
  updateLightMarker();
}

function dragAngles(dx, dy) {
  const h = Math.max(100, canvas.getBoundingClientRect().height);
  return [dx * Math.PI / h, dy * Math.PI / h];
}

function pointerDown(e) {
  if (e.pointerType === 'mouse' && e.button !== 0) return;
  canvas.focus({ preventScroll: true });
  canvas.setPointerCapture(e.pointerId);
  pointers.set(e.pointerId, { x: e.clientX, y: e.clientY });
  if (pointers.size === 1) {
    // Alt+drag moves the chosen object across the view, Shift+drag (or light mode) the chosen light.
    const object = e.altKey;
    state.drag = { x: e.clientX, y: e.clientY, object, light: !object && (e.shiftKey || lightMode), moved: false };
    stage.classList.toggle('dragging-light', state.drag.light);
  } else if (pointers.size === 2) {
    const [a, b] = [...pointers.values()];
    state.drag = { pinch: Math.hypot(a.x - b.x, a.y - b.y), moved: false };
  }
  e.preventDefault();
}

function pointerMove(e) {
  if (!pointers.has(e.pointerId) || !state.drag) return;
  pointers.set(e.pointerId, { x: e.clientX, y: e.clientY });
  const drag = state.drag;
  if (drag.pinch !== undefined) {
    if (pointers.size < 2) return;
    const [a, b] = [...pointers.values()];
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
}

function endPointer(e) {
  if (!pointers.delete(e.pointerId)) return;
  if (pointers.size > 0) return;
  const moved = state.drag?.moved;
  state.drag = null;
  stage.classList.remove('dragging-light');
  if (moved) edit(null, true);  // released: ask for the full-quality still
}

function wheel(e) {
  e.preventDefault();
  const delta = e.deltaMode === 1 ? e.deltaY * 16 : e.deltaY;
  zoomCamera(Math.exp(Math.max(-200, Math.min(200, delta)) * 0.0015), false);
  later('wheel', () => edit(null, true), 300);
}

function keydown(e) {
  const arrows = { ArrowLeft: [-1, 0], ArrowRight: [1, 0], ArrowUp: [0, -1], ArrowDown: [0, 1] };
  let handled = true;
  if (arrows[e.key]) {
    const [x, y] = arrows[e.key];
    if (e.shiftKey || lightMode) moveLight(x * ORBIT_STEP, -y * ORBIT_STEP, false);
    else orbitCamera(-x * ORBIT_STEP, y * ORBIT_STEP, false);
  } else if (e.key === '+' || e.key === '=' || e.key === 'PageUp') {
    zoomCamera(1 / ZOOM_STEP, false);
  } else if (e.key === '-' || e.key === '_' || e.key === 'PageDown') {
    zoomCamera(ZOOM_STEP, false);
  } else if ((e.key === 'f' || e.key === 'F') && !e.ctrlKey && !e.metaKey && !e.altKey) {
    frameObject();
    return void e.preventDefault();
  } else if ((e.key === 'l' || e.key === 'L') && !e.ctrlKey && !e.metaKey && !e.altKey) {
    setLightMode(!lightMode);
    announce(lightMode ? 'Light mode on' : 'Light mode off');
    return void e.preventDefault();
  } else {
    handled = false;
  }
  if (!handled) return;
  e.preventDefault();
  later('keys', () => edit(null, true), 350);  // settled: refine
}

// Wires the view's input and its toolbar, and shows the empty view.
export function initView() {
  new ResizeObserver(() => {
    if (sizeCanvas()) paintFrame();
    updateLightMarker();
    later('resize', () => checkImageSize(), 250);
  }).observe(stage);
  canvas.addEventListener('pointerdown', pointerDown);
  canvas.addEventListener('pointermove', pointerMove);
  canvas.addEventListener('pointerup', endPointer);
  canvas.addEventListener('pointercancel', endPointer);
  canvas.addEventListener('wheel', wheel, { passive: false });
  canvas.addEventListener('keydown', keydown);

  $('mode-light').addEventListener('click', () => setLightMode(!lightMode));
  $('zoom-in').addEventListener('click', () => zoomCamera(1 / ZOOM_STEP, true));
  $('zoom-out').addEventListener('click', () => zoomCamera(ZOOM_STEP, true));
  $('still-btn').addEventListener('click', () => requestFrame('still'));
  $('frame-object').addEventListener('click', frameObject);

  window.addEventListener('keydown', (e) => {
    if (e.key === 'Shift') stage.classList.add('shift');
  });
  window.addEventListener('keyup', (e) => {
    if (e.key === 'Shift') stage.classList.remove('shift');
  });

  setLightMode(false);
  paintFrame();
}
