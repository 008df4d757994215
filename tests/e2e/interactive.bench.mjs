#!/usr/bin/env node
// Interactive benchmark of the browser client against a real refractd (issue 21). Not a test: it
// measures, prints a table and one JSON line, and fails only when it could not measure at all.
//
//   node tests/e2e/interactive.bench.mjs PATH/TO/refractd [PATH/TO/web-client] [LABEL]
//
// Starts refractd on free loopback ports with a temporary data directory (lavapipe's threads as the
// daemon chooses them, four a core, unless LP_NUM_THREADS is set), opens the client in Debian's
// headless Chromium (playwright-core, no browser download) at the default URL and window size, on the
// default scene document, and measures:
//   - the daemon's warm-up (health's warming_up), which navigation waits for, as a user opening the
//     client on a running daemon would;
//   - navigation to the first frame received and drawn, and to the first full-resolution still;
//   - a 3 s orbit drag, a 3 s shift-drag of the light and a 3 s alt-drag of the object: frames received per second while dragging,
//     and the time from releasing the mouse to the first full-resolution still; for the orbit and the
//     light, the width of the frames shown while dragging and the RMSE of the last one shown against
//     the same state refined to level 16 (what the canvas shows, 8-bit sRGB);
//   - every example loaded from the picker: the slowest first frame and full-resolution still;
//   - an exposure edit over HTTP (POST frame.png with a merge patch): the Server-Timing pass sum and
//     the request's wall time.
// Frames are observed on the page's WebSocket (header, then PNG), which works for any client
// version; the client's window.refract hooks, where present, add when a frame was drawn.
// $REFRACT_CHROMIUM overrides /usr/bin/chromium; $REFRACT_BENCH_LOG keeps the daemon's log there;
// $REFRACT_BENCH_SHOTS names a folder for a screenshot halfway through each drag (LABEL-WHAT-mid-drag.png)
// and, for the orbit and the light, the view as the RMSE compares it (LABEL-WHAT-last-shown.png, -refined.png);
// $REFRACT_BENCH_QUERY is appended to the client's URL (temporal=1: previews by temporal reuse).

import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

import { freePort, killOnExit, loadChromium, sleep, startRefractd, stopRefractd, waitForHealth } from './refractd.mjs';

const chromium = await loadChromium();

const HERE = path.dirname(fileURLToPath(import.meta.url));
const REPO = path.resolve(HERE, '../..');
const [refractdArg, webRootArg, labelArg] = process.argv.slice(2);
if (!refractdArg) {
  console.error('usage: node interactive.bench.mjs PATH/TO/refractd [PATH/TO/web-client] [LABEL]');
  process.exit(2);
}
const REFRACTD = path.resolve(refractdArg);
const WEB_ROOT = path.resolve(webRootArg || path.join(REPO, 'web-client'));
const LABEL = labelArg || REFRACTD;
const SHOTS = process.env.REFRACT_BENCH_SHOTS || '';
const QUERY = process.env.REFRACT_BENCH_QUERY || '';  // appended to the client's URL, e.g. temporal=1
const CHROMIUM = process.env.REFRACT_CHROMIUM || '/usr/bin/chromium';
const DRAG_MS = 3000;
const MOVE_EVERY_MS = 16;           // pointer moves while dragging: about one per display frame
const SETTLE_TIMEOUT_MS = 90_000;   // a still frame after navigation or a drag
const LOOK_MS = 2000;               // a drag begins this long after the still before it arrived
const HARD_LIMIT_MS = 8 * 60_000;   // the whole run
const EXPOSURE_EDITS = [1.3, 0.7, 1.3];
const REFINED_LEVEL = 16;           // what a drag's last frame is compared with (issue 37): all photon batches in
const HOLD_MS = 400;                // the pointer held still before a measured release

const tmp = fs.mkdtempSync(path.join(os.tmpdir(), 'refract-bench-'));
const dataDir = path.join(tmp, 'data');
const daemonLogPath = process.env.REFRACT_BENCH_LOG || path.join(tmp, 'refractd.log');
const daemonLog = fs.createWriteStream(daemonLogPath);

let daemon = null;
let browser = null;
let base = '';
const t0 = Date.now();
const log = (...args) => console.error(`[bench +${((Date.now() - t0) / 1000).toFixed(1)}s]`, ...args);

