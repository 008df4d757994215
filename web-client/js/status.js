// What the page says about itself: the connection badge and the device in the header, the progress line
// over the image, the frame's timings under it, the error banner above the panel and the screen reader's
// announcements.

import { $, h } from './dom.js';
import { hooks, state } from './state.js';

const DIM_AFTER_MS = 300;  // a frame pending this long (not while dragging) dims the one shown
const OTHER_EDIT_MS = 4000;  // how long the progress line says that another viewer edited the scene
const stage = $('stage');
let frameTimes = [];
let ticker = null;

export function setConn(kind, text) {
  const el = $('conn');
  el.dataset.state = kind;
  el.textContent = text;
  hooks.connected = kind === 'live';
  stage.classList.toggle('offline', kind !== 'live');
  updateProgress();
}

export function stageMessage(text) {
  const el = $('stage-msg');
  el.textContent = text || '';
  el.hidden = !text;
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

export function showDevice(health) {
  const { name, detail } = deviceText(health);
  const type = health?.device?.type;
  $('device-name').textContent = type ? `${name} · ${type}` : name;
  $('device-name').parentElement.title = detail ? `Render device: ${name} (${detail})` : `Render device: ${name}`;
  hooks.device = name;
}

export function showGlobalError(text) {
  const box = $('global-error');
  const close = h('button', { type: 'button', class: 'dismiss', text: 'Dismiss' });
  close.addEventListener('click', () => { box.hidden = true; });
  box.replaceChildren(h('span', { text }), close);
  box.hidden = false;
}

// How many view the scene (the daemon's count, this viewer included), in the header.
export function showViewers(count) {
  state.viewers = Number(count) || 1;
  const el = $('viewers');
  el.textContent = state.viewers === 1 ? '1 viewer' : `${state.viewers} viewers`;
  el.title = state.viewers === 1 ? 'Nobody else views this scene now' : `${state.viewers} people view this scene now, you included`;
  el.dataset.others = String(state.viewers > 1);
}

// Another viewer made revision `revision`: said on the progress line for a few seconds, and aloud.
export function noteOtherEdit(revision) {
  const now = performance.now();
  // Said aloud once in a while, not for every step of someone's drag.
  if (!state.otherEdit || now - state.otherEdit.at > OTHER_EDIT_MS) announce(`Another viewer edited the scene (revision ${revision})`);
  state.otherEdit = { revision, at: now };
  hooks.otherEdits++;
  updateProgress();
  setTimeout(updateProgress, OTHER_EDIT_MS + 50);
}

export function announce(text) {
  const el = $('announcer');
  el.textContent = '';
  requestAnimationFrame(() => { el.textContent = text; });
}

// ---- progress and stats ------------------------------------------------------------------------

// Counts a frame drawn, for the frames per second of a stream of previews: a still frame or a pause of a
// second starts a new measurement (refinement levels, about one a second, read as a drag's first seconds
// at half its rate).
export function noteFrame(quality) {
  const now = performance.now();
  if (quality !== 'interactive' || (frameTimes.length && now - frameTimes[frameTimes.length - 1] > 1000)) frameTimes = [];
  if (quality !== 'interactive') return;
  frameTimes.push(now);
  while (frameTimes.length > 1 && now - frameTimes[0] > 3000) frameTimes.shift();
}

function fps() {
  const t = frameTimes;
  if (t.length < 2) return null;
  const span = t[t.length - 1] - t[0];
  return span > 0 ? ((t.length - 1) * 1000) / span : null;
}

const duration = (ms) => (ms >= 1000 ? `${(ms / 1000).toFixed(ms < 10_000 ? 1 : 0)} s` : `${Math.round(ms)} ms`);

// The line over the image: what the client is waiting for, or what the last frame was. Runs on events
// and, while a frame is pending, a few times a second (elapsed time, dimming).
export function updateProgress() {
  const el = $('hud-status');
  const inf = state.inflight[0];  // the longest waiting
  const now = performance.now();
  const f = fps();
  const streaming = f !== null && now - frameTimes[frameTimes.length - 1] < 1000;
  let text;
  if (!hooks.connected) {
    text = $('conn').textContent;
  } else if (state.replacing) {
    text = 'Loading the scene…';
  } else if (state.playing) {
    const at = state.playing.at;
    text = at ? `Playing frame ${at.frame + 1} of ${at.frames} · ${at.time.toFixed(2)} s · ${state.playing.shown} shown`
      : 'Starting the animation…';
  } else if (inf) {
    // The newest request says what the daemon renders now: a still asked for after a drag's previews is
    // what comes, not the previews it replaced.
    const newest = state.inflight[state.inflight.length - 1];
    const waited = now - newest.sentAt;
    text = newest.quality === 'still' ? `Rendering the still frame… ${duration(waited)}` : `Rendering a preview… ${duration(waited)}`;
    // A stream of previews (dragging, wheel, keys): how many arrive per second.
    if (streaming && newest.quality === 'interactive') text = `${f.toFixed(f < 10 ? 1 : 0)} fps · ${text}`;
  } else if (hooks.lastQuality) {
    text = shownText(now);
  } else {
    text = 'Waiting for the first frame…';
  }
  el.textContent = text;
  el.dataset.state = !hooks.connected ? 'offline' : inf || state.replacing ? 'busy' : 'idle';
  const dim = Boolean((inf && !state.drag && now - inf.sentAt > DIM_AFTER_MS) || state.replacing || state.newScene);
  const dimmed = dim && Boolean(state.frame);
  if (dimmed && !stage.classList.contains('pending')) hooks.dims++;
  stage.classList.toggle('pending', dimmed);
  if ((inf || state.replacing) && !ticker) {
    ticker = setInterval(updateProgress, 200);
  } else if (!inf && !state.replacing && ticker) {
    clearInterval(ticker);
    ticker = null;
  }
}

// What the frame shown is: a still (and how far the daemon's refinement has come), a preview (the still
// follows unasked), a frame pushed for an edit made elsewhere; and, for a while, another viewer's edit.
function shownText(now) {
  const meta = hooks.lastMeta || {};
  const took = hooks.latencyMs && !state.pushed ? `, ${duration(hooks.latencyMs)}` : '';
  const still = hooks.lastQuality === 'still';
  let text = still ? `Still frame${took}` : `Preview${took}`;
  if (state.pushed) text = still ? 'Still frame of an edit made elsewhere' : 'Preview of an edit made elsewhere';
  // The daemon keeps refining a still frame (more photons, then anti-aliasing) until its cap.
  if (still && meta.level >= 1 && meta.refine > meta.level) text += ` · refining ${meta.level}/${meta.refine}`;
  else if (still && meta.level > 1) text += ` · refined (level ${meta.level})`;
  else if (!still && meta.refine > 0 && !state.playing) text += ' · the still frame follows';
  const other = state.otherEdit;
  if (other && now - other.at < OTHER_EDIT_MS) text = `Another viewer edited the scene (revision ${other.revision}) · ${text}`;
  return text;
}

// What a play showed, as the viewer saw it: the frames drawn of those the animation has, and those the
// daemon skipped to keep time at `fps`. `done`: it reached its last frame.
export function playedNote(playing, fps, done = true) {
  const total = playing.at ? playing.at.frames : 0;
  const shown = `${playing.shown} of ${total} frame${total === 1 ? '' : 's'} shown`;
  const skipped = done ? total - playing.shown : (playing.at ? playing.at.frame + 1 : 0) - playing.shown;
  const keptTime = skipped > 0 ? `, ${skipped} skipped to keep time (the renderer could not draw ${fps} a second)` : '';
  return done ? `Played ${playing.name}: ${shown}${keptTime}.` : `${playing.shown} frame${playing.shown === 1 ? '' : 's'} shown${keptTime}.`;
}

const passClass = (name) => `pass pass-${String(name).replace(/[^a-z_]/g, '')}`;

// The strip under the image: the last frame, and the time each pass took (the last frame that ran any).
export function showStats(meta, quality) {
  // A preview traced smaller than it is shown (its floor and sky drawn at full size) says so.
  const traced = meta.traced_width && meta.traced_width !== meta.width ? ` (traced ${meta.traced_width}×${meta.traced_height})` : '';
  const size = meta.width && meta.height ? `${meta.width}×${meta.height}${traced}` : '';
  const what = meta.play ? `Played frame ${meta.play.frame + 1}/${meta.play.frames}` : quality === 'interactive' ? 'Preview' : 'Still';
  const pushed = state.pushed ? ' (an edit made elsewhere)' : '';
  const parts = [`${what} ${size}`.trim() + pushed, `revision ${meta.revision ?? '—'}`];
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
