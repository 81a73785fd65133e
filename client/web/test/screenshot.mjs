// Takes a picture of a live session as a viewer sees it (used by `make demo`):
//   node screenshot.mjs URL OUT.png [WAIT_MS]
// Opens URL in Debian's headless Chromium, waits until the page has joined and no chunk it had
// not seen has arrived for WAIT_MS (default 1500; at most 20 s: a busy server meshes a restarted
// scene for a new viewer as its background thread gets the core), and every chunk is decoded,
// then writes the screenshot.
import { launchChromium } from './chromium.mjs';

const [url, out, waitMs = '1500'] = process.argv.slice(2);
if (!url || !out) { console.error('usage: node screenshot.mjs URL OUT.png [WAIT_MS]'); process.exit(2); }
const browser = await launchChromium();
try {
  const page = await browser.newPage({ viewport: { width: 1024, height: 720 } });
  await page.goto(url);
  await page.waitForFunction(() => window.sculpt?.stats.state === 'joined'
    && window.sculpt.meshes.totals().chunks > 0 && window.sculpt.meshes.decoding === 0,
  null, { timeout: 20000, polling: 100 });
  // Picture the whole object, not the part of it meshed so far.
  const end = Date.now() + 20000;
  let chunks = -1;
  let since = Date.now();
  while (Date.now() < end) {
    const now = await page.evaluate(() => window.sculpt.meshes.totals().chunks);
    if (now !== chunks) { chunks = now; since = Date.now(); }
    if (Date.now() - since >= Number(waitMs)) break;
    await new Promise((r) => setTimeout(r, 100));
  }
  await page.waitForFunction(() => window.sculpt.meshes.decoding === 0, null, { timeout: 10000, polling: 50 });
  await page.screenshot({ path: out });
  const t = await page.evaluate(() => window.sculpt.meshes.totals());
  console.log(`screenshot ${out}: ${t.chunks} chunks, ${t.faces} triangles`);
} finally {
  await browser.close();
}
