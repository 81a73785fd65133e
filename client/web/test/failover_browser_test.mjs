// Browser test of a failover in cluster mode (issue 17): an etcd (Debian's etcd-server) and two
// sculptd members on loopback; a owns the scene and b follows it as its standby. The page, opened
// on b and redirected to a, sculpts (acknowledged by a); then a is paused (SIGSTOP) while the page
// keeps sculpting, so those strokes wait unanswered in a's socket; b takes the scene over (epoch
// 2) and a is resumed: a refuses the waiting strokes with UNAVAILABLE (its lease is gone) and
// would refuse every later one until they are resent. The page must reconnect (through the
// members it knows, following redirects to b), resend every unacknowledged stroke in order with
// the same client id and client_seq, send the strokes made while it reconnected after them, and
// end with every stroke acknowledged, none refused, and each applied exactly once: the scene's
// sequence on b is the initial one plus one edit per pose the page sent. Then a page whose socket
// (answered by the test) closes with strokes unanswered: it rejoins with the same client id and
// writes the unanswered strokes again in order, before the ones made meanwhile. Usage:
//   node test/failover_browser_test.mjs --bin BUILD/bin --web-root DIST
// Exits 0 with "skipped" when /usr/bin/etcd is missing; non-zero with the failing check's name.
import { execFileSync } from 'node:child_process';
import { rmSync } from 'node:fs';
import { join } from 'node:path';
import { launchChromium } from './chromium.mjs';
import { clusterTest, freePort, sleep, surfacePoint } from './cluster.mjs';
import { sculptdPorts, stopSculptd } from './sculptd.mjs';

const t = await clusterTest('failover browser test', 220000);
const { bin, webRoot, dir, kPrefix, etcd, etcdGet, etcdJson, until, check } = t;
const [aHttp, bHttp] = [await freePort(), await freePort()];
const member = (name, http, otherHttp) => t.member(name, http, otherHttp, 200000);

// The scene's sequence as a viewer joining through `tcpPort` finds it (`sculpt info --server`,
// which follows one redirect to the owner).
const sceneSeq = (tcpPort) => JSON.parse(execFileSync(join(bin, 'sculpt'), ['info', '--server', `127.0.0.1:${tcpPort}`],
  { encoding: 'utf8', timeout: 30000 })).global_seq;

