// Browser test of redirects in cluster mode (issue 17): an etcd (Debian's etcd-server) and two
// sculptd members a and b started here on loopback; a owns the scene, the page is opened on b,
// follows b's Redirect by opening /ws on a's HTTP address, says so in its notice line, joins
// there, and its drag is acknowledged by a (and is in a's history). Then, with the page's socket
// answered by the test (a forged redirect loop, a redirect without an HTTP address): the page
// stops after three redirects with a clear error. Usage:
//   node test/redirect_browser_test.mjs --bin BUILD/bin --web-root DIST
// Exits 0 with "skipped" when /usr/bin/etcd is missing; non-zero with the failing check's name.
import { execFileSync } from 'node:child_process';
import { rmSync } from 'node:fs';
import { join } from 'node:path';
import { launchChromium } from './chromium.mjs';
import { clusterTest, freePort, sleep, surfacePoint } from './cluster.mjs';
import { sculptdPorts, stopSculptd } from './sculptd.mjs';

const t = await clusterTest('redirect browser test', 165000);
const { bin, webRoot, dir, kPrefix, etcd, etcdGet, etcdJson, until, check } = t;
const [aHttp, bHttp] = [await freePort(), await freePort()];
const member = (name, http, otherHttp) => t.member(name, http, otherHttp, 150000);