// ---- daemon --------------------------------------------------------------------------------------

function startDaemon(httpPort, wsPort) {
  const args = ['--bind', '127.0.0.1', '--port', String(httpPort), '--ws-port', String(wsPort),
    '--data-dir', dataDir, '--web-root', WEB_ROOT];
  return startRefractd(REFRACTD, args, daemonLog, log);
}

// ---- frames seen on the page's WebSocket ---------------------------------------------------------

// Every frame the daemon sent: its header (meta), when the header and the PNG arrived (epoch ms).
const frames = [];
const sent = [];  // requests the client sent: { t, seq, quality, patch, view }
let pendingHeader = null;

function watchSockets(page) {
  page.on('websocket', (ws) => {
    if (!/\/ws(\?|$)/.test(ws.url())) return;
    ws.on('framereceived', ({ payload }) => {
      const t = Date.now();
      if (typeof payload === 'string') {
        let msg = null;
        try { msg = JSON.parse(payload); } catch { return; }
        if (msg && msg.type === 'frame') pendingHeader = { meta: msg, tHeader: t };
        return;
      }
      const head = pendingHeader || { meta: {}, tHeader: t };
      pendingHeader = null;
      const m = head.meta;
      frames.push({
        t, tHeader: head.tHeader, quality: m.quality ?? null, width: m.width ?? null, height: m.height ?? null,
        tracedWidth: m.traced_width ?? m.width ?? null,
        level: m.level ?? null, revision: m.revision ?? null, seq: m.seq ?? null, cached: Boolean(m.cached), bytes: payload.length,
        passMs: sumTimings(m.timings), timings: m.timings ?? null, photons: m.photons ?? null,
      });
    });
    ws.on('framesent', ({ payload }) => {
      if (typeof payload !== 'string') return;
      try {
        const msg = JSON.parse(payload);
        sent.push({ t: Date.now(), seq: msg.seq ?? null, quality: msg.quality ?? null, patch: msg.patch ?? null, view: msg.view ?? null });
      } catch { /* not ours */ }
    });
  });
}

function sumTimings(timings) {
  if (!timings || typeof timings !== 'object') return null;
  const values = Object.values(timings).filter((v) => typeof v === 'number');
  return values.length ? values.reduce((a, b) => a + b, 0) : null;
}

// Each pass's median milliseconds over `frames` (over those that ran it), rounded: where a drag's
// frames spend their time.
function medianTimings(frames) {
  const names = [...new Set(frames.flatMap((f) => Object.keys(f.timings ?? {})))];
  return roundTimings(Object.fromEntries(names.map((n) => [n, median(frames.map((f) => f.timings?.[n]))])));
}

// Per-pass milliseconds of a frame, rounded for the JSON line: where a slow frame spent its time.
function roundTimings(timings) {
  if (!timings || typeof timings !== 'object') return null;
  return Object.fromEntries(Object.entries(timings).map(([k, v]) => [k, typeof v === 'number' ? Math.round(v * 10) / 10 : v]));
}

// Milliseconds from sending the request a frame answers to receiving it: the frame's passes plus its
// wait and delivery. Null for frames nobody on the page asked for and for the refinement levels that
// follow an answer (they repeat its seq).
function sinceAsked(f) {
  if (typeof f.seq !== 'number' || frames.find((x) => x.seq === f.seq) !== f) return null;
  const asked = sent.find((m) => m.seq === f.seq);
  return asked ? f.t - asked.t : null;
}

// The client's own record of drawn frames, where it has window.refract: epoch ms of each draw.
async function recordDraws(page) {
  await page.evaluate(() => {
    const draws = [];
    window.__benchDraws = draws;
    let seen = 0;
    const tick = () => {
      const hooks = window.refract;
      if (hooks && typeof hooks.framesReceived === 'number' && hooks.framesReceived !== seen) {
        seen = hooks.framesReceived;
        const meta = hooks.lastMeta || {};
        draws.push({ t: performance.timeOrigin + performance.now(), quality: hooks.lastQuality ?? meta.quality ?? null,
          width: meta.width ?? null, height: meta.height ?? null });
      }
      requestAnimationFrame(tick);
    };
    requestAnimationFrame(tick);
  });
}

const isFull = (f, size) => f.quality === 'still' && f.width === size.width && f.height === size.height;

