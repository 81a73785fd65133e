// Decode speed of the JS contour decoder on the benchmark's 1,000-ball skin, SKC3 (what the
// encoder writes), SKC2 and SKC1 alternately in one run (best of 40 each). The messages come from
// the C++ encoder through the fixtures file tests/web/contour_fixtures.cc writes ("bench").
//
// Usage: node contour_codec_bench.mjs FIXTURES.json [DECODER.js] [RUNS]
// DECODER.js (default ../src/contour_codec.js) lets another version of the decoder, e.g. one
// checked out from an older commit, be timed against the same messages (a decoder that does not
// read a format reports null for it).
import { readFileSync } from 'node:fs';
import { resolve } from 'node:path';
import { pathToFileURL } from 'node:url';

const { ContourView } = await import(process.argv[3]
  ? pathToFileURL(resolve(process.argv[3])).href : '../src/contour_codec.js');
const runs = Number(process.argv[4] ?? 40);

const fixtures = JSON.parse(readFileSync(process.argv[2], 'utf8'));
const hex = (s) => Uint8Array.from(s.match(/../g), (h) => parseInt(h, 16));
const forms = [fixtures.bench.bytes, fixtures.bench.skc2_bytes, fixtures.bench.skc1_bytes]
  .map((s) => (s ? hex(s) : null));
const best = forms.map(() => Infinity);
for (let run = 0; run < runs; ++run) {
  forms.forEach((bytes, f) => {
    if (!bytes || best[f] === null) return;
    const t0 = performance.now();
    try {
      new ContourView().apply(bytes);
    } catch {
      best[f] = null;  // this decoder does not read the format
      return;
    }
    best[f] = Math.min(best[f], performance.now() - t0);
  });
}
const mps = (ms) => (ms === null || ms === Infinity ? null
  : Number((fixtures.bench.points / ms / 1000).toFixed(2)));
console.log(JSON.stringify({
  points: fixtures.bench.points, format: String.fromCharCode(...forms[0].subarray(0, 4)),
  bytes: forms[0].length, skc2_bytes: forms[1]?.length, skc1_bytes: forms[2].length,
  decode_mpoints_per_s: mps(best[0]), decode_mpoints_per_s_skc2: mps(best[1]),
  decode_mpoints_per_s_skc1: mps(best[2]),
}));
