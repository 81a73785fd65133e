// Browser test of rejoining through a member the page learnt from SceneInfo.cluster_members
// (issue 17): an etcd (Debian's etcd-server) and two sculptd members on loopback; a owns the
// scene and b follows it as its standby. The page is opened on a's own HTTP port with no
// #members fragment, so the only members it is told of are those a lists when it answers the
// join. It sculpts (acknowledged by a); then a is killed (SIGKILL) and the page sculpts on: its
// socket closes, a (the member it joined and the one that served the page) no longer answers,
// and the page must find b from the list it learnt, wait for b to take the scene over, rejoin
// there and have every stroke acknowledged by b, each applied exactly once. Usage:
//   node test/members_browser_test.mjs --bin BUILD/bin --web-root DIST
// Exits 0 with "skipped" when /usr/bin/etcd is missing; non-zero with the failing check's name.
import { execFileSync } from 'node:child_process';
import { rmSync } from 'node:fs';
import { join } from 'node:path';
import { launchChromium } from './chromium.mjs';
import { clusterTest, freePort, sleep, surfacePoint } from './cluster.mjs';
import { sculptdPorts, stopSculptd } from './sculptd.mjs';

const t = await clusterTest('members browser test', 220000);
const { bin, webRoot, dir, kPrefix, etcd, etcdGet, etcdJson, until, check } = t;
const [aHttp, bHttp] = [await freePort(), await freePort()];
const member = (name, http, otherHttp) => t.member(name, http, otherHttp, 200000);

// The scene's sequence as a viewer joining through `tcpAddress` finds it (`sculpt info`).
const sceneSeq = (tcpAddress) => JSON.parse(execFileSync(join(bin, 'sculpt'), ['info', '--server', tcpAddress],
  { encoding: 'utf8', timeout: 30000 })).global_seq;

