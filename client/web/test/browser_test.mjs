// Browser tests: the real web client in Debian's Chromium (playwright-core, nothing downloaded)
// against a sculptd this script starts. Usage:
//   node test/browser_test.mjs --bin BUILD/bin --web-root DIST [--screenshots DIR]
// Exits non-zero with the failing check's name. Run by ctest (label browser).
import { execFileSync, spawn } from 'node:child_process';
import { mkdtempSync, existsSync, mkdirSync, writeFileSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { dirname, join } from 'node:path';
import { fileURLToPath } from 'node:url';
import { chromiumPath, launchChromium } from './chromium.mjs';
import { sculptdPorts, startSculptd, stopSculptd } from './sculptd.mjs';

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
// The scene has a ball skin, contours on and paint materials (scene.toml beside this file).
const sceneFile = join(dirname(fileURLToPath(import.meta.url)), 'scene.toml');
const sculptd = startSculptd({ bin, webRoot, dir, label: 'browser tests', limitMs: 240000,
  extra: ['--config', sceneFile] });
let browser;
try {
  const { tcpPort, httpPort } = await sculptdPorts(sculptd);
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
  // A frame drawn after every chunk was in the scene (on a loaded machine the page's frames
  // are spaced out and the next one may not have come yet).
  const framesBefore = await viewer.evaluate(() => {
    window.sculpt.invalidate();
    return window.sculpt.stats.frames || 0;
  });
  await waitFor(viewer, (n) => (window.sculpt.stats.frames || 0) > n, framesBefore);
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
  const versionsAfter = await viewer.evaluate(() => JSON.stringify([...window.sculpt.meshes.versions]));
  const seqAfter = await viewer.evaluate(() => window.sculpt.stats.globalSeq);
  check('viewer: the drag reached its mesh', versionsAfter !== versionsBefore && seqAfter >= s.seq,
    `seq ${seqAfter} of ${s.seq}`);
  // The status line shows a latency only where there is one: the sculptor's acks, not the viewer's.
  await sleep(600);  // the status line is redrawn every 250 ms
  const lines = { viewer: await viewer.evaluate(() => document.getElementById('status').textContent),
    sculptor: await sculptor.evaluate(() => document.getElementById('status').textContent) };
  check('status line: the viewer shows no ack latency, the sculptor its own',
    lines.viewer.includes('no strokes (viewer)') && !lines.viewer.includes('ack p50')
      && /ack p50 \d+\.\d ms/.test(lines.sculptor) && !/ack p50 0\.0 ms p99 0\.0 ms/.test(lines.sculptor),
    JSON.stringify(lines));

  // 3. The viewer sees the sculptor's tool in presence while it hovers.
  for (let i = 0; i < 8; ++i) { await sculptor.mouse.move(400 + 3 * i, 320); await sleep(60); }
  await waitFor(viewer, () => window.sculpt.stats.presence.some((p) => p.name === 'alice'));
  const listed = await viewer.evaluate(() => document.getElementById('people-list').textContent);
  check('viewer: the sculptor is listed and their tool drawn', listed.includes('alice'), listed);
  if (shots) await viewer.screenshot({ path: join(shots, 'web-client-presence.png') });

  // 4. A skin's contour is drawn with the point count the server sent (the same count the
  //    C++ skin code gives for these balls: `sculpt skin`), and dragging a ball on the sculptor's
  //    panel changes the contour on the viewer's.
  const skinPoints = (balls) => {
    const file = join(dir, 'balls.json');
    writeFileSync(file, JSON.stringify({ method: 'hybrid', tolerance: 0.02,
      balls: balls.map((b) => ({ c: [b.x, b.y], r: b.r, theta: b.theta })) }));
    return JSON.parse(execFileSync(join(bin, 'sculpt'), ['skin', '--balls', file], { encoding: 'utf8' })).points;
  };
  const skinOf = (page) => page.evaluate(() => window.sculpt.contours?.stats().skins[0]);
  await waitFor(viewer, () => window.sculpt.contours?.stats().skins[0]?.updates > 0);
  await waitFor(sculptor, () => window.sculpt.contours?.stats().skins[0]?.updates > 0);
  const sk0 = await skinOf(viewer);
  const expected0 = skinPoints(sk0.balls);
  check('viewer: the skin contour is drawn with the point count the server sent',
    sk0.balls.length === 3 && sk0.sections === 2 && sk0.decodedPoints === expected0 && sk0.drawnPoints === expected0,
    JSON.stringify({ ...sk0, expected: expected0 }));
  const grab = await sculptor.evaluate(() => {
    const p = window.sculpt.contours.skins.get('sketch');
    const b = p.balls[1];
    const [cx, cy] = p.frame.toCanvas(b.x, b.y);
    const r = p.canvas.getBoundingClientRect();
    const k = r.width / p.canvas.width;
    return { x: r.left + cx * k, y: r.top + cy * k, scale: p.frame.s * k, y0: b.y };
  });
  await sculptor.mouse.move(grab.x, grab.y);
  await sculptor.mouse.down();
  for (let i = 1; i <= 10; ++i) { await sculptor.mouse.move(grab.x, grab.y - 2 * i); await sleep(40); }
  await sculptor.mouse.up();
  await waitFor(viewer, (v) => window.sculpt.contours.stats().skins[0].version > v, sk0.version);
  await waitFor(sculptor, () => window.sculpt.pendingSkinEdits.size === 0);
  await sleep(300);
  const sk1 = await skinOf(viewer);
  const mine = await skinOf(sculptor);
  const expected1 = skinPoints(sk1.balls);
  const moved = sk1.balls[1].y - sk0.balls[1].y;
  check('sculptor: ball edits accepted, none refused', mine.editsAccepted > 0 && mine.refused === 0, JSON.stringify(mine));
  check('viewer: the dragged ball moved up and its contour was redrawn from the server',
    moved > 1 && Math.abs(moved - 20 / grab.scale) < 0.5 * 20 / grab.scale && sk1.decodedPoints === expected1
      && sk1.drawnPoints === expected1 && sk1.version === mine.version,
    JSON.stringify({ moved, expectedMove: 20 / grab.scale, points: sk1.decodedPoints, expected1, version: sk1.version }));
  // The slice panel: the sphere's cut through its centre is one closed curve of radius ~24.
  await waitFor(viewer, () => window.sculpt.contours.stats().slice?.updates > 0);
  const slice = await viewer.evaluate(() => {
    const lines = window.sculpt.contours.slice.lines;
    let rmin = Infinity, rmax = 0;
    for (const l of lines) for (let i = 0; i < l.length; i += 2) { const r = Math.hypot(l[i], l[i + 1]); rmin = Math.min(rmin, r); rmax = Math.max(rmax, r); }
    return { curves: lines.length, rmin, rmax };
  });
  check('viewer: the slice shows the object\'s cut', slice.curves >= 1 && slice.rmin > 20 && slice.rmax < 28,
    JSON.stringify(slice));
  if (shots) await viewer.screenshot({ path: join(shots, 'web-client-contours.png') });

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
  // Paint: the scene's materials are offered; a drag with the paint tool is acknowledged.
  await sculptor.selectOption('#tool-kind', 'paint');
  await sculptor.selectOption('#tool-material', '1');
  const versionsBeforePaint = await viewer.evaluate(() => JSON.stringify([...window.sculpt.meshes.versions].sort()));
  await sculptor.mouse.move(360, 260);
  await sculptor.mouse.down();
  for (let i = 0; i <= 12; ++i) { await sculptor.mouse.move(360 + 6 * i, 260 + 4 * i); await sleep(40); }
  await sculptor.mouse.up();
  await waitFor(sculptor, () => window.sculpt.stats.paintsSent > 0 && window.sculpt.sculpting.pendingPaints.size === 0);
  const paints = await sculptor.evaluate(() => ({ sent: window.sculpt.stats.paintsSent, acked: window.sculpt.stats.paintsAcked, errors: window.sculpt.stats.errors }));
  check('sculptor: paints acknowledged', paints.sent > 0 && paints.acked === paints.sent && paints.errors.length === 0,
    JSON.stringify(paints));
  await waitFor(viewer, (before) => JSON.stringify([...window.sculpt.meshes.versions].sort()) !== before, versionsBeforePaint);
  const versionsAfterPaint = await viewer.evaluate(() => JSON.stringify([...window.sculpt.meshes.versions].sort()));
  check('viewer: the paint reached its mesh', versionsAfterPaint !== versionsBeforePaint);
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
  await stopSculptd(sculptd);
}
console.log(failures === 0 ? 'browser tests: all passed' : `browser tests: ${failures} failed`);
process.exit(failures === 0 ? 0 : 1);