async function waitUntil(pred, timeoutMs, what) {
  const deadline = Date.now() + timeoutMs;
  while (Date.now() < deadline) {
    const hit = pred();
    if (hit) return hit;
    await sleep(20);
  }
  throw new Error(`timed out after ${timeoutMs / 1000} s waiting for ${what}`);
}

// The user looks at the still for LOOK_MS; a daemon that refines stills keeps rendering meanwhile.
// Returns how many frames (refinement levels) arrived after the still.
async function look(still) {
  await sleep(Math.max(0, still.t + LOOK_MS - Date.now()));
  return frames.filter((f) => f.t > still.t).length;
}

const median = (xs) => {
  const s = xs.filter((x) => typeof x === 'number').sort((a, b) => a - b);
  if (!s.length) return null;
  return s.length % 2 ? s[(s.length - 1) / 2] : (s[s.length / 2 - 1] + s[s.length / 2]) / 2;
};

// ---- the measurements ----------------------------------------------------------------------------

async function sceneOnServer(id) {
  const res = await fetch(`${base}/api/scenes/${encodeURIComponent(id)}`);
  const body = await res.json();
  return { revision: body.revision };
}

// The image size the client last asked for (its view follows its canvas): full resolution. A client
// from before views (issue 38) patched the document's image size instead.
function viewSize() {
  const last = [...sent].reverse().find((m) => m.view || (m.patch?.image?.width && m.patch?.image?.height));
  if (!last) return null;
  const { width, height } = last.view || last.patch.image;
  return { width, height };
}

// The first full-resolution still received after `since` that shows the scene as it is now: its
// revision is the daemon's current one, it answers (or refines) the client's last edit or change of
// view before it, and the client sent none after it arrived. (A refinement of an older revision or of
// the view before an orbit, in flight when a drag began, does not count.)
async function stillOfLatest(sceneId, size, since, what) {
  const deadline = Date.now() + SETTLE_TIMEOUT_MS;
  const changed = (m) => m.patch || m.view;
  const lastChange = (t) => sent.filter((m) => m.t <= t && changed(m)).reduce((seq, m) => Math.max(seq, m.seq ?? -1), -1);
  while (Date.now() < deadline) {
    const { revision } = await sceneOnServer(sceneId);
    const f = frames.find((x) => x.t >= since && isFull(x, size) && x.revision === revision &&
      (x.seq === null || x.seq >= lastChange(x.t)));
    if (f && !sent.some((m) => m.t > f.t && changed(m))) return f;
    await sleep(50);
  }
  throw new Error(`timed out after ${SETTLE_TIMEOUT_MS / 1000} s waiting for ${what}`);
}

