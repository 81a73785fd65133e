// The web client over HTTPS and WSS: sculptd with a throw-away certificate (made here by the
// `openssl` command), Debian's Chromium trusting it for this run only. A viewer and a sculptor
// join over wss://, the sculptor's drag is acknowledged and reaches the viewer's mesh; a page
// served over plain http:// from the HTTPS port gets nothing. Usage:
//   node test/https_test.mjs --bin BUILD/bin --web-root DIST
// Exits non-zero with the failing check's name. Run by ctest (label browser).
import { execFileSync } from 'node:child_process';
import { mkdtempSync, existsSync, writeFileSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';
import { chromium } from 'playwright-core';
import { chromiumPath } from './chromium.mjs';
import { sculptdPorts, startSculptd, stopSculptd } from './sculptd.mjs';

const args = Object.fromEntries(process.argv.slice(2).reduce((acc, a, i, all) =>
  (a.startsWith('--') ? [...acc, [a.slice(2), all[i + 1]]] : acc), []));
const { bin } = args;
const webRoot = args['web-root'];
if (!bin || !webRoot) { console.error('usage: --bin DIR --web-root DIR'); process.exit(2); }
if (!existsSync(chromiumPath)) { console.error(`${chromiumPath} missing`); process.exit(1); }

const sleep = (ms) => new Promise((r) => setTimeout(r, ms));
let failures = 0;
function check(name, ok, detail = '') {
  console.log(`${ok ? 'ok  ' : 'FAIL'} ${name}${detail ? `: ${detail}` : ''}`);
  if (!ok) failures += 1;
}

const dir = mkdtempSync(join(tmpdir(), 'sculpt-https-'));
const ec = ['-newkey', 'ec', '-pkeyopt', 'ec_paramgen_curve:P-256', '-nodes'];
const openssl = (...a) => execFileSync('openssl', a, { cwd: dir, stdio: 'ignore' });
openssl('req', '-x509', ...ec, '-keyout', 'ca.key', '-out', 'ca.pem', '-days', '2', '-subj', '/CN=test-ca');
openssl('req', ...ec, '-keyout', 'server.key', '-out', 'server.csr', '-subj', '/CN=localhost');
writeFileSync(join(dir, 'san.ext'), 'subjectAltName=DNS:localhost,IP:127.0.0.1\n');
openssl('x509', '-req', '-in', 'server.csr', '-CA', 'ca.pem', '-CAkey', 'ca.key', '-CAcreateserial',
  '-out', 'server.pem', '-days', '2', '-extfile', 'san.ext');
// Chromium pins certificates by the SPKI hash of their public key.
const spki = execFileSync('sh', ['-c', 'openssl x509 -in server.pem -pubkey -noout | openssl pkey -pubin '
  + '-outform der | openssl dgst -sha256 -binary | base64'], { cwd: dir }).toString().trim();

const sculptd = startSculptd({ bin, webRoot, dir, label: 'https tests', limitMs: 120000,
  extra: ['--tls-cert', join(dir, 'server.pem'), '--tls-key', join(dir, 'server.key')] });
let browser;
try {
  const { httpPort } = await sculptdPorts(sculptd);
  browser = await chromium.launch({ executablePath: chromiumPath, headless: true,
    args: ['--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run',
      '--disable-background-networking', '--disable-component-update', '--disable-sync',
      '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
      `--ignore-certificate-errors-spki-list=${spki}`] });
  const open = async (url) => {
    const page = await browser.newPage({ viewport: { width: 800, height: 600 } });
    page.sockets = [];
    page.on('websocket', (ws) => page.sockets.push(ws.url()));
    await page.goto(url);
    return page;
  };
  const base = `https://localhost:${httpPort}/`;
  const viewer = await open(`${base}#token=sculpt-dev-viewer&role=viewer&name=watcher`);
  await viewer.waitForFunction(() => window.sculpt?.stats.state === 'joined'
    && window.sculpt.meshes.totals().chunks > 0, null, { timeout: 30000, polling: 100 });
  check('viewer: joined over wss:// and got mesh chunks', viewer.sockets.every((u) => u.startsWith('wss://'))
    && viewer.sockets.length === 1, JSON.stringify(viewer.sockets));

  const sculptor = await open(`${base}#token=sculpt-dev-sculptor&role=sculptor&name=alice`);
  await sculptor.waitForFunction(() => window.sculpt?.stats.state === 'joined'
    && window.sculpt.meshes.totals().chunks > 0 && window.sculpt.framed, null, { timeout: 30000, polling: 100 });
  await sleep(400);
  const seqBefore = await viewer.evaluate(() => window.sculpt.stats.globalSeq);
  await sculptor.mouse.move(330, 300);
  await sculptor.mouse.down();
  for (let i = 0; i <= 20; ++i) { await sculptor.mouse.move(330 + 7 * i, 300 + 2 * i); await sleep(15); }
  await sculptor.mouse.up();
  await sculptor.waitForFunction(() => window.sculpt.stats.acks > 0 && window.sculpt.sculpting.pending.size === 0,
    null, { timeout: 30000, polling: 100 });
  const s = await sculptor.evaluate(() => ({ sent: window.sculpt.stats.strokesSent, acks: window.sculpt.stats.acks,
    seq: window.sculpt.stats.globalSeq, errors: window.sculpt.stats.errors }));
  check('sculptor: every stroke acked over wss://', s.sent > 0 && s.acks === s.sent && s.errors.length === 0,
    JSON.stringify(s));
  await viewer.waitForFunction((seq) => window.sculpt.stats.globalSeq >= seq, s.seq, { timeout: 30000, polling: 100 });
  check('viewer: the drag reached it', s.seq > seqBefore);

  const plain = await browser.newPage();
  let refused = false;
  try { await plain.goto(`http://localhost:${httpPort}/`, { timeout: 10000 }); } catch { refused = true; }
  check('plain http:// to the HTTPS port gets no page', refused);
} catch (e) {
  check('https run', false, e.stack || String(e));
} finally {
  if (browser) await browser.close();
  await stopSculptd(sculptd);
}
process.exit(failures ? 1 : 0);
