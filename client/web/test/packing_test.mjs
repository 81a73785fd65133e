// The web client's stroke splitting (client/web/src/packing.js, posesThatFit) in node: how many
// poses a stroke may carry under the server's work limit (Welcome.max_stroke_work). Usage:
//   node test/packing_test.mjs
import { posesThatFit } from '../src/packing.js';

let failures = 0;
function expect(name, got, want) {
  const ok = got === want;
  console.log(`${ok ? 'ok  ' : 'FAIL'} ${name}${ok ? '' : `: got ${got}, want ${want}`}`);
  if (!ok) failures += 1;
}

// A drag along x, one voxel (0.5) between poses, on the built-in scene's object.
const line = (n) => Array.from({ length: n }, (_, i) => ({ x: 0.5 * i, y: 0, z: 24 }));
const scene = { voxelSize: 0.5, halfWidth: 6, shellRadii: 1, maxWork: 4 << 20 };

expect('an older server (no limit): every pose', posesThatFit(line(32), 16, { ...scene, maxWork: 0 }), 32);
expect('one pose always fits, whatever the tool', posesThatFit(line(1), 16, scene), 1);
expect('never fewer than one', posesThatFit(line(8), 16, { ...scene, maxWork: 1 << 16 }), 1);
// The default tool's 32-pose stroke asks the server 3.4 M voxel-poses (sculpt-bench's block
// sizes): under the default 4 Mi, so the estimate must not split it.
expect('default tool, 32 poses: one stroke', posesThatFit(line(32), 2.5, scene), 32);
// The largest tool's block alone is about 3.2 M voxels: two poses are over 4 Mi.
expect('largest tool: one pose a stroke', posesThatFit(line(4), 16, scene), 1);

// Fewer poses fit as the tool grows, and as the limit shrinks.
let last = Infinity;
let monotone = true;
for (const r of [0.5, 1, 2, 4, 8, 16]) {
  const n = posesThatFit(line(32), r, { ...scene, maxWork: 1 << 21 });
  monotone = monotone && n <= last;
  last = n;
}
expect('fewer poses for larger tools', monotone, true);
const at = (limit) => posesThatFit(line(32), 4, { ...scene, maxWork: limit });
expect('fewer poses for a smaller limit', at(1 << 19) < at(1 << 21), true);

// What it lets through is under the limit by its own count: n poses x block voxels.
const dx = scene.voxelSize;
const n = posesThatFit(line(32), 8, scene);
const reach = Math.max(Math.max(8, 3 * dx) + 3.5 * dx, (scene.halfWidth + 2) * dx);
const side = (ext) => Math.ceil((ext + 16 + 2 * reach) / dx) + 14;
expect('the poses let through are within the limit', n * side(0.5 * (n - 1)) * side(0) ** 2 <= scene.maxWork, true);
expect('one more would not be', (n + 1) * side(0.5 * n) * side(0) ** 2 > scene.maxWork, true);

if (failures > 0) {
  console.log(`${failures} failed`);
  process.exit(1);
}
console.log('all passed');
