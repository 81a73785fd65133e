// Packs stroke poses as proto/README.md ("Packed poses, byte by byte") specifies: per pose
// int16 x, y, z offsets from the float32 origin in units of voxel_size / 256, then uint16
// milliseconds after t0, little-endian, 8 bytes a pose.

/** Largest offset, in units, a packed coordinate holds. */
export const kMaxOffset = 32767;

/**
 * @param {{x:number,y:number,z:number,t:number}[]} poses world positions, client ms
 * @param {number} voxelSize the object's voxel size (SceneInfo)
 * @returns {{origin:{x:number,y:number,z:number}, t0:number, bytes:Uint8Array}|null}
 *   null when a pose lies out of the origin's reach or times run backwards.
 */
export function packPoses(poses, voxelSize) {
  if (poses.length === 0 || !(voxelSize > 0)) return null;
  const mid = poses[Math.floor(poses.length / 2)];
  const f = Math.fround;
  const origin = { x: f(mid.x), y: f(mid.y), z: f(mid.z) };
  const unit = voxelSize / 256;
  const t0 = Math.floor(poses[0].t);
  const bytes = new Uint8Array(8 * poses.length);
  const view = new DataView(bytes.buffer);
  let last = 0;
  for (let i = 0; i < poses.length; ++i) {
    const p = poses[i];
    const q = [p.x - origin.x, p.y - origin.y, p.z - origin.z].map((d) => Math.round(d / unit));
    if (q.some((v) => !Number.isFinite(v) || Math.abs(v) > kMaxOffset)) return null;
    const t = Math.max(last, Math.min(65535, Math.round(p.t - t0)));
    last = t;
    view.setInt16(8 * i, q[0], true);
    view.setInt16(8 * i + 2, q[1], true);
    view.setInt16(8 * i + 4, q[2], true);
    view.setUint16(8 * i + 6, t, true);
  }
  return { origin, t0, bytes };
}

/** Decodes packed poses back (for tests): world positions and ms after t0. */
export function unpackPoses(bytes, origin, voxelSize) {
  const unit = voxelSize / 256;
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  const out = [];
  for (let i = 0; i + 8 <= bytes.length; i += 8) {
    out.push({
      x: origin.x + view.getInt16(i, true) * unit,
      y: origin.y + view.getInt16(i + 2, true) * unit,
      z: origin.z + view.getInt16(i + 4, true) * unit,
      t: view.getUint16(i + 6, true),
    });
  }
  return out;
}

/**
 * How many of `poses` (from the first) one stroke may carry under the server's work limit
 * (Welcome.max_stroke_work, proto/README.md "Stroke work"): the poses times the voxels of the
 * block the kernel reads for them. The server computes the block exactly and refuses a stroke
 * over the limit; this estimate of it is conservative (a press with the scene's compensation
 * shell, the largest reach of any kind), so what it lets through is accepted. Always at least 1.
 * @param {{x:number,y:number,z:number}[]} poses world positions
 * @param {number} radius the sphere tool's radius (world units)
 * @param {{voxelSize:number, halfWidth:number, shellRadii:number, maxWork:number}} limits
 *   maxWork 0 (an older server): no limit
 */
export function posesThatFit(poses, radius, limits) {
  const { voxelSize: dx, halfWidth, shellRadii, maxWork } = limits;
  if (!(maxWork > 0) || poses.length <= 1) return poses.length;
  const reach = Math.max(Math.max((shellRadii || 1) * radius, 3 * dx) + 3.5 * dx, (halfWidth + 2) * dx);
  const pad = 2 * 6 + 2;  // the kernel's stencil pad on both sides, and rounding
  const lo = { ...poses[0] };
  const hi = { ...poses[0] };
  for (let n = 1; n <= poses.length; ++n) {
    const p = poses[n - 1];
    let voxels = 1;
    for (const a of ['x', 'y', 'z']) {
      lo[a] = Math.min(lo[a], p[a]);
      hi[a] = Math.max(hi[a], p[a]);
      voxels *= Math.ceil((hi[a] - lo[a] + 2 * radius + 2 * reach) / dx) + pad;
    }
    if (n * voxels > maxWork) return Math.max(1, n - 1);
  }
  return poses.length;
}
