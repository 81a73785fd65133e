// Renders a mesh file (PLY, as `sculpt demo` and `sculpt export` write) to a PNG the way a viewer
// would see it: three.js in Debian's headless Chromium (SwiftShader), lit from the camera's side.
//   node client/web/test/render_ply.mjs MESH.ply OUT.png [--dir X,Y,Z] [--zoom Z] [--size WxH]
// --dir is where the camera looks from (towards the mesh's centre), --zoom > 1 comes closer.
// Files are served to the page from disk through request interception: no server, no network.
import { readFileSync } from 'node:fs';
import { dirname, join, resolve } from 'node:path';
import { fileURLToPath } from 'node:url';
import { launchChromium } from './chromium.mjs';

const args = process.argv.slice(2);
const opt = (name, fallback) => {
  const i = args.indexOf(name);
  return i >= 0 && i + 1 < args.length ? args.splice(i, 2)[1] : fallback;
};
const dir = opt('--dir', '0,0,1');
const zoom = Number(opt('--zoom', '1'));
const [width, height] = opt('--size', '900x700').split('x').map(Number);
const [mesh, out] = args;
if (!mesh || !out || !(zoom > 0) || !(width > 0) || !(height > 0) || dir.split(',').length !== 3) {
  console.error('usage: node render_ply.mjs MESH.ply OUT.png [--dir X,Y,Z] [--zoom Z] [--size WxH]');
  process.exit(2);
}
const three = join(dirname(fileURLToPath(import.meta.url)), '..', 'node_modules', 'three');
const page = `<!doctype html><html><body style="margin:0">
<script type="importmap">{"imports":{"three":"/three/build/three.module.js","three/addons/":"/three/examples/jsm/"}}</script>
<script type="module">
import * as THREE from 'three';
import { PLYLoader } from 'three/addons/loaders/PLYLoader.js';
const renderer = new THREE.WebGLRenderer({ antialias: true });
renderer.setSize(${width}, ${height});
document.body.appendChild(renderer.domElement);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0x2a2e36);
scene.add(new THREE.HemisphereLight(0xffffff, 0x333344, 1.2));
const g = await new PLYLoader().loadAsync('/mesh.ply');
g.computeVertexNormals();
g.computeBoundingSphere();
scene.add(new THREE.Mesh(g, new THREE.MeshStandardMaterial({ color: 0xc8905c, roughness: 0.8 })));
const c = g.boundingSphere.center, r = g.boundingSphere.radius;
const camera = new THREE.PerspectiveCamera(35, ${width} / ${height}, r / 100, r * 100);
camera.position.copy(c).addScaledVector(new THREE.Vector3(${dir}).normalize(), 3.2 * r / ${zoom});
camera.lookAt(c);
const light = new THREE.DirectionalLight(0xffffff, 1.5);
light.position.copy(camera.position).add(new THREE.Vector3(r, 2 * r, 0));
scene.add(light);
renderer.render(scene, camera);
window.rendered = { triangles: g.index ? g.index.count / 3 : g.attributes.position.count / 3 };
</script></body></html>`;

const browser = await launchChromium();
try {
  const tab = await browser.newPage({ viewport: { width, height } });
  const errors = [];
  tab.on('pageerror', (e) => errors.push(e.message));
  await tab.route('http://render.invalid/**', (route) => {
    const path = new URL(route.request().url()).pathname;
    if (path === '/') return route.fulfill({ contentType: 'text/html', body: page });
    if (path === '/mesh.ply') return route.fulfill({ contentType: 'application/octet-stream', body: readFileSync(resolve(mesh)) });
    if (path.startsWith('/three/') && !path.includes('..')) {
      return route.fulfill({ contentType: 'text/javascript', body: readFileSync(join(three, path.slice('/three/'.length))) });
    }
    return route.fulfill({ status: 404, body: '' });
  });
  await tab.goto('http://render.invalid/');
  await tab.waitForFunction(() => window.rendered, null, { timeout: 60000 }).catch(() => {
    throw new Error(`the page did not render ${mesh}: ${errors.join('; ') || 'no error reported'}`);
  });
  await tab.screenshot({ path: out });
  const r = await tab.evaluate(() => window.rendered);
  console.log(`render_ply: ${out} (${r.triangles} triangles, from ${dir}, zoom ${zoom})`);
} finally {
  await browser.close();
}
