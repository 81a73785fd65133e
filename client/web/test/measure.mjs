// Measures the web client against a running sculptd (not a test; prints JSON):
//   node test/measure.mjs HTTP_URL [SECONDS]
// Time from opening the page to the first full mesh, Draco chunk decode p50/p99 in Chromium,
// and, while SECONDS pass, the viewer's received bytes per second and frame time.
import { launchChromium } from './chromium.mjs';

const [base, seconds = '10'] = process.argv.slice(2);
if (!base) { console.error('usage: node measure.mjs http://HOST:PORT/ [SECONDS]'); process.exit(2); }
const browser = await launchChromium();
try {
  const page = await browser.newPage({ viewport: { width: 1024, height: 720 } });
  const t0 = Date.now();
  await page.goto(`${base}#role=viewer&token=${process.env.TOKEN || 'sculpt-dev-viewer'}&name=measure`);
  await page.waitForFunction(() => window.sculpt?.stats.state === 'joined'
    && window.sculpt.meshes.totals().chunks > 0 && window.sculpt.meshes.decoding === 0,
  null, { timeout: 60000, polling: 20 });
  const firstMeshMs = Date.now() - t0;
  const bytes0 = await page.evaluate(() => window.sculpt.conn.bytesIn);
  const frames0 = await page.evaluate(() => window.sculpt.stats.frames || 0);
  await new Promise((r) => setTimeout(r, Number(seconds) * 1000));
  const r = await page.evaluate(([b0, f0, s]) => {
    const d = [...window.sculpt.meshes.decodeMs].sort((a, b) => a - b);
    const q = (p) => d[Math.min(d.length - 1, Math.floor(p * d.length))];
    return { chunks_decoded: d.length, decode_p50_ms: q(0.5), decode_p99_ms: q(0.99),
      viewer_bytes_per_s: (window.sculpt.conn.bytesIn - b0) / s,
      frames_per_s: ((window.sculpt.stats.frames || 0) - f0) / s,
      last_frame_ms: window.sculpt.stats.frameMs, triangles: window.sculpt.meshes.totals().faces };
  }, [bytes0, frames0, Number(seconds)]);
  console.log(JSON.stringify({ first_full_mesh_ms: firstMeshMs, seconds: Number(seconds), ...r,
    renderer: 'headless chromium, --disable-gpu (SwiftShader software WebGL)' }));
} finally {
  await browser.close();
}
