// What the browser test and the interactive benchmark share: loopback ports, a refractd child process
// that is always stopped, waiting for its health, and Debian's Chromium through playwright-core.

import { spawn } from 'node:child_process';
import net from 'node:net';

export const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

// playwright-core's chromium launcher; exits with a hint when the package is not installed.
export async function loadChromium(onMissing = () => {}) {
  try {
    return (await import('playwright-core')).chromium;
  } catch (e) {
    console.error(`playwright-core is not installed (${e.message}); run: npm --prefix tests/e2e ci`);
    onMissing();
    process.exit(1);
  }
}

// A loopback TCP port nobody listens on right now.
export function freePort() {
  return new Promise((resolve, reject) => {
    const srv = net.createServer();
    srv.unref();
    srv.on('error', reject);
    srv.listen(0, '127.0.0.1', () => {
      const { port } = srv.address();
      srv.close(() => resolve(port));
    });
  });
}

// Starts `binary` with `args` (lavapipe's threads: LP_NUM_THREADS if set, else the daemon's own choice),
// its output appended to `logStream`.
// `child.exited` resolves with { code, signal }.
export function startRefractd(binary, args, logStream, log) {
  log('starting', binary, args.join(' '));
  const child = spawn(binary, args, {
    stdio: ['ignore', 'pipe', 'pipe'],
  });
  child.stdout.pipe(logStream, { end: false });
  child.stderr.pipe(logStream, { end: false });
  child.exited = new Promise((resolve) => child.on('exit', (code, signal) => resolve({ code, signal })));
  child.on('error', (e) => log('refractd failed to start:', e.message));
  return child;
}

// Stops a child started above: `signal`, then SIGKILL after 10 s.
export async function stopRefractd(child, signal = 'SIGTERM') {
  if (!child || child.exitCode !== null || child.signalCode !== null) return;
  child.kill(signal);
  const done = await Promise.race([child.exited, sleep(10_000).then(() => null)]);
  if (!done) {
    child.kill('SIGKILL');
    await child.exited;
  }
}

// The body of GET /api/health once it answers 200, within 60 s; throws if the child exits first.
export async function waitForHealth(base, child) {
  const deadline = Date.now() + 60_000;
  while (Date.now() < deadline) {
    if (child.exitCode !== null || child.signalCode !== null) {
      throw new Error(`refractd exited (${child.exitCode ?? child.signalCode}) before answering /api/health`);
    }
    try {
      const res = await fetch(`${base}/api/health`);
      if (res.status === 200) return await res.json();
    } catch { /* not listening yet */ }
    await sleep(100);
  }
  throw new Error('refractd did not answer /api/health within 60 s');
}

// However the script ends (a signal, an exception, process.exit), the daemon it started does not
// outlive it; on a signal the browser is closed too. The getters read the script's current ones.
export function killOnExit(daemon, browser, log) {
  const kill = () => {
    const child = daemon();
    if (child && child.exitCode === null && child.signalCode === null) child.kill('SIGKILL');
  };
  for (const sig of ['SIGINT', 'SIGTERM', 'SIGHUP']) {
    process.on(sig, async () => {
      log(`got ${sig}, stopping`);
      kill();
      try { await browser()?.close(); } catch { /* ignore */ }
      process.exit(1);
    });
  }
  process.on('exit', kill);
}
