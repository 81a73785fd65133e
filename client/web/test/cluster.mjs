// What the cluster browser tests share: their arguments, the check counter, free ports, an etcd
// (Debian's etcd-server) read through its v3 JSON gateway, polling, and sculptd members on
// loopback (sculptd.mjs) configured for that etcd. A test missing /usr/bin/etcd exits 0 saying
// it was skipped.
import { spawn } from 'node:child_process';
import { existsSync, mkdirSync, mkdtempSync, writeFileSync } from 'node:fs';
import { createServer } from 'node:net';
import { tmpdir } from 'node:os';
import { join } from 'node:path';
import { chromiumPath } from './chromium.mjs';
import { startSculptd } from './sculptd.mjs';

export const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

// A port the kernel just handed out and released (etcd and the HTTP ports must be named up
// front: each member's --http-allow-origin names the other's page origin).
export const freePort = () => new Promise((resolve, reject) => {
  const s = createServer();
  s.once('error', reject);
  s.listen(0, '127.0.0.1', () => { const { port } = s.address(); s.close(() => resolve(port)); });
});

const b64 = (text) => Buffer.from(text).toString('base64');
const kEtcdBinary = '/usr/bin/etcd';

// Reads --bin and --web-root, checks Chromium and etcd, makes the test's temporary directory and
// starts etcd in it. `name` is the test's name in its messages ("failover browser test"); past
// `limitMs` the whole test fails saying so (under ctest's TIMEOUT, so the log says where it hung).
export async function clusterTest(name, limitMs) {
  setTimeout(() => {
    console.error(`FAIL ${name} exceeded ${limitMs / 1000} s`);
    process.exit(1);
  }, limitMs).unref();
  const args = Object.fromEntries(process.argv.slice(2).reduce((acc, a, i, all) =>
    (a.startsWith('--') ? [...acc, [a.slice(2), all[i + 1]]] : acc), []));
  const { bin } = args;
  const webRoot = args['web-root'];
  if (!bin || !webRoot) { console.error('usage: --bin DIR --web-root DIR'); process.exit(2); }
  if (!existsSync(chromiumPath)) { console.error(`${chromiumPath} missing`); process.exit(1); }
  if (!existsSync(kEtcdBinary)) {
    console.log(`${name}: skipped (${kEtcdBinary} missing: install Debian's etcd-server)`);
    process.exit(0);
  }
  const t = { name, bin, webRoot, failures: 0, kPrefix: 't/' };
  t.check = (what, ok, detail = '') => {
    console.log(`${ok ? 'ok  ' : 'FAIL'} ${what}${detail ? `: ${detail}` : ''}`);
    if (!ok) t.failures += 1;
  };
  t.dir = mkdtempSync(join(tmpdir(), `sculpt-${name.split(' ')[0]}-browser-`));
  const [etcdPort, peerPort] = [await freePort(), await freePort()];
  t.etcdUrl = `http://127.0.0.1:${etcdPort}`;
  const peerUrl = `http://127.0.0.1:${peerPort}`;
  t.etcd = spawn(kEtcdBinary, ['--name', 't', '--data-dir', join(t.dir, 'etcd'), '--listen-client-urls', t.etcdUrl,
    '--advertise-client-urls', t.etcdUrl, '--listen-peer-urls', peerUrl, '--initial-advertise-peer-urls', peerUrl,
    '--initial-cluster', `t=${peerUrl}`], { stdio: 'ignore' });
  // The value of `key`, or null (absent, or etcd not answering yet).
  t.etcdGet = async (key) => {
    try {
      const res = await fetch(`${t.etcdUrl}/v3/kv/range`, { method: 'POST', body: JSON.stringify({ key: b64(key) }),
        signal: AbortSignal.timeout(1000) });
      if (!res.ok) return null;
      const body = await res.json();
      return body.kvs && body.kvs.length ? Buffer.from(body.kvs[0].value, 'base64').toString() : '';
    } catch { return null; }
  };
  t.etcdJson = async (key) => {
    const v = await t.etcdGet(key);
    try { return v ? JSON.parse(v) : null; } catch { return null; }
  };
  // fn()'s first truthy value, polled every 100 ms; throws "`what` within N s" past limitMs.
  t.until = async (what, fn, limitMs) => {
    const end = Date.now() + limitMs;
    for (;;) {
      const v = await fn();
      if (v) return v;
      if (Date.now() > end) throw new Error(`${what} within ${limitMs / 1000} s`);
      await sleep(100);
    }
  };
  // Member `memberName` on HTTP port `http` (fixed: a promoted standby runs again with the same
  // command line and keeps its address), lease TTL 2 s. The other member's pages may open /ws
  // here (the Origin check), and this member's pages may open /ws there (the page's
  // Content-Security-Policy connect-src).
  t.member = (memberName, http, otherHttp, limitMs) => {
    const mdir = join(t.dir, memberName);
    mkdirSync(mdir);
    writeFileSync(join(mdir, 'config.toml'), `[cluster]\netcd = ["${t.etcdUrl}"]\nmember = "${memberName}"\n`
      + `lease_ttl_ms = 2000\nprefix = "${t.kPrefix}"\n`);
    return startSculptd({ bin, webRoot, dir: mdir, http: `127.0.0.1:${http}`, label: `${name} (${memberName})`,
      limitMs, extra: ['--config', join(mdir, 'config.toml'), '--http-allow-origin', `http://127.0.0.1:${otherHttp}`] });
  };
  return t;
}

// A point of the page's canvas where a drag starts on the object (the point and one 18 px to its
// right both hit it), searched around the view's centre; throws after 30 s.
export async function surfacePoint(page) {
  return (await page.waitForFunction(() => {
    for (const [dx, dy] of [[0, 0], [-30, 0], [30, 0], [0, -30], [0, 30], [-60, 20], [60, -20]]) {
      const x = 240 + dx, y = 180 + dy;
      if (window.sculpt.sculpting.hit({ clientX: x, clientY: y })
        && window.sculpt.sculpting.hit({ clientX: x + 18, clientY: y + 6 })) return [x, y];
    }
    return null;
  }, null, { timeout: 30000, polling: 200 })).jsonValue();
}
