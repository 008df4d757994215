#!/usr/bin/env node
// End-to-end test of the browser client against a real refractd.
//
//   node tests/e2e/client.e2e.mjs PATH/TO/refractd PATH/TO/web-client
//
// Starts refractd on free loopback ports with a temporary data directory, drives Debian's Chromium
// (headless, through playwright-core; no browser download) and checks what a user would: the first
// frame and its progress line, moving the light, orbiting with the keyboard, an invalid value reported
// next to its control, an OBJ upload (fitted, or in its own units and framed), reload, example scenes
// from the daemon, export and import of the document, saving the frame, dispersion, volumes (built in and
// uploaded, where Add places them, and their emission), a narrow window and a daemon restart. Screenshots go to
// $REFRACT_E2E_OUT (default build/e2e-screenshots); $REFRACT_CHROMIUM overrides /usr/bin/chromium.
// Ends with "browser_e2e: N passed, M failed".

import { execFileSync } from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

import { freePort, killOnExit, loadChromium, sleep, startRefractd, stopRefractd, waitForHealth } from './refractd.mjs';

const chromium = await loadChromium(() => console.log('browser_e2e: 0 passed, 1 failed'));

const HERE = path.dirname(fileURLToPath(import.meta.url));
const REPO = path.resolve(HERE, '../..');
const [refractdArg, webRootArg] = process.argv.slice(2);
if (!refractdArg) {
  console.error('usage: node client.e2e.mjs PATH/TO/refractd [PATH/TO/web-client]');
  process.exit(2);
}
const REFRACTD = path.resolve(refractdArg);
const WEB_ROOT = path.resolve(webRootArg || path.join(REPO, 'web-client'));
const OUT = path.resolve(process.env.REFRACT_E2E_OUT || path.join(REPO, 'build/e2e-screenshots'));
const CHROMIUM = process.env.REFRACT_CHROMIUM || '/usr/bin/chromium';
const WAIT_MS = 60_000;
const MAX_PX = 320;  // the client's image cap for this test (?maxpx=): lavapipe on 2 cores
const SMALL_SCENE = { image: { width: 256, height: 256 }, volume: { resolution: 48 }, photons: { count: 16384 } };
const QUICK = { volume: { resolution: 48 }, photons: { count: 16384 } };  // what the test's examples render at

const tmp = fs.mkdtempSync(path.join(os.tmpdir(), 'refract-e2e-'));
const dataDir = path.join(tmp, 'data');
// The daemon serves copies of examples/*.json made cheap to render (--examples-dir).
const examplesDir = path.join(tmp, 'examples');
fs.mkdirSync(examplesDir);
for (const f of fs.readdirSync(path.join(REPO, 'examples')).filter((n) => n.endsWith('.json'))) {
  const doc = JSON.parse(fs.readFileSync(path.join(REPO, 'examples', f), 'utf8'));
  fs.writeFileSync(path.join(examplesDir, f), JSON.stringify({ ...doc, volume: { ...doc.volume, ...QUICK.volume }, photons: QUICK.photons }));
}
fs.mkdirSync(OUT, { recursive: true });
const daemonLogPath = path.join(OUT, 'refractd.log');
const daemonLog = fs.createWriteStream(daemonLogPath);

let daemon = null;
let browser = null;
let httpPort = 0;
let wsPort = 0;
let base = '';

// ---- helpers -------------------------------------------------------------------------------------

function log(...args) { console.log(`[e2e +${((Date.now() - t0) / 1000).toFixed(1)}s]`, ...args); }
const t0 = Date.now();

function startDaemon() {
  const args = ['--bind', '127.0.0.1', '--port', String(httpPort), '--ws-port', String(wsPort),
    '--data-dir', dataDir, '--web-root', WEB_ROOT, '--examples-dir', examplesDir];
  return startRefractd(REFRACTD, args, daemonLog, log);
}

async function api(method, urlPath, body, contentType = 'application/json') {
  const init = { method, headers: {} };
  if (body !== undefined) {
    init.body = typeof body === 'string' ? body : JSON.stringify(body);
    init.headers['Content-Type'] = contentType;
  }
  const res = await fetch(base + urlPath, init);
  const text = await res.text();
  let json = null;
  try { json = text ? JSON.parse(text) : null; } catch { json = { raw: text }; }
  return { status: res.status, json };
}

function assert(condition, message) {
  if (!condition) throw new Error(message);
}

const waitFor = (page, fn, arg, timeout = WAIT_MS) => page.waitForFunction(fn, arg, { timeout, polling: 100 });

// Waits until the client has nothing in flight, nothing queued, and shows a still of a revision > `after`.
function waitSettled(page, after = -1, timeout = WAIT_MS) {
  return waitFor(page, (rev) => window.refract && window.refract.settled() && window.refract.lastRevision > rev,
    after, timeout);
}

async function shot(page, name, opts = {}) {
  const file = path.join(OUT, name);
  await page.screenshot({ path: file, ...opts });
  screenshots.push(file);
  return file;
}

// Fraction of pixels of the canvas that differ (any channel by > 12) from the snapshot taken before.
const snapshotCanvas = (page) => page.evaluate(() => {
  const c = document.getElementById('view');
  window.__e2eSnapshot = { w: c.width, h: c.height, data: c.getContext('2d').getImageData(0, 0, c.width, c.height).data };
});
const canvasChange = (page) => page.evaluate(() => {
  const c = document.getElementById('view');
  const before = window.__e2eSnapshot;
  if (!before || before.w !== c.width || before.h !== c.height) return 1;
  const now = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
  let changed = 0;
  for (let i = 0; i < now.length; i += 4) {
    if (Math.abs(now[i] - before.data[i]) > 12 || Math.abs(now[i + 1] - before.data[i + 1]) > 12 ||
        Math.abs(now[i + 2] - before.data[i + 2]) > 12) changed++;
  }
  return changed / (now.length / 4);
});

// The scene as the daemon stores it, plus its one light and one object (when it has one) as `light` and
// `object`, as the older form names them.
async function sceneOnServer(id) {
  const r = await api('GET', `/api/scenes/${encodeURIComponent(id)}`);
  assert(r.status === 200, `GET /api/scenes/${id} -> ${r.status} ${JSON.stringify(r.json)}`);
  const only = (members) => (members && Object.keys(members).length === 1 ? Object.values(members)[0] : undefined);
  r.json.scene = { ...r.json.scene, light: only(r.json.scene.lights), object: only(r.json.scene.objects) };
  return r.json;
}

// Drags from the view's centre with `modifier` held: `steps` moves of (dx, dy) CSS pixels, 30 ms apart.
async function dragFromCentre(page, modifier, steps, dx, dy) {
  const box = await page.locator('#view').boundingBox();
  const cx = box.x + box.width / 2;
  const cy = box.y + box.height / 2;
  await page.mouse.move(cx, cy);
  await page.keyboard.down(modifier);
  await page.mouse.down();
  for (let i = 1; i <= steps; ++i) {
    await page.mouse.move(cx + i * dx, cy + i * dy);
    await sleep(30);
  }
  await page.mouse.up();
  await page.keyboard.up(modifier);
}

// Loads example scene `name` from the example picker and waits for its still frame.
async function applyExample(page, name) {
  const rev0 = await page.evaluate(() => window.refract.lastRevision);
  await page.selectOption('#ctl-example', name);
  await page.click('#example-load');
  await waitSettled(page, rev0);
}

// Clicks `selector` and returns the path of the file it downloads.
async function downloadFrom(page, selector) {
  const [download] = await Promise.all([page.waitForEvent('download'), page.click(selector)]);
  const file = path.join(tmp, download.suggestedFilename());
  await download.saveAs(file);
  return file;
}

// Where world point `p` falls in the frames of camera `cam` (a document's) at aspect `aspect` (width /
// height): normalised device coordinates (inside: |x|, |y| <= 1) and the depth in front of the camera.
function inFrame(cam, aspect, p) {
  const sub = (a, b) => a.map((x, i) => x - b[i]);
  const dot = (a, b) => a.reduce((t, x, i) => t + x * b[i], 0);
  const norm = (a) => a.map((x) => x / Math.hypot(...a));
  const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
  const fwd = norm(sub(cam.target, cam.position));
  const right = norm(cross(fwd, cam.up));
  const up = cross(right, fwd);
  const t = Math.tan((cam.fov_deg * Math.PI) / 360);
  const rel = sub(p, cam.position);
  const z = dot(rel, fwd);
  return { x: dot(rel, right) / (z * t * aspect), y: dot(rel, up) / (z * t), z };
}

// The eight corners of the box `lo`..`hi`.
const corners = (lo, hi) => [0, 1, 2, 3, 4, 5, 6, 7].map((k) => [0, 1, 2].map((i) => ((k >> i) & 1 ? hi[i] : lo[i])));

// The scene document without the image size (which follows the browser window).
const canonical = (v) => (Array.isArray(v) ? v.map(canonical) : v && typeof v === 'object'
  ? Object.fromEntries(Object.keys(v).sort().map((k) => [k, canonical(v[k])])) : v);
const sceneOnly = ({ light, object, ...doc }) => JSON.stringify(canonical({ ...doc, image: { ...doc.image, width: 0, height: 0 } }));

// ---- the checks ----------------------------------------------------------------------------------

const results = [];
const screenshots = [];
async function check(name, fn) {
  const start = Date.now();
  try {
    await fn();
    results.push({ name, ok: true });
    log(`PASS ${name} (${((Date.now() - start) / 1000).toFixed(1)} s)`);
  } catch (e) {
    results.push({ name, ok: false, error: e });
    log(`FAIL ${name}: ${e.stack || e.message}`);
  }
}

