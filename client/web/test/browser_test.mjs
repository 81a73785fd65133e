// Browser tests: the real web client in Debian's Chromium (playwright-core, nothing downloaded)
// against a sculptd this script starts. Usage:
//   node test/browser_test.mjs --bin BUILD/bin --web-root DIST [--screenshots DIR]
// Exits non-zero with the failing check's name. Run by ctest (label browser).
import { spawn } from 'node:child_process';
import { mkdtempSync, readFileSync, existsSync, rmSync, mkdirSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';
import { chromiumPath, launchChromium } from './chromium.mjs';

const args = Object.fromEntries(process.argv.slice(2).reduce((acc, a, i, all) =>
  (a.startsWith('--') ? [...acc, [a.slice(2), all[i + 1]]] : acc), []));
// A page may only complain about a missing favicon.
const harmless = (l) => l.includes('favicon');
const bin = args.bin;
const webRoot = args['web-root'];
const shots = args.screenshots;
if (!bin || !webRoot) { console.error('usage: --bin DIR --web-root DIR [--screenshots DIR]'); process.exit(2); }
if (!existsSync(chromiumPath)) { console.error(`${chromiumPath} missing (deploy/install-deps.sh installs chromium)`); process.exit(1); }

const sleep = (ms) => new Promise((r) => setTimeout(r, ms));
let failures = 0;
function check(name, ok, detail = '') {
  console.log(`${ok ? 'ok  ' : 'FAIL'} ${name}${detail ? `: ${detail}` : ''}`);
  if (!ok) failures += 1;
}
async function waitFor(page, fn, arg, timeout = 20000) {
  return page.waitForFunction(fn, arg, { timeout, polling: 100 });
}

const dir = mkdtempSync(join(tmpdir(), 'sculpt-browser-'));
const portFile = join(dir, 'ports');
const server = spawn(join(bin, 'sculptd'), ['serve', '--data', join(dir, 'data'), '--listen',
  '127.0.0.1:0', '--http', '127.0.0.1:0', '--port-file', portFile, '--web-root', webRoot],
{ stdio: ['ignore', 'inherit', 'inherit'] });
// The whole run is bounded: a hung browser must not hold ctest until its own timeout.
const deadline = setTimeout(() => {
  console.error('FAIL browser tests exceeded 240 s');
  server.kill('SIGKILL');
  process.exit(1);
}, 240000);
let browser;
try {
  let ports;
  for (let i = 0; i < 300 && !ports; ++i) {
    if (existsSync(portFile)) ports = readFileSync(portFile, 'utf8').trim().split('\n').map(Number);
    else await sleep(100);
  }
  if (!ports || ports.length < 2) throw new Error('sculptd wrote no port file');
  const [tcpPort, httpPort] = ports;
  const base = `http://127.0.0.1:${httpPort}/`;
  browser = await launchChromium();
  const open = async (fragment) => {
    const page = await browser.newPage({ viewport: { width: 800, height: 600 } });
    const logs = [];
    page.on('console', (m) => logs.push(`${m.type()}: ${m.text()}`));
    page.on('pageerror', (e) => logs.push(`pageerror: ${e.message}`));
    page.logs = logs;
    await page.goto(`${base}#${fragment}`);
    return page;
  };

  // 1. A viewer sees the object: the triangles drawn are the server's chunk totals, and the
  //    picture is not blank.
  const viewer = await open('token=sculpt-dev-viewer&role=viewer&name=watcher');
  await waitFor(viewer, () => window.sculpt?.stats.state === 'joined');
  await waitFor(viewer, () => {
    const m = window.sculpt.meshes;
    return m.totals().chunks > 0 && m.decoding === 0;
  });
  await sleep(500);
  const totals = await viewer.evaluate(() => window.sculpt.meshes.totals());
  check('viewer: triangles drawn equal the server chunk totals',
    totals.faces === totals.serverFaces && totals.faces > 1000, JSON.stringify(totals));
  const pixels = await viewer.evaluate(() => {
    const src = window.sculpt.renderer.domElement;
    const c = document.createElement('canvas');
    c.width = 200; c.height = 150;
    const ctx = c.getContext('2d');
    ctx.drawImage(src, 0, 0, 200, 150);
    const d = ctx.getImageData(0, 0, 200, 150).data;
    const bg = [d[0], d[1], d[2]];
    let differ = 0, sum = 0, sum2 = 0;
    for (let i = 0; i < d.length; i += 4) {
      const l = 0.299 * d[i] + 0.587 * d[i + 1] + 0.114 * d[i + 2];
      sum += l; sum2 += l * l;
      if (Math.abs(d[i] - bg[0]) + Math.abs(d[i + 1] - bg[1]) + Math.abs(d[i + 2] - bg[2]) > 30) differ += 1;
    }
    const n = d.length / 4;
    return { object_fraction: differ / n, luminance_std: Math.sqrt(sum2 / n - (sum / n) ** 2) };
  });
  check('viewer: the object covers part of the picture with shading',
    pixels.object_fraction > 0.05 && pixels.object_fraction < 0.95 && pixels.luminance_std > 10,
    JSON.stringify(pixels));
  if (shots) { mkdirSync(shots, { recursive: true }); await viewer.screenshot({ path: join(shots, 'web-client-viewer.png') }); }

  // 2. A sculptor drags across the surface: acks come back, the global sequence advances and
  //    the viewer's mesh changes.
  const sculptor = await open('token=sculpt-dev-sculptor&role=sculptor&name=alice');
  await waitFor(sculptor, () => window.sculpt?.stats.state === 'joined' && window.sculpt.meshes.totals().chunks > 0
    && window.sculpt.framed);
  await sleep(400);
  const seqBefore = await viewer.evaluate(() => window.sculpt.stats.globalSeq);
  const versionsBefore = await viewer.evaluate(() => JSON.stringify([...window.sculpt.meshes.versions]));
  await sculptor.mouse.move(330, 300);
  await sculptor.mouse.down();
  for (let i = 0; i <= 20; ++i) { await sculptor.mouse.move(330 + 7 * i, 300 + 2 * i); await sleep(15); }
  await sculptor.mouse.up();
  await waitFor(sculptor, () => window.sculpt.stats.acks > 0 && window.sculpt.sculpting.pending.size === 0);
  const s = await sculptor.evaluate(() => ({ sent: window.sculpt.stats.strokesSent, acks: window.sculpt.stats.acks,
    seq: window.sculpt.stats.globalSeq, errors: window.sculpt.stats.errors }));
  check('sculptor: every stroke acked, global sequence advanced',
    s.sent > 0 && s.acks === s.sent && s.seq > seqBefore && s.errors.length === 0, JSON.stringify(s));
  await waitFor(viewer, (before) => JSON.stringify([...window.sculpt.meshes.versions]) !== before, versionsBefore);
  await waitFor(viewer, (seq) => window.sculpt.stats.globalSeq >= seq, s.seq);
  check('viewer: the drag reached its mesh', true);

  // 3. The viewer sees the sculptor's tool in presence while it hovers.
  for (let i = 0; i < 8; ++i) { await sculptor.mouse.move(400 + 3 * i, 320); await sleep(60); }
  await waitFor(viewer, () => window.sculpt.stats.presence.some((p) => p.name === 'alice'));
  const listed = await viewer.evaluate(() => document.getElementById('people-list').textContent);
  check('viewer: the sculptor is listed and their tool drawn', listed.includes('alice'), listed);
  if (shots) await viewer.screenshot({ path: join(shots, 'web-client-presence.png') });

  // 5. A viewer token cannot sculpt: the refusal is shown.
  const impostor = await open('token=sculpt-dev-viewer&role=sculptor&name=mallory');
  await waitFor(impostor, () => window.sculpt?.stats.errors.length > 0);
  const shown = await impostor.evaluate(() => document.getElementById('errors').textContent);
  check('a viewer token asking to sculpt is refused and the page says so',
    /UNAUTHENTICATED|PERMISSION_DENIED/.test(shown), shown);

  // 6. A native sculptor (sculpt-loadgen) and the browser sculptor edit together; both pages
  //    converge to the server's state (the newest sequence).
  const loadgen = spawn(join(bin, 'sculpt-loadgen'), ['--server', `127.0.0.1:${tcpPort}`, '--sculptors', '1',
    '--viewers', '0', '--rate', '30', '--seconds', '2', '--json'], { stdio: ['ignore', 'pipe', 'inherit'] });
  let report = '';
  loadgen.stdout.on('data', (b) => { report += b; });
  const exited = new Promise((r) => loadgen.on('exit', r));
  await sculptor.mouse.move(300, 280);
  await sculptor.mouse.down();
  for (let i = 0; i <= 30; ++i) { await sculptor.mouse.move(300 + 5 * i, 280 + 3 * i); await sleep(30); }
  await sculptor.mouse.up();
  const code = await exited;
  const lg = JSON.parse(report || '{}');
  check('loadgen: its strokes were acked beside the browser sculptor', code === 0 && lg.strokes_acked > 0,
    `exit ${code}, acked ${lg.strokes_acked}`);
  await waitFor(sculptor, () => window.sculpt.sculpting.pending.size === 0);
  // Both pages converge: the same chunk versions once the server has meshed the last edits.
  await sleep(1500);
  const a = await viewer.evaluate(() => JSON.stringify([...window.sculpt.meshes.versions].sort()));
  const b = await sculptor.evaluate(() => JSON.stringify([...window.sculpt.meshes.versions].sort()));
  check('viewer and sculptor pages hold the same chunk versions', a === b);
  const ta = await viewer.evaluate(() => window.sculpt.meshes.totals());
  check('viewer: triangles still equal the server totals after the joint edits',
    ta.faces === ta.serverFaces, JSON.stringify(ta));
  if (shots) await sculptor.screenshot({ path: join(shots, 'web-client-sculptor.png') });
  for (const p of [viewer, sculptor, impostor]) {
    const bad = p.logs.filter((l) => l.startsWith('pageerror') || l.includes('Content Security Policy'));
    check(`no page errors or CSP violations (${await p.title()})`, bad.length === 0, bad.join(' | '));
  }
} catch (err) {
  console.error(`FAIL ${err.stack || err}`);
  for (const p of browser ? browser.contexts().flatMap((c) => c.pages()) : []) {
    console.error(`page ${p.url()}:\n  ${(p.logs || []).slice(-15).join('\n  ')}`);
    console.error(`  stats: ${await p.evaluate(() => JSON.stringify({ ...window.sculpt?.stats, ackLatencies: undefined, totals: window.sculpt?.meshes.totals(), versions: window.sculpt?.meshes.versions.size })).catch((e) => e.message)}`);
  }
  failures += 1;
} finally {
  if (browser) await browser.close();
  server.kill('SIGTERM');
  await new Promise((r) => server.on('exit', r));
  rmSync(dir, { recursive: true, force: true });
}
console.log(failures === 0 ? 'browser tests: all passed' : `browser tests: ${failures} failed`);
clearTimeout(deadline);
process.exit(failures === 0 ? 0 : 1);
