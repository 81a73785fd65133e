// Takes a picture of a live session as a viewer sees it (used by `make demo`):
//   node screenshot.mjs URL OUT.png [WAIT_MS]
// Opens URL in Debian's headless Chromium, waits until the page has joined and decoded every
// chunk it was sent, waits WAIT_MS more (default 1500), then writes the screenshot.
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
  await new Promise((r) => setTimeout(r, Number(waitMs)));
  await page.screenshot({ path: out });
  const t = await page.evaluate(() => window.sculpt.meshes.totals());
  console.log(`screenshot ${out}: ${t.chunks} chunks, ${t.faces} triangles`);
} finally {
  await browser.close();
}