async function main() {
  httpPort = await freePort();
  do wsPort = await freePort(); while (wsPort === httpPort);
  base = `http://127.0.0.1:${httpPort}`;
  daemon = startDaemon();
  const health = await waitForHealth(base, daemon);
  log('refractd is up:', JSON.stringify(health.device));

  const created = await api('POST', '/api/scenes', SMALL_SCENE);
  assert(created.status === 201, `POST /api/scenes -> ${created.status} ${JSON.stringify(created.json)}`);
  const sceneId = created.json.id;
  log('scene', sceneId);

  browser = await chromium.launch({
    executablePath: CHROMIUM,
    args: ['--headless', '--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run',
      '--disable-background-networking', '--disable-component-update', '--disable-sync'],
  });
  const context = await browser.newContext({ viewport: { width: 1200, height: 760 } });
  const page = await context.newPage();
  const pageErrors = [];
  page.on('pageerror', (e) => { pageErrors.push(e.message); log('page error:', e.message); });
  page.on('console', (m) => { if (m.type() === 'error') log('console error:', m.text()); });
  const pageUrl = `${base}/?scene=${encodeURIComponent(sceneId)}&maxpx=${MAX_PX}`;

  await check('first frame drawn, device and timings shown', async () => {
    await page.goto(pageUrl);
    await waitSettled(page);
    const info = await page.evaluate(() => {
      const c = document.getElementById('view');
      const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
      let min = 255;
      let max = 0;
      for (let i = 0; i < d.length; i += 4) {
        const l = d[i] + d[i + 1] + d[i + 2];
        if (l < min) min = l;
        if (l > max) max = l;
      }
      const meta = window.refract.lastMeta;
      return {
        w: meta.width, h: meta.height, min, max, draw: window.refract.lastDraw,
        hud: document.getElementById('hud-status').textContent,
        summary: document.getElementById('frame-summary').textContent,
        device: document.getElementById('device-name').textContent,
        rows: document.querySelectorAll('#timings li').length,
        sceneId: window.refract.sceneId,
        conn: document.getElementById('conn').dataset.state,
      };
    });
    assert(info.max - info.min > 30, `canvas looks blank (luminance ${info.min}..${info.max})`);
    assert(Math.max(info.w, info.h) <= MAX_PX, `image ${info.w}x${info.h} exceeds the ${MAX_PX} cap`);
    assert(info.device && info.device !== '—' && info.device === info.device.trim(), `device name not shown: "${info.device}"`);
    assert(health.device === null || info.device.includes(health.device.name), `device "${info.device}" is not ${health.device?.name}`);
    assert(info.rows > 0, 'no per-pass timings shown');
    // The progress line says what it shows: a still, how long it took (not a "- fps" label) and how far
    // the daemon's refinement of it has come.
    assert(/^Still frame, \d+(\.\d)? (ms|s)( · refining \d+\/\d+| · refined \(level \d+\))?$/.test(info.hud),
      `progress line "${info.hud}"`);
    assert(info.summary.includes(`${info.w}×${info.h}`), `frame summary "${info.summary}" lacks the size`);
    // The canvas keeps its own (CSS) size; the frame is drawn into it with smooth filtering.
    assert(info.draw.smoothing === 'high', `frames drawn with smoothing ${info.draw.smoothing}`);
    assert(info.draw.frame[0] === info.w && info.draw.canvas[0] >= info.w, `draw ${JSON.stringify(info.draw)}`);
    assert(info.sceneId === sceneId, `client uses scene ${info.sceneId}, expected ${sceneId}`);
    assert(info.conn === 'live', `connection state ${info.conn}`);
    // The viewport keeps its size whatever the timings line shows: a frame that ran every pass lists
    // seven, and a line that wrapped resized the stage, which re-rendered the scene at a new image size.
    const stageHeights = await page.evaluate(() => {
      const list = document.getElementById('timings');
      const kept = list.innerHTML;
      const height = () => document.getElementById('stage').getBoundingClientRect().height;
      const before = height();
      list.innerHTML = ['voxelize', 'index_field', 'octree', 'photons', 'view', 'tone_map', 'encode']
        .map((name) => `<li class="pass pass-${name}">${name} 1234.5 ms</li>`).join('');
      const after = height();
      list.innerHTML = kept;
      return { before, after };
    });
    assert(stageHeights.after === stageHeights.before, `a long timings line resized the stage (${JSON.stringify(stageHeights)})`);
    await shot(page, '01-first-frame.png');
  });

  await check('the page fits the window and no tab stop scrolls it, at 1200x760 and at 1024x700', async () => {
    for (const [width, height] of [[1200, 760], [1024, 700]]) {
      await page.setViewportSize({ width, height });
      await waitSettled(page);
      const size = await page.evaluate(() => ({
        height: document.documentElement.scrollHeight, inner: window.innerHeight,
        width: document.documentElement.scrollWidth, innerWidth: window.innerWidth,
        // No blank band: the layout fills the window to its bottom.
        bottom: document.querySelector('main.layout').getBoundingClientRect().bottom,
      }));
      assert(size.height <= size.inner && size.width <= size.innerWidth,
        `at ${width}x${height} the page is ${size.width}x${size.height} px`);
      assert(size.bottom >= size.inner - 2, `at ${width}x${height} the layout ends at ${size.bottom} px, above the window's bottom`);
      await page.evaluate(() => { document.activeElement?.blur(); window.scrollTo(0, 0); window.tabbed = new Set(); });
      const reached = [];
      for (let i = 0; i < 300; ++i) {
        await page.keyboard.press('Tab');
        const at = await page.evaluate(() => {
          const el = document.activeElement;
          const again = window.tabbed.has(el);
          window.tabbed.add(el);
          return { x: window.scrollX, y: window.scrollY, id: el ? el.id || el.tagName : 'none', again };
        });
        assert(at.x === 0 && at.y === 0, `at ${width}x${height} tabbing onto ${at.id} scrolled the page to ${at.x},${at.y}`);
        if (at.again) break;  // around once
        reached.push(at.id);
      }
      assert(reached.includes('environment-file') && reached.includes('view-follow'),
        `at ${width}x${height} the tab order never reached the HDR/EXR upload or Follow the scene's camera: ${reached.join(' ')}`);
      await page.evaluate(() => document.activeElement?.blur());
      if (width === 1024) await shot(page, '01b-1024x700.png');
    }
    await page.setViewportSize({ width: 1200, height: 760 });
    await waitSettled(page);
  });

  await check('every number box is wide enough for its range (Photons: seven digits)', async () => {
    const clipped = await page.evaluate(() => {
      const ctx = document.createElement('canvas').getContext('2d');
      return [...document.querySelectorAll('input.num[data-widest]')].filter((input) => input.getClientRects().length)
        .map((input) => {
          const style = getComputedStyle(input);
          ctx.font = `${style.fontWeight} ${style.fontSize} ${style.fontFamily}`;
          // The text, the padding and Chromium's spin buttons (about 15 px) must fit the box.
          const need = ctx.measureText(input.dataset.widest).width + parseFloat(style.paddingLeft) + parseFloat(style.paddingRight) + 15;
          return { id: input.id, widest: input.dataset.widest, need: Math.ceil(need), has: input.clientWidth };
        }).filter((box) => box.need > box.has);
    });
    const photons = await page.evaluate(() => document.getElementById('ctl-photons-count-num').dataset.widest);
    assert(photons && photons.length >= 7, `the Photons box is sized for "${photons}"`);
    assert(clipped.length === 0, `number boxes too narrow: ${JSON.stringify(clipped)}`);
  });

  await check('the outliner adds a light, edits and renames it, and removes it', async () => {
    await waitSettled(page);
    const rev0 = await page.evaluate(() => window.refract.lastRevision);
    await snapshotCanvas(page);
    await page.click('#light-add');
    await waitSettled(page, rev0);
    let server = (await sceneOnServer(sceneId)).scene;
    const names = Object.keys(server.lights);
    assert(names.length === 2 && names.includes('light2'), `lights after Add: ${names}`);
    const lit = await canvasChange(page);
    assert(lit > 0.005, `a second light changed only ${(lit * 100).toFixed(2)}% of the pixels`);
    await shot(page, '02a-second-light.png');
    // The panel now edits the new light: its intensity slider writes /lights/light2/intensity.
    const picked = await page.evaluate(() => document.getElementById('ctl-light-member').value);
    assert(picked === 'light2', `the outliner shows ${picked}`);
    const rev1 = await page.evaluate(() => window.refract.lastRevision);
    await page.fill('#ctl-light-intensity-num', '30');
    await page.press('#ctl-light-intensity-num', 'Enter');
    await waitSettled(page, rev1);
    server = (await sceneOnServer(sceneId)).scene;
    assert(server.lights.light2.intensity === 30 && server.lights.light.intensity !== 30,
      `intensities ${server.lights.light.intensity} / ${server.lights.light2.intensity}`);
    // A bad name is refused at the control; a good one renames.
    await page.fill('#light-name', 'no spaces');
    await page.click('#light-rename');
    const refused = await page.evaluate(() => document.getElementById('ctl-light-member-error').textContent);
    assert(/name/.test(refused), `bad name message: "${refused}"`);
    const rev2 = await page.evaluate(() => window.refract.lastRevision);
    await page.fill('#light-name', 'fill');
    await page.click('#light-rename');
    await waitSettled(page, rev2);
    server = (await sceneOnServer(sceneId)).scene;
    assert(JSON.stringify(Object.keys(server.lights)) === '["fill","light"]' && server.lights.fill.intensity === 30,
      `lights after Rename: ${JSON.stringify(server.lights)}`);
    const rev3 = await page.evaluate(() => window.refract.lastRevision);
    await page.click('#light-remove');
    await waitSettled(page, rev3);
    server = (await sceneOnServer(sceneId)).scene;
    assert(JSON.stringify(Object.keys(server.lights)) === '["light"]', `lights after Remove: ${Object.keys(server.lights)}`);
    const removeDisabled = await page.evaluate(() => document.getElementById('light-remove').disabled);
    assert(removeDisabled, 'the last light can be removed');
    log(`Add changed ${(lit * 100).toFixed(1)}% of the pixels; renamed and removed`);
  });

  await check('alt-drag moves the object across the view, the camera stays', async () => {
    await waitSettled(page);
    const before = (await sceneOnServer(sceneId)).scene;
    const rev0 = await page.evaluate(() => window.refract.lastRevision);
    await snapshotCanvas(page);
    await dragFromCentre(page, 'Alt', 10, -8, 0);
    await waitSettled(page, rev0);
    const after = (await sceneOnServer(sceneId)).scene;
    const [p0, p1] = [before.object.position, after.object.position];
    const c = after.camera;
    const forward = [0, 1, 2].map((i) => c.target[i] - c.position[i]);
    const along = [0, 1, 2].reduce((sum, i) => sum + (p1[i] - p0[i]) * forward[i], 0) / Math.hypot(...forward);
    assert(JSON.stringify(after.camera) === JSON.stringify(before.camera), 'alt-drag moved the camera');
    assert(p1[0] < p0[0] - 0.05, `object x ${p0[0]} -> ${p1[0]}: not moved left`);
    assert(Math.abs(along) < 1e-3, `the object moved ${along} m along the view`);
    const changed = await canvasChange(page);
    assert(changed > 0.005, `only ${(changed * 100).toFixed(2)}% of the pixels changed`);
    // Put it back for the checks after this one.
    const rev1 = await page.evaluate(() => window.refract.lastRevision);
    const back = await api('PATCH', `/api/scenes/${sceneId}`, { object: { position: p0 } }, 'application/merge-patch+json');
    assert(back.status === 200, `PATCH back: ${back.status}`);
    await waitSettled(page, rev1);
    log(`object ${JSON.stringify(p0)} -> ${JSON.stringify(p1)}, ${(changed * 100).toFixed(1)}% pixels changed`);
  });

  await check('the outliner adds an object beside the chosen one; the panel and Alt+drag edit only it; rename, remove', async () => {
    await waitSettled(page);
    const before = (await sceneOnServer(sceneId)).scene;
    const rev0 = await page.evaluate(() => window.refract.lastRevision);
    await snapshotCanvas(page);
    await page.click('#object-add');
    await waitSettled(page, rev0);
    let server = (await sceneOnServer(sceneId)).scene;
    assert(JSON.stringify(Object.keys(server.objects).sort()) === '["object","object2"]', `objects after Add: ${Object.keys(server.objects)}`);
    const added = server.objects.object2;
    assert(added.mesh === 'sphere' && added.abbe === before.object.abbe && added.scale < before.object.scale,
      `the new object: ${JSON.stringify(added)}`);
    assert(added.position[0] > before.object.position[0] + before.object.scale, `not beside the first: ${added.position}`);
    assert(JSON.stringify(server.objects.object) === JSON.stringify(before.object), 'Add changed the first object');
    const seen = await canvasChange(page);
    assert(seen > 0.005, `a second object changed only ${(seen * 100).toFixed(2)}% of the pixels`);
    // The outliner lists both and has chosen the new one; the panel shows it.
    const outliner = () => page.evaluate(() => ({
      names: [...document.getElementById('ctl-object-member').options].map((o) => o.value),
      chosen: document.getElementById('ctl-object-member').value,
      name: document.getElementById('object-name').value,
      scale: document.getElementById('ctl-object-scale-num').value,
      removeDisabled: document.getElementById('object-remove').disabled,
      error: document.getElementById('ctl-object-member-error').textContent,
      errorShown: !document.getElementById('ctl-object-member-error').hidden,
    }));
    let ui = await outliner();
    assert(JSON.stringify(ui.names) === '["object","object2"]' && ui.chosen === 'object2' && ui.name === 'object2',
      `outliner ${JSON.stringify(ui)}`);
    assert(Number(ui.scale) === added.scale && !ui.removeDisabled, `panel ${JSON.stringify(ui)}`);
    await shot(page, '02b-two-objects.png');
    // The panel edits only the chosen object.
    const rev1 = await page.evaluate(() => window.refract.lastRevision);
    await page.fill('#ctl-object-ior-num', '1.9');
    await page.press('#ctl-object-ior-num', 'Enter');
    await waitSettled(page, rev1);
    server = (await sceneOnServer(sceneId)).scene;
    assert(server.objects.object2.ior === 1.9, `object2 ior ${server.objects.object2.ior}`);
    assert(JSON.stringify(server.objects.object) === JSON.stringify(before.object), 'the IOR edit changed the first object');
    // Alt+drag moves the chosen object, not the first.
    const rev2 = await page.evaluate(() => window.refract.lastRevision);
    await dragFromCentre(page, 'Alt', 6, 6, 0);
    await waitSettled(page, rev2);
    server = (await sceneOnServer(sceneId)).scene;
    assert(server.objects.object2.position[0] > added.position[0] + 0.02, `object2 ${added.position} -> ${server.objects.object2.position}`);
    assert(JSON.stringify(server.objects.object) === JSON.stringify(before.object), 'Alt+drag moved the first object');
    // Choosing the first object in the outliner makes the panel show it.
    await page.selectOption('#ctl-object-member', 'object');
    ui = await outliner();
    assert(ui.name === 'object' && Number(ui.scale) === before.object.scale, `after choosing "object": ${JSON.stringify(ui)}`);
    await page.selectOption('#ctl-object-member', 'object2');
    // Refused renames (a bad name, a name taken) say why at the outliner and send nothing.
    const revBefore = (await sceneOnServer(sceneId)).revision;
    for (const [bad, why] of [['no spaces', /not a name/], ['object', /already an object named “object”/], ['..', /not a name/]]) {
      await page.fill('#object-name', bad);
      await page.click('#object-rename');
      ui = await outliner();
      assert(ui.errorShown && why.test(ui.error), `renaming to "${bad}": ${JSON.stringify(ui)}`);
      const invalid = await page.evaluate(() => document.getElementById('object-name').getAttribute('aria-invalid'));
      assert(invalid === 'true', `the name box is not marked invalid for "${bad}"`);
    }
    await sleep(300);
    const unchanged = await sceneOnServer(sceneId);
    assert(unchanged.revision === revBefore && JSON.stringify(Object.keys(unchanged.scene.objects).sort()) === '["object","object2"]',
      `a refused rename changed the scene (revision ${revBefore} -> ${unchanged.revision})`);
    ui = await outliner();
    assert(JSON.stringify(ui.names) === '["object","object2"]' && ui.chosen === 'object2', `outliner after refusals ${JSON.stringify(ui)}`);
    // A good name renames: one patch, the object's fields kept, still chosen.
    const rev3 = await page.evaluate(() => window.refract.lastRevision);
    await page.fill('#object-name', 'glass.small');
    await page.click('#object-rename');
    await waitSettled(page, rev3);
    server = (await sceneOnServer(sceneId)).scene;
    assert(JSON.stringify(Object.keys(server.objects).sort()) === '["glass.small","object"]' && server.objects['glass.small'].ior === 1.9,
      `objects after Rename: ${JSON.stringify(server.objects)}`);
    ui = await outliner();
    assert(ui.chosen === 'glass.small' && !ui.errorShown, `outliner after Rename ${JSON.stringify(ui)}`);
    await shot(page, '02c-renamed-object.png');
    // The Abbe number is one per scene: the panel writes it to every object, and back.
    for (const abbe of [40, before.object.abbe]) {
      const rev = await page.evaluate(() => window.refract.lastRevision);
      await page.fill('#ctl-object-abbe-num', String(abbe));
      await page.press('#ctl-object-abbe-num', 'Enter');
      await waitSettled(page, rev);
      server = (await sceneOnServer(sceneId)).scene;
      assert(Object.values(server.objects).every((o) => o.abbe === abbe), `Abbe numbers ${Object.values(server.objects).map((o) => o.abbe)}`);
    }
    // Remove takes the chosen one away; the last cannot be removed.
    const rev4 = await page.evaluate(() => window.refract.lastRevision);
    await page.click('#object-remove');
    await waitSettled(page, rev4);
    server = (await sceneOnServer(sceneId)).scene;
    assert(JSON.stringify(server.objects) === JSON.stringify({ object: before.object }), `objects after Remove: ${JSON.stringify(server.objects)}`);
    ui = await outliner();
    assert(JSON.stringify(ui.names) === '["object"]' && ui.chosen === 'object' && ui.removeDisabled, `outliner after Remove ${JSON.stringify(ui)}`);
    log(`Add changed ${(seen * 100).toFixed(1)}% of the pixels at ${JSON.stringify(added.position)}; edited, moved, renamed, removed`);
  });

  await check('a daemon refusal of Add (a grid object stands alone) shows at the outliner and changes nothing', async () => {
    await waitSettled(page);
    const rev0 = await page.evaluate(() => window.refract.lastRevision);
    // Another client imports an index grid: the object's index field becomes "grid".
    const values = Buffer.from(new Float32Array(8).fill(1.3).buffer);
    const put = await fetch(`${base}/api/scenes/${sceneId}/index-field?nx=2&ny=2&nz=2&min=-1,-1,-1&max=1,1,1`,
      { method: 'PUT', body: values, headers: { 'Content-Type': 'application/octet-stream' } });
    assert(put.ok, `PUT index-field: ${put.status} ${await put.text()}`);
    await waitFor(page, (rev) => window.refract.lastRevision > rev && window.refract.doc().objects.object.index_field === 'grid', rev0);
    await waitSettled(page, rev0);
    const before = await sceneOnServer(sceneId);
    const errors0 = await page.evaluate(() => window.refract.errors);
    await page.click('#object-add');
    await waitFor(page, (n) => window.refract.errors > n && !window.refract.busy(), errors0);
    const ui = await page.evaluate(() => ({
      names: [...document.getElementById('ctl-object-member').options].map((o) => o.value),
      chosen: document.getElementById('ctl-object-member').value,
      error: document.getElementById('ctl-object-member-error').textContent,
      lastError: window.refract.lastError,
      doc: window.refract.doc(),
    }));
    assert(/refused/.test(ui.error) && /\/objects\/object\/index_field/.test(ui.error) && /only object/.test(ui.error), `outliner error "${ui.error}"`);
    assert(JSON.stringify(ui.names) === '["object"]' && ui.chosen === 'object', `outliner ${JSON.stringify(ui)}`);
    assert(JSON.stringify(Object.keys(ui.doc.objects)) === '["object"]', `the client's document: ${Object.keys(ui.doc.objects)}`);
    await sleep(300);
    const after = await sceneOnServer(sceneId);
    assert(after.revision === before.revision && JSON.stringify(after.scene.objects) === JSON.stringify(before.scene.objects),
      `the scene changed: revision ${before.revision} -> ${after.revision}`);
    await shot(page, '02d-refused-add.png');
    // Back to a uniform glass sphere for the checks after this one.
    const rev1 = await page.evaluate(() => window.refract.lastRevision);
    const back = await api('PATCH', `/api/scenes/${sceneId}`, { objects: { object: { index_field: 'uniform', grid: '' } } },
      'application/merge-patch+json');
    assert(back.status === 200, `PATCH back: ${back.status} ${JSON.stringify(back.json)}`);
    await waitSettled(page, rev1);
    log(`refused: ${ui.error}`);
  });

  await check('shift-drag moves the light: new revision, different pixels', async () => {
    await waitSettled(page);
    const before = await sceneOnServer(sceneId);
    const rev0 = await page.evaluate(() => window.refract.lastRevision);
    await snapshotCanvas(page);
    await dragFromCentre(page, 'Shift', 12, -14, 4);
    await waitSettled(page, rev0);
    const after = await sceneOnServer(sceneId);
    const changed = await canvasChange(page);
    const stats = await page.evaluate(() => ({ rev: window.refract.lastRevision, maxInFlight: window.refract.maxInFlight }));
    assert(stats.rev > rev0, `revision did not advance (${rev0} -> ${stats.rev})`);
    assert(after.revision === stats.rev, `client shows revision ${stats.rev}, server has ${after.revision}`);
    assert(JSON.stringify(after.scene.light.position) !== JSON.stringify(before.scene.light.position),
      'light position unchanged on the server');
    assert(JSON.stringify(after.scene.camera) === JSON.stringify(before.scene.camera), 'shift-drag moved the camera');
    assert(changed > 0.005, `only ${(changed * 100).toFixed(2)}% of the pixels changed`);
    // One request in flight, or two while a preview renders (the next edit waits at the daemon), and
    // the release's still frame behind them.
    assert(stats.maxInFlight <= 3, `${stats.maxInFlight} requests were in flight at once`);
    log(`light ${JSON.stringify(before.scene.light.position)} -> ${JSON.stringify(after.scene.light.position)},`,
      `${(changed * 100).toFixed(1)}% pixels changed`);
    await shot(page, '02-light-moved.png');
  });

  await check('the light marker is never under the progress line', async () => {
    await waitSettled(page);
    const before = (await sceneOnServer(sceneId)).scene;
    const cam = (await page.evaluate(() => window.refract.view())).camera;
    // A light just above the top of the view, mid-image: its marker is pinned to the top edge, where the
    // progress line is.
    const sub = (a, b) => a.map((x, i) => x - b[i]);
    const unit = (a) => a.map((x) => x / Math.hypot(...a));
    const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
    const forward = unit(sub(cam.target, cam.position));
    const up = cross(unit(cross(forward, cam.up)), forward);
    const lift = Math.hypot(...sub(cam.target, cam.position)) * Math.tan((cam.fov_deg * Math.PI) / 360) * 1.3;
    const high = cam.target.map((x, i) => Number((x + up[i] * lift).toFixed(4)));
    const rev0 = await page.evaluate(() => window.refract.lastRevision);
    const moved = await api('PATCH', `/api/scenes/${sceneId}`, { light: { position: high, direction: [0, -1, 0] } }, 'application/merge-patch+json');
    assert(moved.status === 200, `PATCH light: ${moved.status}`);
    await waitSettled(page, rev0);
    const geo = await page.evaluate(() => {
      const rect = (id) => document.getElementById(id).getBoundingClientRect().toJSON();
      return { hidden: document.getElementById('light-marker').hidden, marker: rect('light-marker'), hud: rect('hud-status'), stage: rect('stage') };
    });
    await shot(page, '02e-light-marker-at-the-top.png');
    const { marker: m, hud: h, stage: st } = geo;
    assert(!geo.hidden, 'the light marker is hidden');
    const cx = m.x + m.width / 2;
    const cy = m.y + m.height / 2;
    assert(!(m.right > h.left && m.left < h.right && m.bottom > h.top && m.top < h.bottom),
      `the light marker ${JSON.stringify(m)} is under the progress line ${JSON.stringify(h)}`);
    assert(cx > st.left && cx < st.right && cy > st.top && cy < st.bottom, `the marker is off the view: ${JSON.stringify(geo)}`);
    assert(cy < st.top + st.height / 3, `the marker is not at the top: ${JSON.stringify(geo)}`);
    const rev1 = await page.evaluate(() => window.refract.lastRevision);
    const back = await api('PATCH', `/api/scenes/${sceneId}`, { lights: { light: before.light } }, 'application/merge-patch+json');
    assert(back.status === 200, `PATCH back: ${back.status}`);
    await waitSettled(page, rev1);
  });

  await check('arrow keys on the focused canvas orbit this viewer\'s own camera; the scene keeps its own', async () => {
    const before = await sceneOnServer(sceneId);
    const rev0 = await page.evaluate(() => window.refract.lastRevision);
    const frames0 = await page.evaluate(() => window.refract.framesReceived);
    const view0 = await page.evaluate(() => window.refract.view());
    await page.focus('#view');
    for (let i = 0; i < 4; ++i) await page.keyboard.press('ArrowLeft');
    await page.keyboard.press('ArrowUp');
    await waitFor(page, (n) => window.refract.framesReceived > n, frames0);
    await waitSettled(page);
    const view1 = await page.evaluate(() => window.refract.view());
    const after = await sceneOnServer(sceneId);
    assert(after.revision === before.revision && JSON.stringify(after.scene.camera) === JSON.stringify(before.scene.camera),
      `orbiting changed the scene: revision ${before.revision} -> ${after.revision}`);
    assert(await page.evaluate(() => window.refract.lastRevision) === rev0, 'orbiting made a revision');
    const focus = await page.evaluate(() => ({
      id: document.activeElement?.id,
      ring: getComputedStyle(document.getElementById('stage')).boxShadow,
    }));
    assert(focus.id === 'view', `focus is on #${focus.id}, not the canvas`);
    assert(focus.ring && focus.ring !== 'none', 'no visible focus ring around the focused canvas');
    const [a, b] = [view0.camera, view1.camera];
    assert(a && b && JSON.stringify(a.position) !== JSON.stringify(b.position), `the view's camera did not move: ${JSON.stringify([a, b])}`);
    const dist = (c) => Math.hypot(...c.position.map((x, i) => x - c.target[i]));
    assert(Math.abs(dist(a) - dist(b)) < 1e-2, `orbit changed the distance (${dist(a)} -> ${dist(b)})`);
    await shot(page, '03-keyboard-orbit.png');
  });

  await check('two viewers of different sizes orbit their own cameras (no letterbox, no revision); each sees the other; presenter mode; save the view', async () => {
    await waitSettled(page);
    const second = await browser.newContext({ viewport: { width: 1024, height: 700 } });
    const page2 = await second.newPage();
    page2.on('pageerror', (e) => { pageErrors.push(e.message); log('page error (second viewer):', e.message); });
    const orbitWith = async (p, key, times) => {
      const frames = await p.evaluate(() => window.refract.framesReceived);
      await p.focus('#view');
      for (let i = 0; i < times; ++i) await p.keyboard.press(key);
      await waitFor(p, (n) => window.refract.framesReceived > n, frames);
      await waitSettled(p);
    };
    const unboxed = async (p, who) => {
      const d = await p.evaluate(() => window.refract.lastDraw);
      assert(Math.abs(d.drawn[0] - d.canvas[0]) <= 2 && Math.abs(d.drawn[1] - d.canvas[1]) <= 2,
        `${who}'s frame is letterboxed: ${JSON.stringify(d)}`);
    };
    try {
      const before = await sceneOnServer(sceneId);
      await page2.goto(pageUrl);
      await waitSettled(page2);
      await waitFor(page, () => window.refract.viewers() === 2);
      await waitFor(page2, () => window.refract.viewers() === 2);
      const badge = await page.evaluate(() => document.getElementById('viewers').textContent);
      assert(badge === '2 viewers', `the header says "${badge}"`);
      await orbitWith(page2, 'ArrowRight', 3);
      await orbitWith(page, 'ArrowLeft', 3);
      const views = await Promise.all([page, page2].map((p) => p.evaluate(() => window.refract.view())));
      assert(views[0].width !== views[1].width || views[0].height !== views[1].height, `one size: ${JSON.stringify(views)}`);
      assert(JSON.stringify(views[0].camera) !== JSON.stringify(views[1].camera), 'the two viewers share a camera');
      for (const v of views) assert(JSON.stringify(v.camera.position) !== JSON.stringify(before.scene.camera.position), 'a view did not move');
      await unboxed(page, 'the first viewer');
      await unboxed(page2, 'the second viewer');
      const meta2 = await page2.evaluate(() => window.refract.lastMeta);
      assert(meta2.width === views[1].width && meta2.height === views[1].height, `the second viewer got ${meta2.width}x${meta2.height}`);
      let now = await sceneOnServer(sceneId);
      assert(now.revision === before.revision && JSON.stringify(now.scene.camera) === JSON.stringify(before.scene.camera) &&
        JSON.stringify(now.scene.image) === JSON.stringify(before.scene.image), `views reached the scene: r${before.revision} -> r${now.revision}`);
      await shot(page, '10a-first-viewer.png');
      await shot(page2, '10b-second-viewer.png');

      // Presenter mode: both follow the scene's camera; the first one's orbit moves it for the second.
      await page2.click('#view-follow');
      await waitSettled(page2);
      await page.click('#view-follow');
      await waitSettled(page);
      const edits0 = await page2.evaluate(() => window.refract.otherEdits);
      await snapshotCanvas(page2);
      await page.focus('#view');
      for (let i = 0; i < 3; ++i) await page.keyboard.press('ArrowRight');
      await waitFor(page2, (rev) => window.refract.lastRevision > rev, before.revision);
      await waitFor(page2, (n) => window.refract.otherEdits > n, edits0);
      const hud = await page2.evaluate(() => document.getElementById('hud-status').textContent);
      await shot(page2, '10c-follower-sees-the-presenter.png');
      await waitSettled(page);
      await waitSettled(page2, before.revision);
      now = await sceneOnServer(sceneId);
      assert(now.revision > before.revision && JSON.stringify(now.scene.camera) !== JSON.stringify(before.scene.camera),
        'the presenter\'s orbit did not move the scene\'s camera');
      assert(await page2.evaluate(() => window.refract.view().camera === null), 'the follower sends a camera of its own');
      assert(await canvasChange(page2) > 0.005, 'the follower\'s frame did not change');
      assert(/edit made elsewhere|Another viewer edited/.test(hud) && !/^Preview frame/.test(hud), `the follower's line said "${hud}"`);
      log(`the follower's line said: ${hud}`);

      // Back to a camera of its own, orbited, then saved: it becomes the scene's camera.
      await page2.click('#view-follow');
      await orbitWith(page2, 'ArrowUp', 2);
      const own = (await page2.evaluate(() => window.refract.view())).camera;
      const rev = now.revision;
      await page2.click('#view-save');
      await waitSettled(page2, rev);
      now = await sceneOnServer(sceneId);
      assert(JSON.stringify(now.scene.camera.position) === JSON.stringify(own.position), `saved ${JSON.stringify(now.scene.camera)}, own ${JSON.stringify(own)}`);
      // The panel says so, and there is nothing more to save until the view moves.
      const savedUi = await page2.evaluate(() => ({
        note: document.getElementById('view-note').textContent, disabled: document.getElementById('view-save').disabled,
      }));
      assert(/saved view/.test(savedUi.note) && savedUi.disabled, `after saving: ${JSON.stringify(savedUi)}`);
      await page.click('#view-follow');
      await waitSettled(page);
    } finally {
      await second.close();
    }
    await waitFor(page, () => window.refract.viewers() === 1);
  });

  await check('an invalid IOR is reported next to its control', async () => {
    const before = await sceneOnServer(sceneId);
    const errors0 = await page.evaluate(() => window.refract.errors);
    await page.fill('#ctl-object-ior-num', '0.5');
    await page.press('#ctl-object-ior-num', 'Enter');
    await waitFor(page, (n) => window.refract.errors > n, errors0);
    const err = await page.evaluate(() => window.refract.lastError);
    assert(err.pointer === '/object/ior', `error pointer ${err.pointer}, expected /object/ior`);
    const ui = await page.evaluate(() => {
      const input = document.getElementById('ctl-object-ior-num');
      const field = input.closest('.field');
      const msg = field.querySelector('.field-error');
      const described = (input.getAttribute('aria-describedby') || '').split(' ');
      const r = msg.getBoundingClientRect();
      return {
        invalid: input.getAttribute('aria-invalid'), text: msg.textContent, visible: !msg.hidden && r.height > 0,
        linked: described.includes(msg.id), otherErrors: document.querySelectorAll('.field-error:not([hidden])').length,
        title: msg.title, number: input.value, slider: document.getElementById('ctl-object-ior').value,
      };
    });
    assert(ui.invalid === 'true', 'IOR input is not aria-invalid');
    assert(ui.visible && ui.text.length > 0, 'no inline error message next to the IOR control');
    // In words, with the pointer in its tooltip; the control back at the scene's value.
    assert(ui.text === 'IOR must be between 1 and 4', `the error reads "${ui.text}"`);
    assert(/\/object\/ior/.test(ui.title), `the error's tooltip is "${ui.title}"`);
    assert(Number(ui.number) === before.scene.object.ior && Number(ui.slider) === before.scene.object.ior,
      `after the refusal the controls show ${ui.number} / ${ui.slider}, the scene has ${before.scene.object.ior}`);
    assert(ui.linked, 'the error message is not linked with aria-describedby');
    assert(ui.otherErrors === 1, `${ui.otherErrors} error messages are shown`);
    const after = await sceneOnServer(sceneId);
    assert(after.scene.object.ior === before.scene.object.ior, 'the invalid IOR reached the scene');
    log('error shown:', ui.text);
    await shot(page, '04-validation-error.png');

    // Fixing the value clears the message and applies it.
    const rev0 = await page.evaluate(() => window.refract.lastRevision);
    await page.fill('#ctl-object-ior-num', '1.6');
    await page.press('#ctl-object-ior-num', 'Enter');
    await waitSettled(page, rev0);
    const fixed = await sceneOnServer(sceneId);
    assert(fixed.scene.object.ior === 1.6, `IOR is ${fixed.scene.object.ior}, expected 1.6`);
    const cleared = await page.evaluate(() => !document.getElementById('ctl-object-ior-num').hasAttribute('aria-invalid'));
    assert(cleared, 'the error stayed after a valid value');
  });

  await check('an uploaded OBJ becomes the object mesh', async () => {
    const objPath = path.join(tmp, 'e2e-cube.obj');
    fs.writeFileSync(objPath, [
      '# unit cube, outward-facing triangles',
      'v -0.5 -0.5 -0.5', 'v 0.5 -0.5 -0.5', 'v 0.5 0.5 -0.5', 'v -0.5 0.5 -0.5',
      'v -0.5 -0.5 0.5', 'v 0.5 -0.5 0.5', 'v 0.5 0.5 0.5', 'v -0.5 0.5 0.5',
      'f 1 3 2', 'f 1 4 3', 'f 5 6 7', 'f 5 7 8', 'f 1 2 6', 'f 1 6 5',
      'f 4 7 3', 'f 4 8 7', 'f 1 5 8', 'f 1 8 4', 'f 2 3 7', 'f 2 7 6', '',
    ].join('\n'));
    const rev0 = await page.evaluate(() => window.refract.lastRevision);
    await page.setInputFiles('#mesh-file', objPath);
    await waitFor(page, () => window.refract.meshUploads > 0 || (window.refract.lastError?.pointer === '/object/mesh'));
    const upload = await page.evaluate(() => ({ up: window.refract.lastUpload, err: window.refract.lastError }));
    assert(upload.up, `upload failed: ${JSON.stringify(upload.err)}`);
    await waitSettled(page, rev0);
    const after = await sceneOnServer(sceneId);
    assert(after.scene.object.mesh === 'upload:e2e-cube', `object.mesh is ${after.scene.object.mesh}`);
    const ui = await page.evaluate(() => ({
      select: document.getElementById('ctl-object-mesh').value,
      status: document.getElementById('mesh-status').textContent,
      rev: window.refract.lastRevision,
    }));
    assert(ui.select === 'upload:e2e-cube', `mesh picker shows ${ui.select}`);
    assert(/12 triangles/.test(ui.status), `upload status "${ui.status}" lacks the triangle count`);
    assert(ui.rev === after.revision, `shown revision ${ui.rev} != server ${after.revision}`);
    const meshes = await api('GET', '/api/meshes');
    assert(JSON.stringify(meshes.json).includes('e2e-cube'), 'GET /api/meshes does not list e2e-cube');
    await shot(page, '05-obj-uploaded.png');
  });

  await check('dragging a slider streams interactive frames, then a still', async () => {
    await waitSettled(page);
    const before = await page.evaluate(() => ({ rev: window.refract.lastRevision, sent: { ...window.refract.sent } }));
    await page.locator('#ctl-light-intensity').scrollIntoViewIfNeeded();
    const box = await page.locator('#ctl-light-intensity').boundingBox();
    const y = box.y + box.height / 2;
    await page.mouse.move(box.x + box.width * 0.1, y);
    await page.mouse.down();
    for (let i = 1; i <= 10; ++i) {
      await page.mouse.move(box.x + box.width * (0.1 + i * 0.05), y);
      await sleep(40);
      if (i === 8) await shot(page, '05c-dragging-slider.png');  // previews streaming: fps in the progress line
    }
    // What the progress line says from the release on: while the still is on its way, that (never
    // "Rendering a preview" because a preview asked for before it is still unanswered).
    const watching = page.evaluate(() => new Promise((resolve) => {
      const seen = [];
      const end = performance.now() + 2000;
      const look = () => {
        const asked = window.refract.inflight();
        seen.push({ asked, text: document.getElementById('hud-status').textContent });
        if (performance.now() < end) requestAnimationFrame(look); else resolve(seen);
      };
      look();
    }));
    await page.mouse.up();
    const lines = await watching;
    const wrong = lines.filter((l) => l.asked.length && l.asked[l.asked.length - 1] === 'still' && !/^Rendering the still frame/.test(l.text));
    assert(lines.some((l) => /^Rendering the still frame/.test(l.text)), `the line never said the still was rendering: ${JSON.stringify(lines.slice(-3))}`);
    assert(wrong.length === 0, `while the still rendered the line said "${wrong[0]?.text}"`);
    await waitSettled(page, before.rev);
    const after = await page.evaluate(() => ({
      sent: { ...window.refract.sent }, quality: window.refract.lastQuality,
      shown: Number(document.getElementById('ctl-light-intensity-num').value),
    }));
    const server = await sceneOnServer(sceneId);
    assert(after.sent.interactive > before.sent.interactive, 'no interactive request while dragging');
    assert(after.sent.still > before.sent.still, 'no still request after releasing');
    assert(after.quality === 'still', `last frame is ${after.quality}`);
    // Interactive frames come at half the side and are scaled up smoothly to the canvas, not pixelated.
    const draw = await page.evaluate(() => window.refract.lastInteractiveDraw);
    assert(draw && draw.frame[0] < draw.drawn[0] && draw.smoothing === 'high',
      `interactive frame drawn as ${JSON.stringify(draw)}`);
    assert(Math.abs(server.scene.light.intensity - after.shown) < 1e-6,
      `server intensity ${server.scene.light.intensity} != shown ${after.shown}`);
    log(`sent ${after.sent.interactive - before.sent.interactive} interactive +`,
      `${after.sent.still - before.sent.still} still; intensity now ${server.scene.light.intensity}`);
  });

  await check('the bounces control sets photons.max_bounces; out of range, its error shows there', async () => {
    const box = '#ctl-photons-max-bounces-num';
    await waitSettled(page);
    const before = await page.evaluate(() => window.refract.lastRevision);
    await page.fill(box, '2');
    await page.press(box, 'Enter');
    await waitSettled(page, before);
    assert((await sceneOnServer(sceneId)).scene.photons.max_bounces === 2, 'max_bounces not 2 on the server');
    const errors0 = await page.evaluate(() => window.refract.errors);
    await page.fill(box, '2000');
    await page.press(box, 'Enter');
    await waitFor(page, (n) => window.refract.errors > n, errors0);
    const err = await page.evaluate(() => window.refract.lastError);
    assert(err.pointer === '/photons/max_bounces', `pointer ${err.pointer}`);
    assert(await page.evaluate((b) => document.querySelector(b).getAttribute('aria-invalid') === 'true', box),
      'bounces error not shown at the bounces control');
    assert((await sceneOnServer(sceneId)).scene.photons.max_bounces === 2, 'a refused edit changed the scene');
    await page.fill(box, '0');
    await page.press(box, 'Enter');
    await waitFor(page, (b) => !document.querySelector(b).hasAttribute('aria-invalid'), box);
  });

  await check('linked-value and upload errors land next to their controls', async () => {
    // scattering above extinction: the daemon names /object/scattering/0, shown at the scattering control.
    const errors0 = await page.evaluate(() => window.refract.errors);
    await page.fill('#ctl-object-scattering-r', '5');
    await page.press('#ctl-object-scattering-r', 'Enter');
    await waitFor(page, (n) => window.refract.errors > n, errors0);
    const err = await page.evaluate(() => window.refract.lastError);
    assert(/^\/object\/scattering/.test(err.pointer || ''), `pointer ${err.pointer}`);
    const shown = await page.evaluate(() => {
      const input = document.getElementById('ctl-object-scattering-r');
      const msg = input.closest('.field').querySelector('.field-error');
      return { invalid: input.getAttribute('aria-invalid'), text: msg.hidden ? '' : msg.textContent };
    });
    assert(shown.invalid === 'true' && shown.text, 'scattering error not shown at the scattering control');
    await page.fill('#ctl-object-scattering-r', '0');
    await page.press('#ctl-object-scattering-r', 'Enter');
    await waitFor(page, () => !document.getElementById('ctl-object-scattering-r').hasAttribute('aria-invalid'));

    // An OBJ that is not one: the daemon's 400 is shown under the mesh picker; the mesh stays.
    const broken = path.join(tmp, 'broken.obj');
    fs.writeFileSync(broken, 'this is not a mesh\nf 1 2 3\n');
    const errors1 = await page.evaluate(() => window.refract.errors);
    await page.setInputFiles('#mesh-file', broken);
    await waitFor(page, (n) => window.refract.errors > n, errors1);
    const ui = await page.evaluate(() => {
      const select = document.getElementById('ctl-object-mesh');
      const msg = select.closest('.field').querySelector('.field-error');
      return { invalid: select.getAttribute('aria-invalid'), text: msg.hidden ? '' : msg.textContent, value: select.value };
    });
    assert(ui.invalid === 'true' && /broken\.obj/.test(ui.text), `upload error not shown: ${JSON.stringify(ui)}`);
    assert(ui.value === 'upload:e2e-cube', `mesh picker changed to ${ui.value}`);
    log('upload error shown:', ui.text);
    await shot(page, '05b-upload-error.png');
    const server = await sceneOnServer(sceneId);
    assert(server.scene.object.mesh === 'upload:e2e-cube', 'a failed upload changed the mesh');
    assert(JSON.stringify(server.scene.object.scattering) === '[0,0.02,0.02]',
      `scattering is ${JSON.stringify(server.scene.object.scattering)}`);
    // The next accepted edit clears the stale upload message.
    const rev0 = await page.evaluate(() => window.refract.lastRevision);
    await page.fill('#ctl-light-intensity-num', '31.5');
    await page.press('#ctl-light-intensity-num', 'Enter');
    await waitSettled(page, rev0);
    const stale = await page.evaluate(() => document.getElementById('ctl-object-mesh').hasAttribute('aria-invalid'));
    assert(!stale, 'the upload error stayed after a successful edit');
  });

  await check('reload shows the same scene id and revision', async () => {
    await waitSettled(page);
    const before = await page.evaluate(() => ({ id: window.refract.sceneId, rev: window.refract.lastRevision }));
    const server0 = await sceneOnServer(sceneId);
    await page.reload();
    await waitFor(page, () => window.refract && window.refract.framesReceived > 0);
    await waitSettled(page);
    const after = await page.evaluate(() => ({
      id: window.refract.sceneId, rev: window.refract.lastRevision, url: location.href,
      mesh: document.getElementById('ctl-object-mesh').value,
      ior: document.getElementById('ctl-object-ior-num').value,
    }));
    const server1 = await sceneOnServer(sceneId);
    assert(after.id === before.id, `scene id ${before.id} -> ${after.id}`);
    assert(new URL(after.url).searchParams.get('scene') === before.id, `URL ${after.url} lost the scene id`);
    assert(after.rev === before.rev, `revision ${before.rev} -> ${after.rev} after reload`);
    assert(server1.revision === server0.revision, 'reload edited the scene');
    assert(after.mesh === 'upload:e2e-cube', `controls show mesh ${after.mesh} after reload`);
    assert(Number(after.ior) === 1.6, `controls show IOR ${after.ior} after reload`);
    await shot(page, '06-after-reload.png');
  });

  await check('without uploads, Add places a built-in volume; the flame glows by its temperature, each edit valid', async () => {
    await waitSettled(page);
    assert(!(await api('GET', '/api/volumes')).json.volumes.length, 'this check wants a daemon without volume uploads');
    const offered = await page.evaluate(() => [...document.getElementById('ctl-medium-volume-asset').options]
      .map((o) => `${o.value}=${o.textContent}`));
    assert(offered.includes('builtin.flame=Flame (built-in)'), `the volume picker offers ${offered}`);
    const errors0 = await page.evaluate(() => window.refract.errors);
    // One edit of the panel, and the scene as the daemon has it once its still is drawn.
    const step = async (action) => {
      const rev = await page.evaluate(() => window.refract.lastRevision);
      await action();
      await waitSettled(page, rev);
      return (await sceneOnServer(sceneId)).scene.volumes || {};
    };
    let volumes = await step(() => page.click('#medium_volume-add'));
    const [name] = Object.keys(volumes);
    assert(volumes[name]?.asset.startsWith('builtin.'), `volumes ${JSON.stringify(volumes)}`);
    volumes = await step(() => page.selectOption('#ctl-medium-volume-asset', 'builtin.flame'));
    const grids = await page.evaluate(() => [...document.getElementById('ctl-medium-volume-grid').options].map((o) => o.value));
    assert(volumes[name].asset === 'builtin.flame' && grids.join() === 'density,temperature', `grids ${grids}`);
    await snapshotCanvas(page);
    // A temperature grid names it and clears the plain one in one edit; then brighter.
    await step(() => page.selectOption('#ctl-medium-volume-emitter', 'k:temperature'));
    volumes = await step(async () => {
      await page.fill('#ctl-medium-volume-emission-intensity-num', '6');
      await page.press('#ctl-medium-volume-emission-intensity-num', 'Enter');
    });
    let emission = volumes[name].emission;
    assert(emission.temperature_grid === 'temperature' && emission.grid === '' && emission.intensity === 6,
      `emission ${JSON.stringify(emission)}`);
    const glow = await canvasChange(page);
    log(`the flame's glow changed ${(glow * 100).toFixed(1)}% of the pixels`);
    assert(glow > 0.005, `the frame hardly changed (${glow})`);
    await page.locator('#ctl-medium-volume-emitter').scrollIntoViewIfNeeded();
    await shot(page, '06e-volume-emission.png');
    // None turns it off; intensity raised with no grid named takes the temperature grid by itself.
    await step(() => page.selectOption('#ctl-medium-volume-emitter', ''));
    volumes = await step(async () => {
      await page.fill('#ctl-medium-volume-emission-intensity-num', '2');
      await page.press('#ctl-medium-volume-emission-intensity-num', 'Enter');
    });
    emission = volumes[name].emission;
    assert(emission.temperature_grid === 'temperature' && emission.intensity === 2, `emission ${JSON.stringify(emission)}`);
    // The cloud has no temperature grid: its density glows instead, in the colour shown for it.
    volumes = await step(() => page.selectOption('#ctl-medium-volume-asset', 'builtin.cloud'));
    emission = volumes[name].emission;
    assert(emission.grid === 'density' && emission.temperature_grid === '', `emission ${JSON.stringify(emission)}`);
    assert(!(await page.evaluate(() => document.getElementById('ctl-medium-volume-emission-color').closest('.field').hidden)),
      'the emission colour is hidden while a grid glows in it');
    await page.locator('#ctl-medium-volume-emission-color').scrollIntoViewIfNeeded();
    await shot(page, '06f-volume-emission-colour.png');
    const errors = await page.evaluate((n) => window.refract.errors - n, errors0);
    assert(errors === 0, `${errors} edit(s) refused: ${JSON.stringify(await page.evaluate(() => window.refract.lastError))}`);
    volumes = await step(() => page.click('#medium_volume-remove'));
    assert(!Object.keys(volumes).length, `volumes ${JSON.stringify(volumes)}`);
  });

  await check('Add places a built-in volume beside the default glass, in view, on the floor; another file takes its place', async () => {
    // A viewer of a new default scene (the glass sphere at the origin), so that nothing earlier moved it.
    const made = await api('POST', '/api/scenes', SMALL_SCENE);
    assert(made.status === 201, `POST /api/scenes -> ${made.status}`);
    const id = made.json.id;
    const fresh = await context.newPage();
    try {
      await fresh.goto(`${base}/?scene=${encodeURIComponent(id)}&maxpx=${MAX_PX}`);
      await waitSettled(fresh);
      const listed = (await api('GET', '/api/volumes')).json.builtin;
      // A volume's box in the world: its usable grids' world boxes (GET /api/volumes) scaled and moved as
      // the member says (the daemon applies scale, then position, to the grid's world coordinates).
      const boxOf = (member) => {
        const grids = listed.find((v) => v.name === member.asset).grids.filter((g) => g.usable);
        const at = (v, i) => member.position[i] + member.scale * v;
        return {
          lo: [0, 1, 2].map((i) => at(Math.min(...grids.map((g) => g.world_bounds.min[i])), i)),
          hi: [0, 1, 2].map((i) => at(Math.max(...grids.map((g) => g.world_bounds.max[i])), i)),
        };
      };
      const edited = async (action) => {
        const rev = await fresh.evaluate(() => window.refract.lastRevision);
        await action();
        await waitSettled(fresh, rev);
        return (await sceneOnServer(id)).scene;
      };
      // With no volume in the scene, the picker only chooses what Add places.
      await fresh.selectOption('#ctl-medium-volume-asset', 'builtin.cloud');
      const scene = await edited(() => fresh.click('#medium_volume-add'));
      const [name] = Object.keys(scene.volumes || {});
      const volume = scene.volumes[name];
      assert(volume?.asset === 'builtin.cloud', `volumes ${JSON.stringify(scene.volumes)}`);
      const seen = await fresh.evaluate(() => window.refract.view());
      const cam = seen.camera || scene.camera;
      const { position: at, scale: size } = scene.object;  // the sphere: [-1, 1] a side in its own units
      const object = { lo: at.map((p) => p - size), hi: at.map((p) => p + size) };
      // Where a volume is placed well: its box apart from the glass's, every corner in this viewer's
      // frame, its bottom on the floor (not below it, nor more than a few centimetres above).
      const faults = (box) => [
        [0, 1, 2].every((i) => box.lo[i] < object.hi[i] && box.hi[i] > object.lo[i]) && 'inside the glass sphere',
        !corners(box.lo, box.hi).every((p) => {
          const f = inFrame(cam, seen.width / seen.height, p);
          return f.z > 0 && Math.abs(f.x) <= 1 && Math.abs(f.y) <= 1;
        }) && 'out of the frame',
        !(box.lo[1] >= scene.floor.height - 1e-6 && box.lo[1] <= scene.floor.height + 0.05) &&
          `standing at ${box.lo[1]}, not on the floor`,
      ].filter(Boolean);
      // And lit, so that it shows: its middle inside the spot's cone and out of the sphere's shadow (the
      // side of the sphere away from the light is dark, and a cloud there is not seen).
      const lit = (b) => {
        const light = scene.light;
        const mid = [0, 1, 2].map((i) => (b.lo[i] + b.hi[i]) / 2);
        const to = mid.map((v, i) => v - light.position[i]);
        const r = Math.hypot(...to);
        const d = to.map((v) => v / r);
        const axis = light.direction.map((v) => v / Math.hypot(...light.direction));
        const inCone = d.reduce((t, v, i) => t + v * axis[i], 0) >= Math.cos((light.cone_deg * Math.PI) / 180);
        const t = Math.min(r, Math.max(0, d.reduce((u, v, i) => u + v * (at[i] - light.position[i]), 0)));
        const closest = light.position.map((v, i) => v + t * d[i] - at[i]);
        return inCone && Math.hypot(...closest) > size;
      };
      const box = boxOf(volume);
      assert(lit(box), `the cloud ${JSON.stringify(volume)} is out of the light`);
      assert(!faults(box).length,
        `the cloud ${JSON.stringify(volume)} (box ${JSON.stringify(box)}) is ${faults(box).join(', ')}`);
      // What Add did before: the volume at the origin, scale 1, is inside the glass.
      const old = faults(boxOf({ ...volume, position: [0, 0, 0], scale: 1 }));
      assert(old.includes('inside the glass sphere'), `the check would pass the old placement: ${old}`);
      const shown = (v) => v.map((x) => x.toFixed(2));
      log(`the cloud: scale ${volume.scale}, position ${volume.position}, box ${shown(box.lo)}..${shown(box.hi)}`);
      await shot(fresh, '06g-volume-added.png');
      // Another file for it stands where it stood, as large (its longest side), wherever that file's origin.
      const swapped = (await edited(() => fresh.selectOption('#ctl-medium-volume-asset', 'builtin.flame'))).volumes[name];
      const flame = boxOf(swapped);
      const foot = (b) => [(b.lo[0] + b.hi[0]) / 2, b.lo[1], (b.lo[2] + b.hi[2]) / 2];
      const longest = (b) => Math.max(...[0, 1, 2].map((i) => b.hi[i] - b.lo[i]));
      assert(swapped.asset === 'builtin.flame' && foot(flame).every((v, i) => Math.abs(v - foot(box)[i]) < 0.02) &&
        Math.abs(longest(flame) - longest(box)) < 0.02,
      `the flame ${JSON.stringify(swapped)} (box ${JSON.stringify(flame)})`);
      await shot(fresh, '06h-volume-swapped.png');
    } finally {
      await fresh.close();
      await api('DELETE', `/api/scenes/${encodeURIComponent(id)}`);
    }
  });

  await check('an OBJ 190 units wide is fitted and centred; in its own units, "Frame object" frames it', async () => {
    // A box 190 x 80 x 150 units, far from the origin (as CAD files are).
    const lo = [400, -30, 20];
    const hi = [590, 50, 170];
    const corner = (k) => [0, 1, 2].map((i) => ((k >> i) & 1 ? hi[i] : lo[i])).join(' ');
    const faces = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
    const obj = ['# 190 units wide', ...[0, 1, 2, 3, 4, 5, 6, 7].map((k) => `v ${corner(k)}`),
      ...faces.map((f) => `f ${f.map((i) => i + 1).join(' ')}`), ''].join('\n');
    const objPath = path.join(tmp, 'wide-box.obj');
    fs.writeFileSync(objPath, obj);
    const rev0 = await page.evaluate(() => window.refract.lastRevision);
    const uploads0 = await page.evaluate(() => window.refract.meshUploads);
    await page.setInputFiles('#mesh-file', objPath);
    await waitFor(page, (n) => window.refract.meshUploads > n, uploads0);
    await waitSettled(page, rev0);
    const fitted = (await sceneOnServer(sceneId)).scene.object;
    const s = 2 / 190;
    assert(fitted.mesh === 'upload:wide-box', `mesh ${fitted.mesh}`);
    assert(Math.abs(fitted.scale - s) < 1e-4, `scale ${fitted.scale}, expected ${s}`);
    const centre = [0, 1, 2].map((i) => fitted.position[i] + fitted.scale * (lo[i] + hi[i]) / 2);
    assert(centre.every((c) => Math.abs(c) < 1e-3), `fitted centre at ${centre}`);
    const ui = await page.evaluate(() => ({
      scale: Number(document.getElementById('ctl-object-scale-num').value),
      status: document.getElementById('mesh-status').textContent,
    }));
    assert(Math.abs(ui.scale - s) < 1e-4, `the scale box shows ${ui.scale}`);
    assert(/190 units across/.test(ui.status) && /scaled by/.test(ui.status), `upload status "${ui.status}"`);
    await shot(page, '06b-obj-fitted.png');

    // Keeping its own units: the upload changes only the mesh; then the view is framed on it.
    await page.check('#mesh-keep-units');
    await page.fill('#ctl-object-scale-num', '0.02');
    await page.press('#ctl-object-scale-num', 'Enter');
    await waitSettled(page, rev0);
    const rev1 = await page.evaluate(() => window.refract.lastRevision);
    const uploads1 = await page.evaluate(() => window.refract.meshUploads);
    await page.setInputFiles('#mesh-file', { name: 'wide-box-2.obj', mimeType: 'text/plain', buffer: Buffer.from(obj) });
    await waitFor(page, (n) => window.refract.meshUploads > n, uploads1);
    await waitSettled(page, rev1);
    const own = (await sceneOnServer(sceneId)).scene.object;
    assert(own.mesh === 'upload:wide-box-2' && own.scale === 0.02, `kept units: ${JSON.stringify(own)}`);
    const frames2 = await page.evaluate(() => window.refract.framesReceived);
    await page.click('#frame-object');
    await waitFor(page, (n) => window.refract.framesReceived > n, frames2);
    await waitSettled(page);
    // This viewer's own camera is framed on it (the scene's camera stays where it was).
    const framed = await page.evaluate(() => window.refract.view());
    const cam = framed.camera;
    const placed = [0, 1, 2].map((i) => own.position[i] + own.scale * (lo[i] + hi[i]) / 2);
    assert(cam.target.every((t, i) => Math.abs(t - placed[i]) < 1e-3), `camera aims at ${cam.target}, object at ${placed}`);
    // Every corner of the box is inside the view.
    const at = (p) => p.map((x, i) => own.position[i] + own.scale * x);
    corners(lo, hi).forEach((p, k) => {
      const { x, y, z } = inFrame(cam, framed.width / framed.height, at(p));
      assert(z > 0 && Math.abs(x) <= 1 && Math.abs(y) <= 1, `corner ${k} outside the view (${x}, ${y})`);
    });
    await shot(page, '06c-obj-own-units-framed.png');
    await page.uncheck('#mesh-keep-units');
  });

  await check('a volume uploaded (OpenVDB) is placed in the scene, edited and removed; a bad file is refused', async () => {
    await waitSettled(page);
    const writer = process.env.REFRACT_E2E_VDB_WRITER;
    assert(writer, 'REFRACT_E2E_VDB_WRITER is not set (ctest sets it to the program that writes the test volume)');
    const vdb = path.join(tmp, 'smoke-ball.vdb');
    execFileSync(writer, [vdb]);
    // Not OpenVDB: refused at the control with the file's name, nothing stored, the scene unchanged.
    const bad = path.join(tmp, 'not-a-volume.vdb');
    fs.writeFileSync(bad, 'not a volume');
    const errors0 = await page.evaluate(() => window.refract.errors);
    await page.setInputFiles('#volume-file', bad);
    await waitFor(page, (n) => window.refract.errors > n, errors0);
    const refusal = await page.textContent('#ctl-medium-volume-asset-error');
    assert(/not-a-volume\.vdb/.test(refusal), `the refusal says "${refusal}"`);
    assert(!(await api('GET', '/api/volumes')).json.volumes.some((v) => v.name === 'not-a-volume'), 'the bad file was stored');
    assert(!Object.keys((await sceneOnServer(sceneId)).scene.volumes || {}).length, 'the scene has a volume after a refused upload');

    const rev0 = await page.evaluate(() => window.refract.lastRevision);
    await page.setInputFiles('#volume-file', vdb);
    await waitSettled(page, rev0);
    let scene = (await sceneOnServer(sceneId)).scene;
    assert(scene.volumes?.volume?.asset === 'smoke-ball', `volumes ${JSON.stringify(scene.volumes)}`);
    const shown = await page.evaluate(() => ({
      grid: document.getElementById('ctl-medium-volume-grid').value,
      status: document.getElementById('volume-status').textContent,
      hidden: document.getElementById('ctl-medium-volume-density-scale').closest('.field').hidden,
    }));
    assert(shown.grid === 'density' && !shown.hidden && /smoke-ball/.test(shown.status), JSON.stringify(shown));
    const rev1 = await page.evaluate(() => window.refract.lastRevision);
    await page.fill('#ctl-medium-volume-density-scale-num', '4');
    await page.press('#ctl-medium-volume-density-scale-num', 'Enter');
    await waitSettled(page, rev1);
    scene = (await sceneOnServer(sceneId)).scene;
    assert(scene.volumes.volume.density_scale === 4, `density_scale ${scene.volumes.volume.density_scale}`);
    await shot(page, '06v-volume-uploaded.png');
    const rev2 = await page.evaluate(() => window.refract.lastRevision);
    await page.click('#medium_volume-remove');
    await waitSettled(page, rev2);
    scene = (await sceneOnServer(sceneId)).scene;
    assert(!Object.keys(scene.volumes || {}).length, `volumes ${JSON.stringify(scene.volumes)}`);
    assert(await page.evaluate(() => document.getElementById('ctl-medium-volume-grid').closest('.field').hidden),
      'the volume controls show without a volume');
  });

  await check('examples come from the daemon; the name shown clears once the scene is edited', async () => {
    const list = await api('GET', '/api/examples');
    const names = list.json.examples.map((e) => e.name);
    for (const n of ['ball_lens_fog', 'luneburg', 'maxwell_fisheye', 'prism']) assert(names.includes(n), `examples: ${names}`);
    assert(list.json.examples.find((e) => e.name === 'ball_lens_fog').title === 'Ball lens fog', 'title of ball_lens_fog');
    assert((await api('GET', '/api/examples/..')).status !== 200, 'GET /api/examples/.. answered');
    assert((await api('GET', '/api/examples/Luneburg')).status === 400, 'a bad name is not a 400');
    assert((await api('GET', '/api/examples/nope')).status === 404, 'a missing example is not a 404');
    const options = await page.evaluate(() => [...document.querySelectorAll('#ctl-example option')].map((o) => o.value));
    assert(names.every((n) => options.includes(n)), `picker lists ${options}`);

    const example = (await api('GET', '/api/examples/luneburg')).json;
    const rev0 = await page.evaluate(() => window.refract.lastRevision);
    const dims0 = await page.evaluate(() => window.refract.dims);
    await page.selectOption('#ctl-example', 'luneburg');
    await page.click('#example-load');
    // While the new scene loads and renders, the old frame is dimmed and the progress line says so.
    await waitFor(page, (n) => window.refract.dims > n, dims0);
    await sleep(200);  // the dimming's transition (on a fast device the new frame may be there already)
    await shot(page, '07-example-pending.png');
    await waitSettled(page, rev0);
    const after = (await sceneOnServer(sceneId)).scene;
    assert(after.object.index_field === 'luneburg' && after.object.mesh === 'sphere', `object ${JSON.stringify(after.object)}`);
    assert(after.light.intensity === example.light.intensity, `light ${after.light.intensity}`);
    assert(JSON.stringify(after.volume.bounds) === JSON.stringify(example.volume.bounds), 'volume bounds differ');
    assert(after.object.scale === example.object.scale && after.object.position.every((x) => x === 0), 'object placement');
    // Members the example leaves out take their defaults, whatever the scene had before.
    assert(after.object.rotation_deg.every((x) => x === 0) && after.medium.ior === 1, 'defaults not restored');
    const ui = await page.evaluate(() => ({
      picked: document.getElementById('ctl-example').value, name: window.refract.example,
      field: document.getElementById('ctl-object-index-field').value,
      iorHidden: document.getElementById('ctl-object-ior').closest('.field').hidden,
      meshNote: document.getElementById('mesh-status').textContent,
    }));
    assert(ui.picked === 'luneburg' && ui.name === 'luneburg', `picker shows "${ui.picked}"`);
    assert(ui.meshNote === '', `the mesh note still says "${ui.meshNote}"`);
    assert(ui.field === 'luneburg', `index field control shows ${ui.field}`);
    assert(ui.iorHidden, 'the IOR control is still shown for a Luneburg lens');
    await shot(page, '07b-example-luneburg.png');

    const rev1 = await page.evaluate(() => window.refract.lastRevision);
    await page.fill('#ctl-light-intensity-num', '1200');
    await page.press('#ctl-light-intensity-num', 'Enter');
    await waitSettled(page, rev1);
    const edited = await page.evaluate(() => ({ picked: document.getElementById('ctl-example').value, name: window.refract.example }));
    assert(edited.picked === '' && edited.name === null, `still named after an edit: ${JSON.stringify(edited)}`);
  });

  await check('a load does not wait for the still in flight: the still gives way to the new scene', async () => {
    await waitSettled(page);
    // A still of minutes: 2^22 photons scattering up to 1024 times in dense white fog.
    const heavy = await api('PATCH', `/api/scenes/${sceneId}`, {
      medium: { extinction: [50, 50, 50], scattering: [50, 50, 50] }, photons: { count: 4194304, max_bounces: 1024 },
    }, 'application/merge-patch+json');
    assert(heavy.status === 200, `heavy scene: ${heavy.status}`);
    await sleep(500);
    await page.click('#still-btn');
    await waitFor(page, () => window.refract.inflight().includes('still'));
    await sleep(500);
    const rev0 = await page.evaluate(() => window.refract.lastRevision);
    await page.selectOption('#ctl-example', 'prism');
    const [patched] = await Promise.all([
      page.waitForRequest((r) => r.method() === 'PATCH' && r.url().includes(`/api/scenes/${sceneId}`), { timeout: 30_000 }),
      page.click('#example-load'),
    ]);
    assert(patched, 'the example was never sent');
    const inflight = await page.evaluate(() => window.refract.inflight());
    assert(inflight.includes('still'), `the load waited for the still in flight (in flight now: ${inflight})`);
    await waitSettled(page, rev0);
    const after = (await sceneOnServer(sceneId)).scene;
    assert(after.photons.count === QUICK.photons.count && after.medium.extinction[0] !== 50, 'the example did not replace the scene');
    const meta = await page.evaluate(() => window.refract.lastMeta);
    assert(meta.revision === (await sceneOnServer(sceneId)).revision, `the frame shown is of revision ${meta.revision}`);
  });

  await check('export and import the scene document (JSON, and glTF); save the frame as PNG', async () => {
    await waitSettled(page);
    const exported = await downloadFrom(page, '#scene-export');
    const doc = JSON.parse(fs.readFileSync(exported, 'utf8'));
    const server0 = await sceneOnServer(sceneId);
    assert(sceneOnly(doc) === sceneOnly(server0.scene), 'the exported document is not the scene');

    const png = fs.readFileSync(await downloadFrom(page, '#save-png'));
    const meta = await page.evaluate(() => window.refract.lastMeta);
    assert(png.subarray(1, 4).toString() === 'PNG', 'the saved frame is not a PNG');
    assert(png.readUInt32BE(16) === meta.width && png.readUInt32BE(20) === meta.height,
      `saved PNG ${png.readUInt32BE(16)}x${png.readUInt32BE(20)}, frame ${meta.width}x${meta.height}`);

    // A partial document: what it leaves out takes the defaults.
    const partial = path.join(tmp, 'partial.json');
    fs.writeFileSync(partial, JSON.stringify({ object: { mesh: 'torus', rotation_deg: [60, 0, 20] }, ...QUICK }));
    const rev0 = await page.evaluate(() => window.refract.lastRevision);
    await page.setInputFiles('#scene-file', partial);
    await waitSettled(page, rev0);
    const torus = (await sceneOnServer(sceneId)).scene;
    assert(torus.object.mesh === 'torus' && torus.light.intensity === 20 && torus.camera.fov_deg === 35,
      `partial import: ${JSON.stringify(torus.object)} ${torus.light.intensity}`);
    await shot(page, '07c-imported-partial.png');

    // The exported file brings the scene back as it was.
    const rev1 = await page.evaluate(() => window.refract.lastRevision);
    await page.setInputFiles('#scene-file', exported);
    await waitSettled(page, rev1);
    const back = await sceneOnServer(sceneId);
    assert(sceneOnly(back.scene) === sceneOnly(server0.scene), 'import did not restore the exported scene');
    const shown = await page.evaluate(() => Number(document.getElementById('ctl-light-intensity-num').value));
    assert(shown === server0.scene.light.intensity, `controls show intensity ${shown}`);

    // A file that is not JSON is reported at the import control and changes nothing.
    const errors0 = await page.evaluate(() => window.refract.errors);
    await page.setInputFiles('#scene-file', { name: 'junk.json', mimeType: 'application/json', buffer: Buffer.from('{ nope') });
    await waitFor(page, (n) => window.refract.errors > n, errors0);
    const err = await page.evaluate(() => document.getElementById('scene-file').closest('.field').querySelector('.field-error').textContent);
    assert(/junk\.json/.test(err), `import error "${err}"`);
    assert((await sceneOnServer(sceneId)).revision === back.revision, 'a broken import changed the scene');

    // A glTF scene: the daemon maps it (its meshes uploaded), the scene takes its objects and lights.
    const rev2 = await page.evaluate(() => window.refract.lastRevision);
    const glbPath = path.join(REPO, 'examples/gltf/glass_shelf.glb');
    const glb = fs.readFileSync(glbPath);
    const shelf = JSON.parse(glb.subarray(20, 20 + glb.readUInt32LE(12)).toString());  // the GLB's JSON chunk
    await page.setInputFiles('#scene-file', glbPath);
    await waitSettled(page, rev2);
    const imported = await sceneOnServer(sceneId);
    const glass = imported.scene;
    const names = shelf.nodes.filter((n) => n.mesh !== undefined).map((n) => n.name).sort();
    assert(JSON.stringify(Object.keys(glass.objects).sort()) === JSON.stringify(names),
      `glTF import: objects ${Object.keys(glass.objects)}, the file's ${names}`);
    assert(glass.objects.crown_ball.mesh.startsWith('upload:') && glass.lights.key.type === 'spot',
      `glTF import: ${JSON.stringify(glass.objects.crown_ball)} ${JSON.stringify(glass.lights)}`);
    const note = await page.evaluate(() => document.getElementById('scene-file-status').textContent);
    assert(/Imported glass_shelf\.glb/.test(note), `glTF import note "${note}"`);
    await shot(page, '07d-imported-gltf.png');

    // A glTF naming a file outside itself is refused at the import control with its path; nothing changes.
    const errors1 = await page.evaluate(() => window.refract.errors);
    const external = JSON.stringify({ asset: { version: '2.0' }, buffers: [{ uri: 'secret.bin', byteLength: 4 }] });
    await page.setInputFiles('#scene-file', { name: 'outside.gltf', mimeType: 'model/gltf+json', buffer: Buffer.from(external) });
    await waitFor(page, (n) => window.refract.errors > n, errors1);
    const refused = await page.evaluate(() => document.getElementById('scene-file').closest('.field').querySelector('.field-error').textContent);
    assert(/\/buffers\/0\/uri/.test(refused), `glTF import error "${refused}"`);
    assert((await sceneOnServer(sceneId)).revision === imported.revision, 'a refused glTF changed the scene');

    // The scene as the checks after these expect it (one light, one object)...
    await page.setInputFiles('#scene-file', exported);
    await waitSettled(page, imported.revision);
    // ...and a .glb dropped anywhere on the page imports as one chosen does; then that scene again.
    const rev3 = await page.evaluate(() => window.refract.lastRevision);
    const dropped = await page.evaluateHandle((bytes) => {
      const transfer = new DataTransfer();
      transfer.items.add(new File([new Uint8Array(bytes)], 'dropped.glb', { type: 'model/gltf-binary' }));
      return transfer;
    }, [...glb]);
    await page.dispatchEvent('body', 'drop', { dataTransfer: dropped });
    await waitSettled(page, rev3);
    const afterDrop = await sceneOnServer(sceneId);
    assert(JSON.stringify(Object.keys(afterDrop.scene.objects).sort()) === JSON.stringify(names),
      `dropped glTF: objects ${Object.keys(afterDrop.scene.objects)}`);
    await page.setInputFiles('#scene-file', exported);
    await waitSettled(page, afterDrop.revision);
  });

  await check('keyframes played into the view, the scene unchanged; bad keyframes reported', async () => {
    const before = await sceneOnServer(sceneId);
    const played0 = await page.evaluate(() => { window.refract.playedSizes = []; return window.refract.playedFrames; });
    // One second of a light swinging across (24 frames/s): the client shows each frame as it comes.
    const keys = [{ time: 0, patch: { light: { position: [2.5, 2.5, 1], direction: [-2.5, -3, -1] } } },
                  { time: 1, patch: { light: { position: [-2.5, 2.5, 1], direction: [2.5, -3, -1] } } }];
    await page.setInputFiles('#keyframes-file', { name: 'swing.json', mimeType: 'application/json',
      buffer: Buffer.from(JSON.stringify(keys)) });
    await waitFor(page, () => window.refract.playing() !== null && window.refract.playedFrames > 0 &&
      document.getElementById('play-stop').hidden === false);
    await shot(page, '07e-playing.png');
    await waitFor(page, () => window.refract.playing() === null);
    const played = await page.evaluate(() => window.refract.playedFrames);
    assert(played - played0 >= 2, `only ${played - played0} played frames drawn`);
    // The note says what was seen: the frames drawn of the 25, and the rest skipped to keep time.
    const note = await page.evaluate(() => document.getElementById('scene-file-status').textContent);
    const counted = /^Played swing\.json: (\d+) of 25 frames shown(, (\d+) skipped to keep time .*)?\.$/.exec(note);
    assert(counted, `status "${note}"`);
    assert(Number(counted[1]) === played - played0 && Number(counted[1]) + Number(counted[3] || 0) === 25,
      `"${note}", and ${played - played0} played frames were drawn`);
    // Played at this viewer's size: the frames grow to it (the budget of a play lets them).
    const playedAt = await page.evaluate(() => ({ sizes: window.refract.playedSizes, view: window.refract.view() }));
    assert(playedAt.sizes.some(([w, h]) => w === playedAt.view.width && h === playedAt.view.height),
      `played frames ${JSON.stringify(playedAt.sizes)}, the view ${playedAt.view.width}x${playedAt.view.height}`);
    log(note);
    await waitSettled(page, -1);
    const after = await sceneOnServer(sceneId);
    assert(after.revision === before.revision, `playing changed the scene: r${before.revision} -> r${after.revision}`);
    // Keyframes out of order: the daemon's pointer is shown at the control, nothing plays.
    const errors0 = await page.evaluate(() => window.refract.errors);
    await page.setInputFiles('#keyframes-file', { name: 'backwards.json', mimeType: 'application/json',
      buffer: Buffer.from(JSON.stringify([{ time: 1, patch: {} }, { time: 0, patch: {} }])) });
    await waitFor(page, (n) => window.refract.errors > n, errors0);
    const err = await page.evaluate(() => window.refract.lastError);
    assert(err.pointer === '/keyframes/1/time', `play error pointer ${err.pointer}`);
    assert(await page.evaluate(() => window.refract.playing()) === null, 'a refused play is still shown as playing');
  });

  await check('an environment picked in a lamp-lit scene is balanced against the lamps, not washing them out', async () => {
    await applyExample(page, 'two_lamps');
    // Mean luminance of a box of the canvas at (x, y), fractions of its size: the lamps' pools meet on the
    // floor at the bottom centre; the floor outside them is at the bottom-left corner.
    const poolContrast = () => page.evaluate(() => {
      const c = document.getElementById('view');
      const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
      const mean = (fx, fy) => {
        let sum = 0, n = 0;
        for (let y = Math.floor((fy - 0.04) * c.height); y < (fy + 0.04) * c.height; y++)
          for (let x = Math.floor((fx - 0.05) * c.width); x < (fx + 0.05) * c.width; x++, n++) {
            const i = 4 * (y * c.width + x);
            sum += 0.2126 * d[i] + 0.7152 * d[i + 1] + 0.0722 * d[i + 2];
          }
        return sum / n;
      };
      return mean(0.5, 0.85) / Math.max(1, mean(0.07, 0.93));
    });
    const unlit = await poolContrast();
    const rev0 = await page.evaluate(() => window.refract.lastRevision);
    await page.selectOption('#ctl-environment', 'image:sky-sun');
    await waitSettled(page, rev0);
    const env = (await sceneOnServer(sceneId)).scene.environment;
    const note = await page.evaluate(() => document.getElementById('environment-status').textContent);
    assert(env.image === 'sky-sun' && env.intensity > 0 && env.intensity < 0.2, `environment ${JSON.stringify(env)}`);
    assert(note.includes(`Intensity ${env.intensity}`), `the environment's note says "${note}"`);
    const balanced = await poolContrast();
    await shot(page, '07e-two-lamps-sky-sun.png');
    // The same sky at intensity 1: the pools vanish in daylight, which is what the balance prevents.
    const rev1 = await page.evaluate(() => window.refract.lastRevision);
    await page.fill('#ctl-environment-intensity-num', '1');
    await page.press('#ctl-environment-intensity-num', 'Enter');
    await waitSettled(page, rev1);
    const daylight = await poolContrast();
    log(`pool contrast: lamps alone ${unlit.toFixed(2)}, balanced sky ${balanced.toFixed(2)}, sky at 1 ${daylight.toFixed(2)}`);
    assert(balanced > 1.5, `the lamps' pools are washed out by the balanced sky (contrast ${balanced.toFixed(2)})`);
    assert(daylight < balanced, `the sky at intensity 1 did not wash out more (${daylight.toFixed(2)})`);
  });

  await check('the dispersion example and its Abbe number control', async () => {
    await applyExample(page, 'dispersion');
    const applied = await sceneOnServer(sceneId);
    // A loaded example shows a preview before its still (issue 37): the new scene's first frame drawn is
    // interactive, its last the still.
    const drawn = (await page.evaluate(() => window.refract.drawn)).filter((f) => f.revision >= applied.revision);
    assert(drawn.length >= 2 && drawn[0].quality === 'interactive' && drawn[drawn.length - 1].quality === 'still',
      `frames drawn of the loaded example: ${JSON.stringify(drawn)}`);
    assert(applied.scene.object.abbe > 0, `abbe is ${applied.scene.object.abbe}`);
    const shown = await page.evaluate(() => Number(document.getElementById('ctl-object-abbe-num').value));
    assert(shown === applied.scene.object.abbe, `the Abbe control shows ${shown}, the scene has ${applied.scene.object.abbe}`);
    await shot(page, '07d-example-dispersion.png');
    // An Abbe number no glass has is refused next to the control; 0 turns dispersion off.
    const errors0 = await page.evaluate(() => window.refract.errors);
    await page.fill('#ctl-object-abbe-num', '2');
    await page.press('#ctl-object-abbe-num', 'Enter');
    await waitFor(page, (n) => window.refract.errors > n, errors0);
    const err = await page.evaluate(() => window.refract.lastError);
    assert(err.pointer === '/object/abbe', `error pointer ${err.pointer}, expected /object/abbe`);
    const rev1 = await page.evaluate(() => window.refract.lastRevision);
    await page.fill('#ctl-object-abbe-num', '0');
    await page.press('#ctl-object-abbe-num', 'Enter');
    await waitSettled(page, rev1);
    const off = await sceneOnServer(sceneId);
    assert(off.scene.object.abbe === 0, `abbe is ${off.scene.object.abbe} after setting 0`);
    // Dispersion on again: the restart check below expects this scene to come back as it was.
    const rev2 = await page.evaluate(() => window.refract.lastRevision);
    await page.fill('#ctl-object-abbe-num', '20');
    await page.press('#ctl-object-abbe-num', 'Enter');
    await waitSettled(page, rev2);
  });

  await check('narrow window: stacked layout, no overflow, smaller image', async () => {
    const server0 = await sceneOnServer(sceneId);
    const frames0 = await page.evaluate(() => window.refract.framesReceived);
    await page.setViewportSize({ width: 390, height: 844 });
    await waitFor(page, (n) => window.refract.framesReceived > n, frames0);
    await waitSettled(page);
    const layout = await page.evaluate(() => {
      const stage = document.getElementById('stage').getBoundingClientRect();
      const panel = document.getElementById('panel').getBoundingClientRect();
      const offenders = [...document.querySelectorAll('input, select, button, label, canvas, table')]
        .filter((el) => { const r = el.getBoundingClientRect(); return r.width > 0 && r.right > window.innerWidth + 1; })
        .map((el) => el.id || el.tagName);
      const c = document.getElementById('view');
      return {
        scrollWidth: document.documentElement.scrollWidth, inner: window.innerWidth,
        stageBottom: stage.bottom, panelTop: panel.top, stageWidth: stage.width, offenders, w: c.width, h: c.height,
        image: window.refract.lastMeta.width,
      };
    });
    assert(layout.scrollWidth <= layout.inner, `page scrolls sideways (${layout.scrollWidth} > ${layout.inner})`);
    assert(layout.offenders.length === 0, `controls overflow the window: ${layout.offenders.join(', ')}`);
    assert(layout.panelTop >= layout.stageBottom - 1, 'controls are not below the viewport');
    assert(layout.image <= 390 && layout.image >= 200, `image width ${layout.image} does not follow the canvas`);
    // The frame is this viewer's view; the scene's own image size (its saved view) is not touched.
    const server = await sceneOnServer(sceneId);
    const sent = await page.evaluate(() => window.refract.view());
    assert(sent.width === layout.image, `view width ${sent.width} != drawn ${layout.image}`);
    assert(JSON.stringify(server.scene.image) === JSON.stringify(server0.scene.image) && server.revision === server0.revision,
      `the scene's image became ${JSON.stringify(server.scene.image)} (revision ${server0.revision} -> ${server.revision})`);
    await shot(page, '08-narrow.png');
    await shot(page, '08-narrow-full.png', { fullPage: true });
    const frames1 = await page.evaluate(() => window.refract.framesReceived);
    await page.setViewportSize({ width: 1200, height: 760 });
    await waitFor(page, (n) => window.refract.framesReceived > n, frames1);
    await waitSettled(page);
  });

  await check('the client reconnects after a daemon restart and restores the view', async () => {
    await waitSettled(page);
    const before = await page.evaluate(() => ({
      id: window.refract.sceneId, frames: window.refract.framesReceived, connects: window.refract.connects,
      abbe: Number(document.getElementById('ctl-object-abbe-num').value),
    }));
    assert(before.abbe > 0, 'the scene before the restart does not disperse');
    await stopRefractd(daemon);
    await waitFor(page, () => !window.refract.connected);
    await shot(page, '09-daemon-down.png');
    await sleep(1500);  // let the client back off at least once
    daemon = startDaemon();
    await waitForHealth(base, daemon);
    await waitFor(page, (n) => window.refract.connects > n && window.refract.framesReceived > 0, before.connects);
    await waitFor(page, (n) => window.refract.framesReceived > n, before.frames);
    await waitSettled(page);
    const after = await page.evaluate(() => ({
      id: window.refract.sceneId, url: location.href, conn: document.getElementById('conn').dataset.state,
      abbe: Number(document.getElementById('ctl-object-abbe-num').value),
    }));
    assert(after.conn === 'live', `connection state ${after.conn}`);
    assert(new URL(after.url).searchParams.get('scene') === after.id, 'URL and client disagree on the scene');
    assert(after.id === before.id, `scene ${before.id} was not restored (now ${after.id})`);
    assert(after.abbe === before.abbe, `controls show Abbe number ${after.abbe} after reconnecting, not ${before.abbe}`);
    await shot(page, '09-reconnected.png');
  });

  await check('without ?scene= the client creates a scene and puts its id in the URL', async () => {
    const page2 = await context.newPage();
    try {
      // Only the HTTP side matters here: the WebSocket is answered by a stub that never asks for a
      // frame, so the daemon does not start a (slow, default 128^3) render of the new scene.
      await page2.routeWebSocket(/\/api\/scenes\/.*\/ws/, () => {});
      await page2.goto(`${base}/?maxpx=96`);
      await waitFor(page2, () => new URL(location.href).searchParams.get('scene') !== null);
      const id = await page2.evaluate(() => new URL(location.href).searchParams.get('scene'));
      assert(id !== sceneId, 'a fresh page reused the test scene');
      const server = await sceneOnServer(id);
      assert(server.revision >= 0, 'no revision for the new scene');
      const list = await api('GET', '/api/scenes');
      assert(JSON.stringify(list.json).includes(id), 'new scene not listed by GET /api/scenes');
    } finally {
      await page2.close();
    }
  });

  if (pageErrors.length) log('page errors seen:', pageErrors);
  await check('no script errors in the page', async () => {
    assert(pageErrors.length === 0, pageErrors.join('; '));
  });
}

// ---- run -----------------------------------------------------------------------------------------

async function cleanup() {
  try { if (browser) await browser.close(); } catch { /* already gone */ }
  browser = null;
  await stopRefractd(daemon);
  daemon = null;
  await new Promise((resolve) => daemonLog.end(resolve));
  fs.rmSync(tmp, { recursive: true, force: true });
}

killOnExit(() => daemon, () => browser, log);

let fatal = null;
try {
  await main();
} catch (e) {
  fatal = e;
  log('FATAL', e.stack || e.message);
} finally {
  await cleanup();
}
const passed = results.filter((r) => r.ok).length;
const failed = results.length - passed + (fatal ? 1 : 0);
if (failed) {
  const tail = fs.existsSync(daemonLogPath) ? fs.readFileSync(daemonLogPath, 'utf8').split('\n').slice(-25).join('\n') : '';
  console.log(`--- last lines of ${daemonLogPath} ---\n${tail}`);
}
if (screenshots.length) console.log(`screenshots: ${OUT}`);
console.log(`browser_e2e: ${passed} passed, ${failed} failed`);
process.exit(failed ? 1 : 0);
