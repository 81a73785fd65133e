// The web client's contour decoder (src/contour_codec.js) against the C++ codec. The fixtures
// (tests/web/contour_fixtures.cc) hold messages from the C++ encoder (SKC3, and SKC2 and SKC1
// from the older encoders) with what the C++ decoder made of them; every one must decode to the same
// points here (identical doubles: both repeat the same operations), and every truncated or
// corrupted variant must get the C++ verdict: a ContourError where C++ refused, the same points
// where it accepted. Last, the JS decode speed on the benchmark's 1,000-ball skin.
//
// Usage: node contour_codec_test.mjs --fixtures-bin PATH/contour_fixtures --out FIXTURES.json
//        node contour_codec_test.mjs --json FIXTURES.json      (fixtures written earlier)
import { execFileSync } from 'node:child_process';
import { readFileSync } from 'node:fs';
import {
  ContourError, ContourView, decodeContours, describeContour,
} from '../src/contour_codec.js';

const args = process.argv.slice(2);
const arg = (name) => {
  const i = args.indexOf(name);
  return i >= 0 ? args[i + 1] : undefined;
};
let jsonPath = arg('--json');
if (arg('--fixtures-bin')) {
  jsonPath = arg('--out');
  execFileSync(arg('--fixtures-bin'), [jsonPath], { stdio: 'inherit' });
}
if (!jsonPath) {
  console.error('usage: contour_codec_test.mjs ' +
                '(--fixtures-bin BIN --out OUT.json | --json IN.json)');
  process.exit(2);
}
const started = performance.now();
const fixtures = JSON.parse(readFileSync(jsonPath, 'utf8'));

let failures = 0;
let checks = 0;
function fail(where, message) {
  failures += 1;
  if (failures <= 30) console.error(`FAIL ${where}: ${message}`);
}
function check(cond, where, message) {
  checks += 1;
  if (!cond) fail(where, message);
  return cond;
}

const hex = (s) => Uint8Array.from(s.match(/../g) ?? [], (h) => parseInt(h, 16));

/** Expected interleaved points (null where C++ wrote a non-finite value) against decoded ones. */
function samePoints(expected, actual, where) {
  if (!check(actual instanceof Float64Array, where, 'not a Float64Array')) return false;
  if (!check(actual.length === expected.length, where,
             `${actual.length / 2} points, C++ decoded ${expected.length / 2}`)) {
    return false;
  }
  for (let i = 0; i < expected.length; ++i) {
    const e = expected[i];
    const a = actual[i];
    const ok = e === null ? !Number.isFinite(a) : a === e;
    if (!check(ok, where, `value ${i}: ${a}, C++ decoded ${e}`)) return false;
  }
  return true;
}

function sameView(expected, view, where) {
  check(view.step === expected.step, where, `step ${view.step}, C++ ${expected.step}`);
  const got = view.sections;
  if (!check(got.length === expected.sections.length, where,
             `${got.length} sections, C++ has ${expected.sections.length}`)) {
    return;
  }
  expected.sections.forEach((s, k) => {
    check(got[k].id === s.id && got[k].version === s.version, `${where} section ${k}`,
          `id/version ${got[k].id}/${got[k].version}, C++ ${s.id}/${s.version}`);
    samePoints(s.plus, got[k].plus, `${where} section ${k} plus`);
    samePoints(s.minus, got[k].minus, `${where} section ${k} minus`);
  });
  samePoints(expected.chain_plus, view.chain(1), `${where} chain(+1)`);
  samePoints(expected.chain_minus, view.chain(-1), `${where} chain(-1)`);
}

/** Runs f and returns the error it threw (null if none); a non-ContourError is a failure. */
function thrown(f, where) {
  try {
    f();
    return null;
  } catch (e) {
    check(e instanceof ContourError, where, `threw ${e?.name}: ${e?.message}, not a ContourError`);
    return e;
  }
}

