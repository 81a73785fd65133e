// Measures the web client against a running sculptd (a benchmark, not a test; prints JSON):
//   node test/measure.mjs HTTP_URL [SECONDS]
// - first_full_mesh_ms: from navigation start to the last chunk of the first full mesh (the page
//   is opened as a viewer; the mesh is full once no chunk has come for a second);
// - chunk decode p50/p99: the chunks received, decoded again one at a time by the page's own
//   DRACOLoader (worker hand-off, WASM decode and transfer back; no queueing behind other chunks);
//   chunk_latency p50/p99 is the page's own figure, from receipt to mesh, queueing included;
// - while SECONDS pass: the viewer's received bytes per second, and frames per second with the
//   page drawing every animation frame (frame_ms: the JavaScript side of a frame).
import { launchChromium } from './chromium.mjs';

const [base, seconds = '10'] = process.argv.slice(2);
if (!base) { console.error('usage: node measure.mjs http://HOST:PORT/ [SECONDS]'); process.exit(2); }
const quantile = (xs, q) => {
  const d = [...xs].sort((a, b) => a - b);
  return d.length ? d[Math.min(d.length - 1, Math.floor(q * d.length))] : null;
};
const browser = await launchChromium();
try {
  const page = await browser.newPage({ viewport: { width: 1024, height: 720 } });
  // Keep a copy of every chunk's Draco bytes for the decode measurement.
  await page.addInitScript(() => { window.measureChunks = []; window.measureArrivals = []; });
  await page.goto(`${base}#role=viewer&token=${process.env.TOKEN || 'sculpt-dev-viewer'}&name=measure`);
  await page.waitForFunction(() => window.sculpt?.stats.state === 'joined', null, { timeout: 60000, polling: 20 });
  const joinedMs = await page.evaluate(() => performance.now());
  await page.evaluate(() => window.sculpt.conn.addEventListener('meshChunk', (ev) => {
    window.measureArrivals.push(performance.now());
    if (ev.detail.draco && ev.detail.draco.length && window.measureChunks.length < 400) {
      window.measureChunks.push(ev.detail.draco.slice());
    }
  }));
  await page.waitForFunction(() => {
    const m = window.sculpt.meshes;
    return m.totals().chunks > 0 && m.decoding === 0 && performance.now() - m.lastChangeAt > 1000;
  }, null, { timeout: 120000, polling: 50 });
  const first = await page.evaluate(() => ({ ms: window.sculpt.meshes.lastChangeAt, ...window.sculpt.meshes.totals(),
    firstArrival: window.measureArrivals[0], lastArrival: window.measureArrivals[window.measureArrivals.length - 1] }));
  const latencyFirst = await page.evaluate(() => [...window.sculpt.meshes.decodeMs]);
  const bytes0 = await page.evaluate(() => window.sculpt.conn.bytesIn);
  // Drawn continuously while measuring, so that frames per second is what the renderer sustains.
  const frames0 = await page.evaluate(() => { window.sculpt.continuous = true; window.sculpt.invalidate(); return window.sculpt.frameTimes.length; });
  const t0 = Date.now();
  await new Promise((r) => setTimeout(r, Number(seconds) * 1000));
  const live = await page.evaluate(([b0, f0, t0]) => {
    const s = (Date.now() - t0) / 1000;
    return { viewer_bytes_per_s: (window.sculpt.conn.bytesIn - b0) / s, seconds: s,
      frames: window.sculpt.frameTimes.slice(f0), chunks_per_s: window.sculpt.stats.chunksPerSecond,
      latencies: [...window.sculpt.meshes.decodeMs], stop: (window.sculpt.continuous = false) };
  }, [bytes0, frames0, t0]);
  // Decode the chunks seen one at a time (the page is otherwise idle now).
  const decode = await page.evaluate(async () => {
    const loader = window.sculpt.meshes.loader;
    const times = [];
    for (const bytes of window.measureChunks) {
      const buf = bytes.slice().buffer;
      const t = performance.now();
      await new Promise((resolve, reject) => loader.parse(buf, (g) => { g.dispose(); resolve(); }, reject));
      times.push(performance.now() - t);
    }
    return times;
  });
  console.log(JSON.stringify({
    first_full_mesh_ms: Math.round(first.ms), joined_ms: Math.round(joinedMs),
    first_chunk_arrived_ms: Math.round(first.firstArrival), last_chunk_arrived_ms: Math.round(first.lastArrival), first_full_mesh_chunks: first.chunks, first_full_mesh_triangles: first.faces,
    chunk_decode_p50_ms: quantile(decode, 0.5), chunk_decode_p99_ms: quantile(decode, 0.99), chunks_decoded: decode.length,
    chunk_latency_first_mesh_p50_ms: quantile(latencyFirst, 0.5), chunk_latency_first_mesh_p99_ms: quantile(latencyFirst, 0.99),
    chunk_latency_live_p50_ms: quantile(live.latencies.slice(latencyFirst.length), 0.5),
    chunk_latency_live_p99_ms: quantile(live.latencies.slice(latencyFirst.length), 0.99),
    seconds: live.seconds, viewer_bytes_per_s: Math.round(live.viewer_bytes_per_s), chunks_per_s: live.chunks_per_s,
    frames_per_s: live.frames.length / live.seconds, frame_ms_p50: quantile(live.frames, 0.5), frame_ms_p99: quantile(live.frames, 0.99),
    renderer: 'headless chromium, --disable-gpu (SwiftShader software WebGL)' }));
} finally {
  await browser.close();
}