// A drag of DRAG_MS over the canvas (`what`: 'orbit'; 'light' with Shift; 'object' with Alt), then
// release; frames while dragging and the time from release to the first full-resolution still; with
// `refined`, the pointer held still for HOLD_MS before the release and the RMSE of the last frame shown
// then against that state refined to REFINED_LEVEL. Returns [measurements, the last frame waited for].
async function drag(page, sceneId, size, what, refined = false) {
  const modifier = { orbit: null, light: 'Shift', object: 'Alt' }[what];
  const box = await page.locator('#view').boundingBox();
  const cx = box.x + box.width / 2;
  const cy = box.y + box.height / 2;
  const amp = Math.min(box.width, box.height) * 0.25;
  const firstIndex = frames.length;
  const sentIndex = sent.length;
  await page.mouse.move(cx, cy);
  if (modifier) await page.keyboard.down(modifier);
  await page.mouse.down();
  const start = Date.now();
  let moves = 0;
  let shot = !SHOTS;
  while (Date.now() - start < DRAG_MS) {
    const phase = ((Date.now() - start) / 1500) * 2 * Math.PI;
    await page.mouse.move(cx + amp * Math.sin(phase), cy + 0.3 * amp * Math.sin(2 * phase));
    moves++;
    if (!shot && Date.now() - start > DRAG_MS / 2) {
      shot = true;
      await page.screenshot({ path: path.join(SHOTS, `${LABEL}-${what}-mid-drag.png`) });
    }
    await sleep(MOVE_EVERY_MS);
  }
  const end = Date.now();
  if (refined) {
    // The pointer held still before the release, so that the last frame shown is of the state the
    // refined still shows; then what the canvas shows (at the viewport's size).
    await sleep(HOLD_MS);
    await page.evaluate(() => { window.__benchShown = canvasNow(); });
    if (SHOTS) await page.locator('#view').screenshot({ path: path.join(SHOTS, `${LABEL}-${what}-last-shown.png`) });
  }
  const released = Date.now();
  await page.mouse.up();
  if (modifier) await page.keyboard.up(modifier);
  const during = frames.slice(firstIndex).filter((f) => f.t >= start && f.t <= end);
  const still = await stillOfLatest(sceneId, size, released, `a full-resolution still after the ${what} drag`);
  const interactive = during.filter((f) => f.quality === 'interactive');
  const firstDuring = frames.slice(firstIndex).find((f) => f.t >= start);
  // Frames of the drag's own edits: from the first one answering a request sent while dragging.
  const firstSeq = sent.slice(sentIndex).find((m) => m.t >= start)?.seq;
  const answers = (f) => typeof f.seq === 'number' && typeof firstSeq === 'number' && f.seq >= firstSeq;
  const firstAnswer = frames.slice(firstIndex).find(answers);
  const answering = during.filter(answers);
  const steadySpan = answering.length >= 2 ? (answering[answering.length - 1].t - answering[0].t) / 1000 : 0;
  const result = {
    seconds: (end - start) / 1000,
    moves,
    requests: sent.slice(sentIndex).filter((s) => s.t >= start && s.t <= end).length,
    frames: during.length,
    fps: during.length / ((end - start) / 1000),
    interactive_frames: interactive.length,
    first_frame_ms: firstDuring ? firstDuring.t - start : null,
    first_answer_ms: firstAnswer ? firstAnswer.t - start : null,
    steady_fps: steadySpan > 0 ? (answering.length - 1) / steadySpan : null,
    interactive_size: interactive.length ? `${median(interactive.map((f) => f.width))}x${median(interactive.map((f) => f.height))}` : null,
    interactive_pass_ms: median(interactive.map((f) => f.passMs)),
    interactive_timings: medianTimings(interactive),
    release_to_full_ms: still.t - released,
    still_pass_ms: still.passMs,
    still_level: still.level,
    viewport_width: size.width,
    displayed_width: median(interactive.map((f) => f.width)),
    // The width the frames' eye rays were traced at (a daemon that sends previews at the viewer's size
    // says so in traced_width; before, what was traced was what was sent).
    traced_width: median(interactive.map((f) => f.tracedWidth)),
  };
  if (refined) {
    // Against the same state refined: the first frame of it at REFINED_LEVEL or above, once drawn.
    const settled = await waitUntil(() => frames.find((f) => f.t >= still.t && isFull(f, size) &&
      f.revision === still.revision && (f.level ?? 0) >= REFINED_LEVEL), SETTLE_TIMEOUT_MS, `level ${REFINED_LEVEL}`);
    await sleep(150);  // drawn
    if (SHOTS) await page.locator('#view').screenshot({ path: path.join(SHOTS, `${LABEL}-${what}-refined.png`) });
    result.rmse_vs_still = await page.evaluate(() => srgbRmse(window.__benchShown, canvasNow()));
    result.refined_level = settled.level;
    return [result, settled];
  }
  return [result, still];
}

// Installs the page helpers the drags measure with: the canvas's pixels now, and the RMSE of two such
// snapshots over the 8-bit sRGB channels (null when their sizes differ).
async function installPixelHelpers(page) {
  await page.evaluate(() => {
    window.canvasNow = () => {
      const c = document.getElementById('view');
      return c.getContext('2d').getImageData(0, 0, c.width, c.height);
    };
    window.srgbRmse = (a, b) => {
      if (!a || !b || a.width !== b.width || a.height !== b.height) return null;
      let sum = 0;
      for (let i = 0; i < a.data.length; i += 4)
        for (let c = 0; c < 3; c++) sum += (a.data[i + c] - b.data[i + c]) ** 2;
      return Math.sqrt(sum / (3 * a.width * a.height));
    };
  });
}

