// throwaway new-user walk (not committed)
import fs from 'node:fs'; import os from 'node:os'; import path from 'node:path';
import { freePort, loadChromium, sleep, startRefractd, stopRefractd, waitForHealth } from './refractd.mjs';
const chromium = await loadChromium();
const [bin, out] = process.argv.slice(2);
const port = await freePort(), ws = await freePort();
const data = fs.mkdtempSync(path.join(os.tmpdir(), 'walk-'));
const log = fs.createWriteStream(path.join(out, 'refractd.log'));
const d = startRefractd(bin, ['--port', String(port), '--ws-port', String(ws), '--data-dir', data, '--web-root', path.resolve('web-client'), '--examples-dir', path.resolve('examples')], log, console.log);
const base = `http://127.0.0.1:${port}`;
await waitForHealth(base, d);
const browser = await chromium.launch({ executablePath: '/usr/bin/chromium', args: ['--no-sandbox'] });
const page = await (await browser.newContext()).newPage();
const t0 = Date.now();
await page.goto(base + '/');
for (const s of [2, 6, 20]) { await sleep(s * 1000 - (Date.now() - t0)); await page.screenshot({ path: `${out}/open_${s}s.png` }); }
const names = (await (await fetch(`${base}/api/examples`)).json()).examples.map((e) => e.name);
console.log(names.join(' '));
for (const name of names) {
  await page.selectOption('#ctl-example', name); await page.click('#example-load');
  await sleep(1000); await page.screenshot({ path: `${out}/ex_${name}_1s.png` });
  await sleep(9000); await page.screenshot({ path: `${out}/ex_${name}_10s.png` });
}
await browser.close(); await stopRefractd(d);