let a, b, browser, page;
let stage = 'starting';
let paused = false;
try {
  await until('etcd did not answer', async () => (await etcdGet('ping')) !== null, 20000);
  a = member('a', aHttp, bHttp);
  const aPorts = await sculptdPorts(a);
  await until('a did not take the scene', async () => (await etcdJson(`${kPrefix}scenes/default/owner`))?.member === 'a', 10000);
  b = member('b', bHttp, aHttp);
  await sculptdPorts(b);
  stage = 'waiting for b to follow a';
  await until('b did not become a\'s standby', async () => {
    const standby = await etcdJson(`${kPrefix}scenes/default/standby`);
    const m = await etcdJson(`${kPrefix}members/b`);
    return standby?.member === 'b' && m?.follows === 'default';
  }, 30000);
  const initialSeq = sceneSeq(aPorts.tcpPort);

  browser = await launchChromium();
  page = await browser.newPage({ viewport: { width: 480, height: 360 } });
  page.logs = [];
  page.on('console', (m) => page.logs.push(`${m.type()}: ${m.text()}`));
  page.on('pageerror', (e) => page.logs.push(`pageerror: ${e.message}`));
  stage = 'joining through b';
  await page.goto(`http://127.0.0.1:${bHttp}/#token=sculpt-dev-sculptor&role=sculptor&name=alice`);
  await page.waitForFunction(() => window.sculpt?.stats.state === 'joined' && window.sculpt.meshes.totals().chunks > 0
    && window.sculpt.framed && window.sculpt.meshes.decoding === 0, null, { timeout: 60000, polling: 100 });
  const first = await page.evaluate(() => ({ server: window.sculpt.stats.server, member: window.sculpt.stats.member }));
  check('the page joined on a', first.member === 'a' && first.server === `127.0.0.1:${aHttp}`, JSON.stringify(first));

  stage = 'looking for the surface';
  const at = await surfacePoint(page);
  // A drag of `steps` moves; each 60 Hz flush sends what was sampled as one stroke.
  const drag = async (steps) => {
    await page.mouse.move(at[0], at[1]);
    await page.mouse.down();
    for (let i = 0; i <= steps; ++i) { await page.mouse.move(at[0] + 3 * (i % 7), at[1] + (i % 7)); await sleep(20); }
    await page.mouse.up();
  };
  const stats = () => page.evaluate(() => {
    const s = window.sculpt.stats;
    return { state: s.state, sent: s.strokesSent, poses: s.posesSent, acks: s.acks, refused: s.strokesRefused || 0,
      duplicates: s.duplicateAcks || 0, queued: s.strokesQueued || 0, reconnects: s.reconnects, resent: s.resent, server: s.server, member: s.member,
      unanswered: window.sculpt.outbox?.size ?? window.sculpt.sculpting.pending.size,
      pending: window.sculpt.sculpting.pending.size, globalSeq: s.globalSeq,
      notice: s.notice, errors: s.errors };
  });

  stage = 'first drag, on a';
  await drag(6);
  await page.waitForFunction(() => window.sculpt.stats.acks > 0 && (window.sculpt.outbox?.size ?? 0) === 0
    && window.sculpt.sculpting.pending.size === 0, null, { timeout: 30000, polling: 100 });
  const before = await stats();
  check('the first drag acknowledged by a', before.sent > 0 && before.acks === before.sent && before.refused === 0,
    JSON.stringify(before));
  // Replication is asynchronous here: b must hold what a acknowledged before a stops.
  stage = 'waiting for b\'s copy';
  await until('b\'s copy did not catch up', async () => (await etcdJson(`${kPrefix}members/b`))?.follow_seq >= before.globalSeq,
    15000);

  stage = 'sculpting on the paused owner';
  a.server.kill('SIGSTOP');
  paused = true;
  await drag(8);  // these strokes wait, unanswered, in a's socket
  const during = await stats();
  check('strokes sent to the paused owner are unanswered', during.sent > before.sent && during.unanswered > 0,
    JSON.stringify(during));
  stage = 'waiting for b to take the scene';
  const owner = await until('b did not take the scene over', async () => {
    const o = await etcdJson(`${kPrefix}scenes/default/owner`);
    return o?.member === 'b' ? o : null;
  }, 20000);
  check('b owns the scene at epoch 2', owner.epoch === 2, JSON.stringify(owner));

  // The page sculpts on across the refusal and the reconnection: a drag begun before a resumes,
  // held until the page has rejoined, so part of it is made while the page reconnects.
  stage = 'resuming a while the page sculpts';
  const queuedFrom = (await stats()).sent;
  await page.mouse.move(at[0], at[1]);
  await page.mouse.down();
  let step = 0;
  const move = async () => { step += 1; await page.mouse.move(at[0] + 3 * (step % 7), at[1] + (step % 7)); await sleep(20); };
  for (let i = 0; i < 3; ++i) await move();
  a.server.kill('SIGCONT');
  paused = false;
  // a refuses the waiting strokes (UNAVAILABLE): the page reconnects.
  const end = Date.now() + 30000;
  while (Date.now() < end && !(await page.evaluate(() => window.sculpt.stats.reconnects > 0
    && ['joined', 'resending'].includes(window.sculpt.stats.state)))) await move();
  for (let i = 0; i < 5; ++i) await move();
  await page.mouse.up();
  stage = 'waiting for every stroke to be acknowledged after the reconnection';
  // Not thrown on: the checks below say what is missing (a page without the resend never gets there).
  await page.waitForFunction(() => window.sculpt.stats.state === 'joined' && (window.sculpt.outbox?.size ?? 0) === 0
    && window.sculpt.sculpting.pending.size === 0 && !window.sculpt.sculpting.dragging,
  null, { timeout: 60000, polling: 100 }).catch(() => console.log('not every stroke answered within 60 s'));
  const after = await stats();
  console.log(`page: ${JSON.stringify({ ...after, errors: undefined })}`);
  check('every stroke acknowledged, none refused', after.acks === after.sent && after.refused === 0
    && after.sent > queuedFrom, JSON.stringify(after));
  check('strokes made while reconnecting were kept and sent after the resend', after.queued > 0,
    `${after.queued} of the ${after.sent - queuedFrom} strokes of the last drag made while reconnecting`);
  check('the page reconnected to b', after.reconnects >= 1 && after.server === `127.0.0.1:${bHttp}`,
    `${after.reconnects} reconnections, on ${after.server}`);
  check('the strokes a left unanswered were resent', after.resent >= during.sent - before.sent,
    `${after.resent} resent, ${during.sent - before.sent} sent to the paused owner`);
  check('the page said it reconnected and resent', /^reconnected to .*, resent \d+ strokes? \(all acknowledged\)$/.test(after.notice),
    after.notice);
  check('the refusal was no error shown to the user', after.errors.length === 0, JSON.stringify(after.errors));
  check('the console named the refusal', page.logs.some((l) => l.includes('UNAVAILABLE')),
    page.logs.filter((l) => l.includes('sculpt:')).slice(-8).join(' | '));
  stage = 'reading the scene on b';
  const seq = sceneSeq(aPorts.tcpPort);  // a redirects to b now
  check('each stroke applied exactly once: the scene\'s sequence is one edit per pose sent',
    seq === initialSeq + after.poses, `scene at seq ${seq}, initial ${initialSeq} + ${after.poses} poses`);
  const bad = page.logs.filter((l) => l.startsWith('pageerror') || l.includes('Content Security Policy'));
  check('no page errors or CSP violations', bad.length === 0, bad.join(' | '));

  // The other way a member goes: its connection closes (kill -9, a restart) with strokes
  // unanswered. The page's /ws is answered here (playwright's routeWebSocket): the first socket
  // acknowledges strokes 1-3 and closes after the 6th; the page must rejoin with the same client
  // id and write 4, 5, 6 again, in order, before the strokes made after the close.
  stage = 'a socket that closes with strokes unanswered';
  const { sculpt: { v1 } } = await import('../gen/sculpt_pb.js');
  const mock = await browser.newPage({ viewport: { width: 320, height: 240 } });
  mock.logs = [];
  mock.on('console', (m) => mock.logs.push(`${m.type()}: ${m.text()}`));
  const sockets = [];  // per socket: { clientId, strokes: [client_seq] }
  await mock.routeWebSocket(/\/ws$/, (ws) => {
    const me = { clientId: '', strokes: [] };
    sockets.push(me);
    const first = sockets.length === 1;
    const send = (body, value) => ws.send(Buffer.from(v1.ServerMessage.encode(v1.ServerMessage.create({ [body]: value })).finish()));
    ws.onMessage((data) => {
      const m = v1.ClientMessage.decode(typeof data === 'string' ? Buffer.from(data) : data);
      if (m.body === 'hello') {
        me.clientId = String(m.hello.clientId);
        send('welcome', { protocolVersion: 1, sessionId: sockets.length, role: v1.Role.ROLE_SCULPTOR,
          clientId: m.hello.clientId, maxPosesPerStroke: 32, maxStrokesPerSecond: 240 });
      } else if (m.body === 'join') {
        send('sceneInfo', { scene: 'default', globalSeq: 0, minToolSize: 0.5, maxToolSize: 16, maxSpeed: 10,
          objects: [{ name: 'clay', voxelSize: 0.25, halfWidth: 3 }] });
      } else if (m.body === 'stroke') {
        const seq = Number(m.stroke.clientSeq);
        me.strokes.push(seq);
        if (!first || seq <= 3) send('ack', { clientSeq: seq, globalSeqFirst: seq, edits: 1 });
        if (first && me.strokes.length === 6) ws.close();
      }
    });
  });
  await mock.goto(`http://127.0.0.1:${bHttp}/#token=sculpt-dev-sculptor&role=sculptor&name=carol`);
  await mock.waitForFunction(() => window.sculpt?.stats.state === 'joined' && window.sculpt.sculpting, null,
    { timeout: 30000, polling: 50 });
  const strokeFrom = (n) => mock.evaluate((k) => {
    for (let i = 0; i < k; ++i) window.sculpt.sculpting.sendStroke([{ x: i, y: 0, z: 20, t: 0 }], 1);
  }, n);
  await strokeFrom(6);
  await mock.waitForFunction(() => window.sculpt.stats.reconnects > 0, null, { timeout: 10000, polling: 5 });
  await strokeFrom(2);  // made while reconnecting
  await mock.waitForFunction(() => window.sculpt.stats.state === 'joined' && window.sculpt.outbox.size === 0,
    null, { timeout: 30000, polling: 50 }).catch(() => {});
  const m = await mock.evaluate(() => ({ sent: window.sculpt.stats.strokesSent, acks: window.sculpt.stats.acks,
    resent: window.sculpt.stats.resent, notice: window.sculpt.stats.notice, errors: window.sculpt.stats.errors }));
  check('closed socket: one client id on both sockets', sockets.length === 2 && sockets[0].clientId === sockets[1].clientId,
    JSON.stringify(sockets));
  check('closed socket: the unanswered strokes resent in order, then the new ones',
    JSON.stringify(sockets[1]?.strokes) === JSON.stringify([4, 5, 6, 7, 8]), JSON.stringify(sockets.map((x) => x.strokes)));
  check('closed socket: every stroke acknowledged, 3 resent, said so', m.sent === 8 && m.acks === 8 && m.resent === 3
    && /resent 3 strokes \(all acknowledged\)$/.test(m.notice), JSON.stringify(m));
} catch (err) {
  check(`failover run (${stage})`, false, err.stack || String(err));
  if (page) {
    console.error(`page:\n  ${(page.logs || []).slice(-15).join('\n  ')}`);
    console.error(`  stats: ${await page.evaluate(() => JSON.stringify({ ...window.sculpt?.stats, ackLatencies: undefined,
      unanswered: window.sculpt?.outbox?.size })).catch((e) => e.message)}`);
  }
} finally {
  if (paused) a.server.kill('SIGCONT');
  if (browser) await browser.close();
  if (b) await stopSculptd(b);
  if (a) await stopSculptd(a);
  etcd.kill('SIGKILL');
  rmSync(dir, { recursive: true, force: true });
}
console.log(t.failures === 0 ? 'failover browser test: all passed' : `failover browser test: ${t.failures} failed`);
process.exit(t.failures === 0 ? 0 : 1);