// Loads every example from the picker (as a user does, the scene replaced) and times, from the click,
// its first frame and its first full-resolution still.
async function loadExamples(page, sceneId, size) {
  const list = await (await fetch(`${base}/api/examples`)).json();
  const names = (list.examples || []).map((e) => e.name);
  const loads = [];
  for (const name of names) {
    const before = (await sceneOnServer(sceneId)).revision;
    const since = Date.now();
    await page.selectOption('#ctl-example', name);
    await page.click('#example-load');
    const first = await waitUntil(() => frames.find((f) => f.t >= since && (f.revision ?? 0) > before),
      SETTLE_TIMEOUT_MS, `the first frame of ${name}`);
    const full = await stillOfLatest(sceneId, size, since, `the still of ${name}`);
    loads.push({ name, first_frame_ms: first.t - since, first_quality: first.quality, full_ms: full.t - since });
    log('example', JSON.stringify(loads[loads.length - 1]));
  }
  const slowest = (key) => Math.max(...loads.map((l) => l[key]));
  return { examples_first_frame_ms: slowest('first_frame_ms'), examples_full_ms: slowest('full_ms'), loads };
}

// An exposure edit over HTTP on the daemon's "default" scene, rendered once before (not timed).
async function exposureEdits() {
  const url = `${base}/api/scenes/default/frame.png`;
  const warm = await fetch(url);
  await warm.arrayBuffer();
  if (warm.status !== 200) throw new Error(`GET ${url} -> ${warm.status}`);
  const edits = [];
  for (const exposure of EXPOSURE_EDITS) {
    const startedAt = performance.now();
    const res = await fetch(url, {
      method: 'POST', headers: { 'Content-Type': 'application/merge-patch+json' },
      body: JSON.stringify({ image: { exposure } }),
    });
    await res.arrayBuffer();
    const wall = performance.now() - startedAt;
    if (res.status !== 200) throw new Error(`POST ${url} -> ${res.status}`);
    const timing = res.headers.get('server-timing') || '';
    const passes = {};
    for (const part of timing.split(',')) {
      const m = /^\s*([^;]+);dur=([0-9.]+)/.exec(part);
      if (m) passes[m[1].trim()] = Number(m[2]);
    }
    edits.push({ exposure, passMs: Object.values(passes).reduce((a, b) => a + b, 0), wallMs: wall, passes });
  }
  return edits;
}