// 1. Every polyline set decodes to the C++ decoder's points; both codings, both Draco schemes
//    and more than the smallest rANS precision occur.
const seen = new Set();
for (const set of fixtures.sets) {
  const bytes = hex(set.bytes);
  const where = `set ${set.name}`;
  let lines;
  const err = thrown(() => { lines = decodeContours(bytes); }, where);
  if (!check(err === null, where, `refused: ${err?.message}`)) continue;
  if (!check(lines.length === set.lines.length, where,
             `${lines.length} polylines, C++ decoded ${set.lines.length}`)) {
    continue;
  }
  set.lines.forEach((l, i) => samePoints(l, lines[i], `${where} polyline ${i}`));
  const d = describeContour(bytes);
  check(d.coding === bytes[13] && d.step === set.step, where, `described as ${JSON.stringify(d)}`);
  seen.add(d.coding === 0 ? 'varint' : d.coding === 2 ? 'curve' : d.coding === 3 ? 'turtle'
    : d.scheme);
  if (d.scheme === 'raw' && d.precisionBits > 12) seen.add('raw, precision > 12');
  if (d.scheme === 'tagged') seen.add(`tagged`);
}
for (const want of ['turtle', 'curve', 'varint', 'raw', 'tagged', 'raw, precision > 12']) {
  check(seen.has(want), 'coverage', `no fixture uses ${want} (seen: ${[...seen].join(', ')})`);
}

// 2. Skin snapshots and updates, applied in order, give the C++ view after every step; a step
//    C++ refused throws and leaves the view as it was.
for (const seq of fixtures.views) {
  const view = new ContourView();
  seq.steps.forEach((step, i) => {
    const where = `view ${seq.name} step ${i} (${step.what})`;
    const err = thrown(() => view.apply(hex(step.bytes)), where);
    check((err === null) === step.ok, where,
          step.ok ? `refused: ${err?.message}` : `accepted what C++ refused (${step.error})`);
    sameView(step, view, where);
  });
  const snap = hex(seq.steps[0].bytes);
  check(thrown(() => decodeContours(snap), `${seq.name} as a polyline set`) !== null,
        `${seq.name} snapshot as a polyline set`, 'decoded');
}

// 3. Truncated and corrupted messages: refused wherever C++ refuses them; where C++ accepts, the
//    same result, or a refusal for one of the reasons the JS decoder is stricter for (see the
//    head of contour_codec.js: tagged values cut short, a rANS stream not ending in its initial
//    state, ids of 2^53 and above). Every truncation is refused here (not all are in C++).
const stricter = new RegExp('tagged values past the end|does not end in its initial state|' +
                            'state cut short|outside \\[0, 2\\^53\\)');
const tally = {};
let slowest = 0;
for (const c of fixtures.corrupt) {
  const scheme = describeContour(hex(c.bytes)).scheme;
  check(c.name === (scheme ?? 'varint') || !['raw', 'tagged', 'varint'].includes(c.name),
        `corrupt ${c.name}`, `is coded ${scheme}`);
  const t = (tally[c.name] = { variants: c.variants.length, cxxRefused: 0, jsRefused: 0,
                                cxxAcceptedPrefixes: 0 });
  c.variants.forEach((v, i) => {
    const where = `corrupt ${c.name} variant ${i} (${v.bytes.length / 2} bytes)`;
    const bytes = hex(v.bytes);
    const t0 = performance.now();
    let result;
    let err;
    if (c.base) {
      const view = new ContourView();
      if (c.base_bytes) view.apply(hex(c.base_bytes));
      if (i === 0) sameView(c.base, view, `corrupt ${c.name} base`);
      err = thrown(() => view.apply(bytes), where);
      result = view;
    } else {
      err = thrown(() => { result = decodeContours(bytes); }, where);
    }
    slowest = Math.max(slowest, performance.now() - t0);
    if (err) t.jsRefused += 1;
    if (!v.ok) t.cxxRefused += 1;
    const prefix = i < c.bytes.length / 2;
    if (v.ok && prefix) t.cxxAcceptedPrefixes += 1;
    if (prefix) check(err !== null, where, 'accepted a truncated message');
    if (!v.ok) {
      check(err !== null, where, 'accepted what C++ refused');
      return;
    }
    if (err) {
      check(stricter.test(err.message), where, `refused what C++ accepted: ${err.message}`);
      return;
    }
    if (c.base) {
      sameView(v.view, result, where);
    } else if (check(result.length === v.lines.length, where, 'polyline count differs')) {
      v.lines.forEach((l, k) => samePoints(l, result[k], `${where} polyline ${k}`));
    }
  });
}

// The stricter checks do work: on rANS-coded messages they refuse corruptions C++ lets through.
for (const [name, t] of Object.entries(tally)) {
  if (name === 'raw' || name === 'tagged' || name === 'arc') {
    check(t.jsRefused > t.cxxRefused, `corrupt ${name}`,
          `refused ${t.jsRefused} variants, no more than C++'s ${t.cxxRefused}`);
  }
}

