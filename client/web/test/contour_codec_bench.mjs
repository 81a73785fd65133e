// Decode speed of the JS contour decoder on the benchmark's 1,000-ball skin, SKC2 and SKC1
// alternately in one run (best of 40 each). The messages come from the C++ encoder through the
// fixtures file tests/web/contour_fixtures.cc writes ("bench").
//
// Usage: node contour_codec_bench.mjs FIXTURES.json [DECODER.js]
// DECODER.js (default ../src/contour_codec.js) lets another version of the decoder, e.g. one
// checked out from an older commit, be timed against the same messages.
import { readFileSync } from 'node:fs';
import { resolve } from 'node:path';
import { pathToFileURL } from 'node:url';

const { ContourView } = await import(process.argv[3]
  ? pathToFileURL(resolve(process.argv[3])).href : '../src/contour_codec.js');

const fixtures = JSON.parse(readFileSync(process.argv[2], 'utf8'));
const hex = (s) => Uint8Array.from(s.match(/../g), (h) => parseInt(h, 16));
const forms = [hex(fixtures.bench.bytes), hex(fixtures.bench.skc1_bytes)];
const best = [Infinity, Infinity];
for (let run = 0; run < 40; ++run) {
  forms.forEach((bytes, f) => {
    const t0 = performance.now();
    new ContourView().apply(bytes);
    best[f] = Math.min(best[f], performance.now() - t0);
  });
}
const mps = (ms) => (fixtures.bench.points / ms / 1000).toFixed(2);
console.log(JSON.stringify({
  points: fixtures.bench.points, skc2_bytes: forms[0].length, skc1_bytes: forms[1].length,
  decode_mpoints_per_s: Number(mps(best[0])), decode_mpoints_per_s_skc1: Number(mps(best[1])),
}));