async function main() {
  const httpPort = await freePort();
  let wsPort;
  do wsPort = await freePort(); while (wsPort === httpPort);
  base = `http://127.0.0.1:${httpPort}`;
  daemon = startDaemon(httpPort, wsPort);
  const health = await waitForHealth(base, daemon);
  const device = health.device?.name ?? health.device ?? null;
  log('refractd is up:', JSON.stringify(device));
  // A user opens the client on a running daemon: navigation waits for its warm-up (health's warming_up;
  // a daemon without the field has none to wait for). How long that took is reported beside it.
  const warmStart = Date.now();
  for (let h = health; h.warming_up === true; h = await (await fetch(`${base}/api/health`)).json()) {
    if (Date.now() - warmStart > SETTLE_TIMEOUT_MS) throw new Error('the daemon stayed warming up');
    await sleep(50);
  }
  const warmUpMs = Date.now() - warmStart;
  log(`warm-up ended ${warmUpMs} ms after health answered`);

  browser = await chromium.launch({
    executablePath: CHROMIUM,
    args: ['--headless', '--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run',
      '--disable-background-networking', '--disable-component-update', '--disable-sync'],
  });
  const context = await browser.newContext();  // Playwright's default window: 1280x720, scale 1
  const page = await context.newPage();
  page.on('pageerror', (e) => log('page error:', e.message));
  watchSockets(page);

  // 1. Navigation to the first frame and the first full-resolution still.
  const navStart = Date.now();
  await page.goto(`${base}/${QUERY ? `?${QUERY}` : ''}`);
  const hooked = await page.evaluate(() => typeof window.refract === 'object' && window.refract !== null);
  if (hooked) await recordDraws(page);
  await waitUntil(() => frames.length > 0, SETTLE_TIMEOUT_MS, 'the first frame');
  await waitUntil(() => sent.length > 0, SETTLE_TIMEOUT_MS, 'the first request');
  const sceneId = await page.evaluate(() => new URL(location.href).searchParams.get('scene'));
  // The image size the client asked for (it follows the canvas), i.e. full resolution.
  await waitUntil(() => frames.some((f) => f.quality === 'still'), SETTLE_TIMEOUT_MS, 'a still frame');
  const size = viewSize();
  const firstFull = await stillOfLatest(sceneId, size, navStart, 'a full-resolution still');
  const draws = hooked ? await page.evaluate(() => window.__benchDraws) : [];
  const firstDraw = draws.find((d) => d.t >= navStart);
  const firstFullDraw = draws.find((d) => d.quality === 'still' && d.width === size.width && d.height === size.height);
  const load = {
    warm_up_ms: warmUpMs,
    first_frame_ms: frames[0].t - navStart,
    first_drawn_ms: firstDraw ? firstDraw.t - navStart : null,
    first_full_ms: firstFull.t - navStart,
    first_full_drawn_ms: firstFullDraw ? firstFullDraw.t - navStart : null,
    first_quality: frames[0].quality,
    first_size: `${frames[0].width}x${frames[0].height}`,
    full_size: `${size.width}x${size.height}`,
    full_pass_ms: firstFull.passMs,
  };
  log('load', JSON.stringify(load));

  // 2. Drags, each LOOK_MS after the still before it.
  await installPixelHelpers(page);
  const refinedBeforeOrbit = await look(firstFull);
  const [orbit, orbitStill] = await drag(page, sceneId, size, 'orbit', true);
  orbit.frames_before = refinedBeforeOrbit;
  log('orbit', JSON.stringify(orbit));
  const refinedBeforeLight = await look(orbitStill);
  const [light, lightStill] = await drag(page, sceneId, size, 'light', true);
  light.frames_before = refinedBeforeLight;
  log('light', JSON.stringify(light));
  const refinedBeforeObject = await look(lightStill);
  const [object] = await drag(page, sceneId, size, 'object');
  object.frames_before = refinedBeforeObject;
  log('object', JSON.stringify(object));
  const maxLevel = Math.max(0, ...frames.map((f) => f.level ?? 0));
  // 3. Every example loaded, the slowest first frame and still (issue 37).
  const examples = await loadExamples(page, sceneId, size);
  await page.close();
  await context.close();

  // 4. The exposure edit, with no page rendering alongside.
  const edits = await exposureEdits();
  log('exposure', JSON.stringify(edits.map(({ passes, ...e }) => e)));

  return {
    label: LABEL, refractd: REFRACTD, web_root: WEB_ROOT, device, hooks: hooked, scene: sceneId,
    frames_total: frames.length, max_level: maxLevel, load, orbit, light, object,
    examples_first_frame_ms: examples.examples_first_frame_ms, examples_full_ms: examples.examples_full_ms,
    examples: examples.loads,
    frames: frames.map((f) => [f.t - navStart, f.quality, `${f.width}x${f.height}`, f.level, f.revision, f.seq,
      f.passMs === null ? null : Math.round(f.passMs), roundTimings(f.timings), sinceAsked(f), f.photons, f.tracedWidth]),
    exposure: {
      first_pass_ms: edits[0].passMs, first_wall_ms: edits[0].wallMs,
      median_pass_ms: median(edits.map((e) => e.passMs)), median_wall_ms: median(edits.map((e) => e.wallMs)),
      passes: edits[0].passes,
    },
  };
}

