// Runs sculptd for a browser test: on free loopback ports (TCP and HTTP, read back from its port
// file), its data under the test's temporary directory, its output beside the test's, and a
// watchdog that kills it and ends the test when the whole run exceeds its limit (a hung browser
// must not hold ctest until ctest's own timeout).
import { spawn } from 'node:child_process';
import { existsSync, readFileSync, rmSync } from 'node:fs';
import { join } from 'node:path';

const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

// Starts `sculptd serve` with --data DIR/data, both ports on 127.0.0.1:0 (HTTP on `http` when
// given), --web-root and `extra` arguments, and returns { server, watchdog, dir } at once (so that
// a failure while waiting can still stop it). `label` and `limitMs` name and bound the whole test.
export function startSculptd({ bin, webRoot, dir, extra = [], label, limitMs, http = '127.0.0.1:0' }) {
  const portFile = join(dir, 'ports');
  const server = spawn(join(bin, 'sculptd'), ['serve', '--data', join(dir, 'data'),
    '--listen', '127.0.0.1:0', '--http', http, '--port-file', portFile,
    '--web-root', webRoot, ...extra], { stdio: ['ignore', 'inherit', 'inherit'] });
  const watchdog = setTimeout(() => {
    console.error(`FAIL ${label} exceeded ${limitMs / 1000} s`);
    server.kill('SIGKILL');
    process.exit(1);
  }, limitMs);
  return { server, watchdog, dir, portFile };
}

// Resolves { tcpPort, httpPort } once sculptd's port file names both; throws after 30 s.
export async function sculptdPorts({ portFile }) {
  for (let i = 0; i < 300; ++i) {
    if (existsSync(portFile)) {
      const ports = readFileSync(portFile, 'utf8').trim().split('\n').map(Number);
      if (ports.length >= 2) return { tcpPort: ports[0], httpPort: ports[1] };
    }
    await sleep(100);
  }
  throw new Error('sculptd wrote no port file');
}

// Stops the watchdog and sculptd (SIGTERM, then waits for it to exit) and removes the directory.
export async function stopSculptd({ server, watchdog, dir }) {
  clearTimeout(watchdog);
  if (server.exitCode === null && server.signalCode === null) {
    const exited = new Promise((r) => server.once('exit', r));
    server.kill('SIGTERM');
    // Bounded: a member whose shutdown hangs must not hold the test until ctest's timeout.
    const killer = setTimeout(() => {
      console.error(`sculptd (${dir}) did not exit within 15 s of SIGTERM: killed`);
      server.kill('SIGKILL');
    }, 15000);
    await exited;
    clearTimeout(killer);
  }
  rmSync(dir, { recursive: true, force: true });
}