// 4. Input only JS can be handed, and hostile headers: a ContourError, quickly.
check(thrown(() => decodeContours([0x53, 0x4b, 0x43, 0x31]), 'array') !== null, 'array', 'decoded');
{
  // A message inside a larger buffer (a WebSocket frame's payload, say) decodes the same.
  const set = fixtures.sets.find((x) => x.name === 'mixed');
  const inner = hex(set.bytes);
  const outer = new Uint8Array(inner.length + 7);
  outer.set(inner, 3);
  const where = 'subarray';
  let lines;
  const err = thrown(() => { lines = decodeContours(outer.subarray(3, 3 + inner.length)); }, where);
  if (check(err === null, where, `refused: ${err?.message}`)) {
    set.lines.forEach((l, i) => samePoints(l, lines[i], `${where} polyline ${i}`));
  }
}
{
  // SKC1, kind 0, step 1, coding 1, one polyline claiming 2^26 points: refused by the size cap.
  const b = new Uint8Array([0x53, 0x4b, 0x43, 0x31, 0, 0, 0, 0, 0, 0, 0, 0xf0, 0x3f, 1, 1,
                            0x80, 0x80, 0x80, 0x20, 0, 0]);
  const e = thrown(() => decodeContours(b), 'huge count');
  check(e && /contour\.points=67108864/.test(e.message), 'huge count', e?.message);
}
{
  // Seeded random bytes after a valid header prefix: never anything but a ContourError.
  let seed = 12345;
  const rand = () => ((seed = (seed * 1103515245 + 12345) % 2147483648) / 2147483648);
  const base = hex(fixtures.sets.find((s) => s.name === 'mixed').bytes);
  for (let k = 0; k < 2000; ++k) {
    const b = base.slice(0, 14 + Math.floor(rand() * 40));
    for (let i = 14; i < b.length; ++i) b[i] = Math.floor(rand() * 256);
    const t0 = performance.now();
    thrown(() => decodeContours(b), `random bytes ${k}`);
    slowest = Math.max(slowest, performance.now() - t0);
  }
}
check(slowest < 1000, 'time', `one decode took ${slowest.toFixed(0)} ms`);

// 5. Decode speed on the benchmark's skin, SKC3 (the default), SKC2 and SKC1 alternately in one
//    run (one snapshot each; best of several runs).
let speed = '';
if (fixtures.bench) {
  const forms = [hex(fixtures.bench.bytes), hex(fixtures.bench.skc2_bytes),
                 hex(fixtures.bench.skc1_bytes)];
  const best = [Infinity, Infinity, Infinity];
  let points = 0;
  for (let run = 0; run < 30; ++run) {
    forms.forEach((bytes, f) => {
      const t0 = performance.now();
      const view = new ContourView();
      view.apply(bytes);
      best[f] = Math.min(best[f], performance.now() - t0);
      points = view.sections.reduce((n, sec) => n + (sec.plus.length + sec.minus.length) / 2, 0);
      check(points === fixtures.bench.points, 'bench', `${points} points, C++ ${fixtures.bench.points}`);
    });
  }
  const bytes = forms[0];
  speed = `; bench skin ${points} points in ${bytes.length} bytes ` +
          `(${(bytes.length * 8 / points).toFixed(2)} bits/point), decode ` +
          `${best[0].toFixed(2)} ms = ${(points / best[0] / 1000).toFixed(1)} M points/s ` +
          `(SKC2 ${forms[1].length} bytes: ${(points / best[1] / 1000).toFixed(1)} M points/s, ` +
          `SKC1 ${forms[2].length} bytes: ${(points / best[2] / 1000).toFixed(1)} M points/s)`;
}

const ms = performance.now() - started;
console.log(`contour codec: ${fixtures.sets.length} polyline sets (${[...seen].join(', ')}), ` +
            `${fixtures.views.map((v) => v.steps.length).join('+')} view steps, ` +
            `corruptions ${JSON.stringify(tally)}; ${checks} checks in ${ms.toFixed(0)} ms, ` +
            `slowest decode ${slowest.toFixed(1)} ms${speed}`);
if (failures) {
  console.error(`${failures} failures`);
  process.exit(1);
}