let a, b, browser;
let stage = 'starting';
try {
  await until('etcd did not answer', async () => (await etcdGet('ping')) !== null, 20000);
  a = member('a', aHttp, bHttp);
  const aPorts = await sculptdPorts(a);
  const owner = await until('a did not take the scene', async () => {
    const v = await etcdGet(`${kPrefix}scenes/default/owner`);
    return v ? JSON.parse(v) : null;
  }, 10000);
  check('a owns the scene', owner.member === 'a', JSON.stringify(owner));
  b = member('b', bHttp, aHttp);
  const bPorts = await sculptdPorts(b);
  await until('b did not register', async () => !!(await etcdGet(`${kPrefix}members/b`)), 10000);
  // b routes to a once it has read a's owner key (its table is re-read every lease_ttl_ms / 4):
  // the C++ client (`sculpt history`, which follows one redirect) gets through b then.
  await until('b did not route to a', async () => {
    try {
      execFileSync(join(bin, 'sculpt'), ['history', '--server', `127.0.0.1:${bPorts.tcpPort}`, '--timeout', '5'],
        { stdio: 'ignore' });
      return true;
    } catch { return false; }
  }, 15000);

  browser = await launchChromium();
  const page = await browser.newPage({ viewport: { width: 480, height: 360 } });
  page.logs = [];
  page.sockets = [];
  page.on('console', (m) => page.logs.push(`${m.type()}: ${m.text()}`));
  page.on('pageerror', (e) => page.logs.push(`pageerror: ${e.message}`));
  page.on('websocket', (ws) => page.sockets.push(ws.url()));
  stage = 'joining through b';
  await page.goto(`http://127.0.0.1:${bHttp}/#token=sculpt-dev-sculptor&role=sculptor&name=alice`);
  await page.waitForFunction(() => ['joined', 'refused'].includes(window.sculpt?.stats.state)
    && (window.sculpt.stats.state === 'refused' || (window.sculpt.meshes.totals().chunks > 0 && window.sculpt.framed
      && window.sculpt.meshes.decoding === 0)),
  null, { timeout: 60000, polling: 100 });
  const joined = await page.evaluate(() => ({ state: window.sculpt.stats.state, server: window.sculpt.stats.server,
    redirects: window.sculpt.stats.redirects, member: window.sculpt.stats.member, errors: window.sculpt.stats.errors,
    notice: document.getElementById('notice').textContent, shown: !document.getElementById('notice').hidden }));
  check('page opened on b joined on a after one redirect', joined.state === 'joined' && joined.redirects === 1
    && joined.member === 'a' && joined.server === `127.0.0.1:${aHttp}`, JSON.stringify(joined));
  check('the sockets: b\'s /ws, then a\'s', JSON.stringify(page.sockets)
    === JSON.stringify([`ws://127.0.0.1:${bHttp}/ws`, `ws://127.0.0.1:${aHttp}/ws`]), JSON.stringify(page.sockets));
  check('the notice names the member', joined.shown && joined.notice.includes('member a'), joined.notice);
  check('a redirect is no error', joined.errors.length === 0, JSON.stringify(joined.errors));
  check('the console said "reconnecting"', page.logs.some((l) => /is on member a at .*, reconnecting/.test(l)),
    page.logs.filter((l) => l.includes('sculpt:')).join(' | '));

  // A point of the page where the pointer is on the surface (the view settles after framing).
  stage = 'looking for the surface';
  const at = await surfacePoint(page);
  await page.mouse.move(at[0], at[1]);
  await page.mouse.down();
  for (let i = 0; i <= 6; ++i) { await page.mouse.move(at[0] + 3 * i, at[1] + i); await sleep(15); }
  await page.mouse.up();
  stage = 'waiting for the drag\'s acks';
  await page.waitForFunction(() => window.sculpt.stats.acks > 0 && window.sculpt.sculpting.pending.size === 0,
    null, { timeout: 30000, polling: 100 });
  stage = 'mocked sockets';
  const s = await page.evaluate(() => ({ sent: window.sculpt.stats.strokesSent, acks: window.sculpt.stats.acks,
    errors: window.sculpt.stats.errors }));
  check('every stroke acked by the owner', s.sent > 0 && s.acks === s.sent && s.errors.length === 0, JSON.stringify(s));
  const history = JSON.parse(execFileSync(join(bin, 'sculpt'), ['history', '--server', `127.0.0.1:${aPorts.tcpPort}`,
    '--json', '--limit', '100'], { encoding: 'utf8' }));
  check('a\'s history holds the page\'s strokes', (history.entries || []).length === s.sent,
    `${(history.entries || []).length} entries, ${s.sent} sent`);
  const bad = page.logs.filter((l) => l.startsWith('pageerror') || l.includes('Content Security Policy'));
  check('no page errors or CSP violations', bad.length === 0, bad.join(' | '));

  // Members that keep redirecting (a forged answer, or owners that disagree): the page's /ws is
  // answered here (playwright's routeWebSocket) by Welcome and then a Redirect for every
  // JoinScene, back to the same address; the page gives up after kMaxRedirects with a clear error.
  const { sculpt: { v1 } } = await import('../gen/sculpt_pb.js');
  const mocked = async (redirect) => {
    const p = await browser.newPage({ viewport: { width: 320, height: 240 } });
    p.logs = [];
    p.on('console', (m) => p.logs.push(`${m.type()}: ${m.text()}`));
    p.joins = 0;
    p.clientIds = new Set();
    await p.routeWebSocket(/\/ws$/, (ws) => {
      const send = (body, value) => ws.send(Buffer.from(v1.ServerMessage.encode(
        v1.ServerMessage.create({ [body]: value })).finish()));
      ws.onMessage((data) => {
        const m = v1.ClientMessage.decode(typeof data === 'string' ? Buffer.from(data) : data);
        if (m.body === 'hello') {
          p.clientIds.add(String(m.hello.clientId));
          send('welcome', { protocolVersion: 1, sessionId: 7, role: v1.Role.ROLE_SCULPTOR, clientId: m.hello.clientId });
        } else if (m.body === 'join') {
          p.joins += 1;
          send('redirect', redirect);
          send('bye', { reason: 'redirected' });
          ws.close();
        }
      });
    });
    await p.goto(`http://127.0.0.1:${bHttp}/#token=sculpt-dev-sculptor&role=sculptor&name=bob`);
    await p.waitForFunction(() => window.sculpt?.stats.state === 'refused', null, { timeout: 30000, polling: 100 });
    return { page: p, errors: await p.evaluate(() => window.sculpt.stats.errors) };
  };
  const loop = await mocked({ scene: 'default', member: 'x', tcpAddress: '127.0.0.1:9', httpAddress: `127.0.0.1:${bHttp}`, epoch: 4 });
  check('redirect loop: refused after 3 redirects followed, naming the last member', loop.page.joins === 4
    && loop.errors.length === 1 && /redirected 4 times in a row \(last to member x at 127\.0\.0\.1:\d+, epoch 4\)/.test(loop.errors[0]),
  `${loop.page.joins} joins: ${JSON.stringify(loop.errors)}`);
  check('redirect loop: one client id on every member', loop.page.clientIds.size === 1, [...loop.page.clientIds].join());
  check('redirect loop: the notice is cleared', await loop.page.evaluate(() => document.getElementById('notice').hidden));
  const noHttp = await mocked({ scene: 'default', member: 'y', tcpAddress: '127.0.0.1:9', httpAddress: '', epoch: 2 });
  check('redirect to a member without an HTTP port: refused, saying so', noHttp.page.joins === 1
    && noHttp.errors.length === 1 && noHttp.errors[0].includes('member y, which has no HTTP port'), JSON.stringify(noHttp.errors));
} catch (err) {
  check(`redirect run (${stage})`, false, err.stack || String(err));
  for (const p of browser ? browser.contexts().flatMap((c) => c.pages()) : []) {
    console.error(`page ${p.url()}:\n  ${(p.logs || []).slice(-10).join('\n  ')}`);
    console.error(`  stats: ${await p.evaluate(() => JSON.stringify({ ...window.sculpt?.stats, ackLatencies: undefined }))
      .catch((e) => e.message)}`);
  }
} finally {
  if (browser) await browser.close();
  if (b) await stopSculptd(b);
  if (a) await stopSculptd(a);
  etcd.kill('SIGKILL');
  rmSync(dir, { recursive: true, force: true });
}
console.log(t.failures === 0 ? 'redirect browser test: all passed' : `redirect browser test: ${t.failures} failed`);
process.exit(t.failures === 0 ? 0 : 1);