function table(r) {
  const ms = (v) => (typeof v === 'number' ? `${Math.round(v)} ms` : '—');
  const num = (v) => (typeof v === 'number' ? v.toFixed(1) : '—');
  const rows = [
    ['daemon warm-up, waited before navigation', ms(r.load.warm_up_ms), 'health: warming_up'],
    ['navigation -> first frame received', ms(r.load.first_frame_ms), `${r.load.first_quality} ${r.load.first_size}`],
    ['navigation -> first frame drawn', ms(r.load.first_drawn_ms), r.hooks ? 'window.refract' : 'no hooks'],
    ['navigation -> first full-resolution still', ms(r.load.first_full_ms), `${r.load.full_size}, passes ${ms(r.load.full_pass_ms)}`],
    ['orbit drag: frames/s', r.orbit.fps.toFixed(1), `${r.orbit.frames} frames in ${r.orbit.seconds.toFixed(1)} s, interactive ${r.orbit.interactive_size ?? '—'}`],
    ['orbit: first frame of the drag\'s edits', ms(r.orbit.first_answer_ms), `then ${r.orbit.steady_fps === null ? '—' : r.orbit.steady_fps.toFixed(1)} frames/s, interactive passes ${ms(r.orbit.interactive_pass_ms)}`],
    ['orbit release -> full-resolution still', ms(r.orbit.release_to_full_ms), `passes ${ms(r.orbit.still_pass_ms)}`],
    ['light drag: frames/s', r.light.fps.toFixed(1), `${r.light.frames} frames in ${r.light.seconds.toFixed(1)} s, interactive ${r.light.interactive_size ?? '—'}`],
    ['light: first frame of the drag\'s edits', ms(r.light.first_answer_ms), `then ${r.light.steady_fps === null ? '—' : r.light.steady_fps.toFixed(1)} frames/s, interactive passes ${ms(r.light.interactive_pass_ms)}`],
    ['light release -> full-resolution still', ms(r.light.release_to_full_ms), `passes ${ms(r.light.still_pass_ms)}`],
    ['orbit / light: frame width shown while dragging', `${r.orbit.displayed_width} / ${r.light.displayed_width}`, `the viewport's: ${r.orbit.viewport_width}; traced ${r.orbit.traced_width} / ${r.light.traced_width}`],
    ['orbit / light: RMSE of the last drag frame vs refined', `${num(r.orbit.rmse_vs_still)} / ${num(r.light.rmse_vs_still)}`, `8-bit sRGB, against level ${REFINED_LEVEL}+`],
    ['object drag (Alt): frames/s', r.object.fps.toFixed(1), `${r.object.frames} frames in ${r.object.seconds.toFixed(1)} s, interactive ${r.object.interactive_size ?? '—'}`],
    ['object: first frame of the drag\'s edits', ms(r.object.first_answer_ms), `then ${r.object.steady_fps === null ? '—' : r.object.steady_fps.toFixed(1)} frames/s, interactive passes ${ms(r.object.interactive_pass_ms)}`],
    ['object release -> full-resolution still', ms(r.object.release_to_full_ms), `passes ${ms(r.object.still_pass_ms)}`],
    ['examples: slowest first frame after Load', ms(r.examples_first_frame_ms), `${r.examples.length} examples`],
    ['examples: slowest full-resolution still after Load', ms(r.examples_full_ms), ''],
    ['exposure edit: pass sum (Server-Timing)', ms(r.exposure.first_pass_ms), `median of ${EXPOSURE_EDITS.length}: ${ms(r.exposure.median_pass_ms)}`],
    ['exposure edit: wall time (HTTP)', ms(r.exposure.first_wall_ms), `median of ${EXPOSURE_EDITS.length}: ${ms(r.exposure.median_wall_ms)}`],
  ];
  const w0 = Math.max(...rows.map((x) => x[0].length));
  const w1 = Math.max(...rows.map((x) => x[1].length));
  return rows.map(([a, b, c]) => `${a.padEnd(w0)}  ${b.padStart(w1)}  ${c}`).join('\n');
}

// ---- run -----------------------------------------------------------------------------------------

async function cleanup() {
  try { if (browser) await browser.close(); } catch { /* already gone */ }
  browser = null;
  await stopRefractd(daemon);
  daemon = null;
  await new Promise((resolve) => daemonLog.end(resolve));
  if (!process.env.REFRACT_BENCH_LOG) fs.rmSync(tmp, { recursive: true, force: true });
  else fs.rmSync(dataDir, { recursive: true, force: true });
}

killOnExit(() => daemon, () => browser, log);
const limit = setTimeout(() => {
  log(`still running after ${HARD_LIMIT_MS / 60_000} min: stopping`);
  if (daemon && daemon.exitCode === null) daemon.kill('SIGKILL');
  if (browser) browser.close().catch(() => {});
  setTimeout(() => process.exit(1), 5000).unref();
}, HARD_LIMIT_MS);
limit.unref();

let result = null;
let fatal = null;
try {
  result = await main();
} catch (e) {
  fatal = e;
  log('FATAL', e.stack || e.message);
} finally {
  await cleanup();
}
if (result) {
  console.log(`interactive bench: ${result.label} (${result.device})`);
  console.log(table(result));
  console.log(`BENCH_JSON ${JSON.stringify(result)}`);
}
process.exit(fatal ? 1 : 0);