let a, b, browser, page;
let stage = 'starting';
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
  const initialSeq = sceneSeq(`127.0.0.1:${aPorts.tcpPort}`);

  browser = await launchChromium();
  page = await browser.newPage({ viewport: { width: 480, height: 360 } });
  page.logs = [];
  page.on('console', (m) => page.logs.push(`${m.type()}: ${m.text()}`));
  page.on('pageerror', (e) => page.logs.push(`pageerror: ${e.message}`));
  stage = 'joining on a, the owner, without #members';
  await page.goto(`http://127.0.0.1:${aHttp}/#token=sculpt-dev-sculptor&role=sculptor&name=dora`);
  await page.waitForFunction(() => window.sculpt?.stats.state === 'joined' && window.sculpt.meshes.totals().chunks > 0
    && window.sculpt.framed && window.sculpt.meshes.decoding === 0, null, { timeout: 60000, polling: 100 });
  const first = await page.evaluate(() => ({ server: window.sculpt.stats.server, redirects: window.sculpt.stats.redirects,
    members: window.sculpt.opts.members, learnt: window.sculpt.stats.learntMembers }));
  check('the page joined on a directly, told of no member', first.server === `127.0.0.1:${aHttp}`
    && first.redirects === 0 && first.members.length === 0, JSON.stringify(first));
  check('a listed both members\' HTTP addresses', JSON.stringify([...first.learnt].sort())
    === JSON.stringify([`127.0.0.1:${aHttp}`, `127.0.0.1:${bHttp}`].sort()), JSON.stringify(first.learnt));

  stage = 'looking for the surface';
  const at = await surfacePoint(page);
  const drag = async (steps) => {
    await page.mouse.move(at[0], at[1]);
    await page.mouse.down();
    for (let i = 0; i <= steps; ++i) { await page.mouse.move(at[0] + 3 * (i % 7), at[1] + (i % 7)); await sleep(20); }
    await page.mouse.up();
  };
  const stats = () => page.evaluate(() => {
    const s = window.sculpt.stats;
    return { state: s.state, sent: s.strokesSent, poses: s.posesSent, acks: s.acks, refused: s.strokesRefused || 0,
      reconnects: s.reconnects, resent: s.resent, server: s.server, member: s.member,
      unanswered: window.sculpt.outbox?.size ?? 0, pending: window.sculpt.sculpting.pending.size,
      globalSeq: s.globalSeq, notice: s.notice, errors: s.errors };
  });

  stage = 'first drag, on a';
  await drag(6);
  await page.waitForFunction(() => window.sculpt.stats.acks > 0 && (window.sculpt.outbox?.size ?? 0) === 0
    && window.sculpt.sculpting.pending.size === 0, null, { timeout: 30000, polling: 100 });
  const before = await stats();
  check('the first drag acknowledged by a', before.sent > 0 && before.acks === before.sent && before.refused === 0,
    JSON.stringify(before));
  // Replication is asynchronous here: b must hold what a acknowledged before a dies.
  stage = 'waiting for b\'s copy';
  await until('b\'s copy did not catch up', async () => (await etcdJson(`${kPrefix}members/b`))?.follow_seq >= before.globalSeq,
    15000);

  stage = 'killing a';
  a.server.kill('SIGKILL');
  await page.waitForFunction(() => window.sculpt.stats.reconnects > 0, null, { timeout: 10000, polling: 50 });
  await drag(8);  // made while the page reconnects: kept, sent once it has rejoined
  stage = 'waiting for b to take the scene';
  const owner = await until('b did not take the scene over', async () => {
    const o = await etcdJson(`${kPrefix}scenes/default/owner`);
    return o?.member === 'b' ? o : null;
  }, 30000);
  check('b owns the scene at epoch 2', owner.epoch === 2, JSON.stringify(owner));
  stage = 'waiting for every stroke to be acknowledged after the reconnection';
  await page.waitForFunction(() => window.sculpt.stats.state === 'joined' && (window.sculpt.outbox?.size ?? 0) === 0
    && window.sculpt.sculpting.pending.size === 0 && !window.sculpt.sculpting.dragging,
  null, { timeout: 60000, polling: 100 }).catch(() => console.log('not every stroke answered within 60 s'));
  const after = await stats();
  console.log(`page: ${JSON.stringify({ ...after, errors: undefined })}`);
  check('the page reconnected to b, which it learnt from a', after.reconnects >= 1 && after.server === `127.0.0.1:${bHttp}`,
    `${after.reconnects} reconnections, on ${after.server}`);
  check('every stroke acknowledged, none refused', after.acks === after.sent && after.refused === 0
    && after.sent > before.sent, JSON.stringify(after));
  check('the page said it reconnected', /^reconnected to .*\(all acknowledged\)$/.test(after.notice), after.notice);
  check('no error shown to the user', after.errors.length === 0, JSON.stringify(after.errors));
  stage = 'reading the scene on b';
  const bRecord = await etcdJson(`${kPrefix}members/b`);
  const seq = sceneSeq(bRecord.tcp);
  check('each stroke applied exactly once: the scene\'s sequence is one edit per pose sent',
    seq === initialSeq + after.poses, `scene at seq ${seq}, initial ${initialSeq} + ${after.poses} poses`);
  const bad = page.logs.filter((l) => l.startsWith('pageerror') || l.includes('Content Security Policy'));
  check('no page errors or CSP violations', bad.length === 0, bad.join(' | '));
} catch (err) {
  check(`members run (${stage})`, false, err.stack || String(err));
  if (page) {
    console.error(`page:\n  ${(page.logs || []).slice(-15).join('\n  ')}`);
    console.error(`  stats: ${await page.evaluate(() => JSON.stringify({ ...window.sculpt?.stats, ackLatencies: undefined,
      unanswered: window.sculpt?.outbox?.size })).catch((e) => e.message)}`);
  }
} finally {
  if (browser) await browser.close();
  if (b) await stopSculptd(b);
  if (a) await stopSculptd(a);
  etcd.kill('SIGKILL');
  rmSync(dir, { recursive: true, force: true });
}
console.log(t.failures === 0 ? 'members browser test: all passed' : `members browser test: ${t.failures} failed`);
process.exit(t.failures === 0 ? 0 : 1);
