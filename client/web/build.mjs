// Builds the web client into dist/ (or $SCULPT_WEB_OUT): protobuf code generated from
// proto/sculpt/v1/sculpt.proto, the app bundled with esbuild, three.js's Draco decoder copied
// beside it so sculptd serves it (no CDN).
import { execFileSync } from 'node:child_process';
import { cpSync, mkdirSync, copyFileSync } from 'node:fs';
import { dirname, join, resolve } from 'node:path';
import { fileURLToPath } from 'node:url';
import * as esbuild from 'esbuild';

const here = dirname(fileURLToPath(import.meta.url));
const out = resolve(process.env.SCULPT_WEB_OUT || join(here, 'dist'));
const proto = resolve(here, '../../proto/sculpt/v1/sculpt.proto');

mkdirSync(join(here, 'gen'), { recursive: true });
execFileSync(process.execPath, [join(here, 'node_modules/protobufjs-cli/bin/pbjs'), '-t',
  'static-module', '-w', 'es6', '--no-comments', '--no-verify', '--no-convert', '--no-delimited',
  '-o', join(here, 'gen/sculpt_pb.js'), proto], { stdio: 'inherit' });

mkdirSync(join(out, 'assets'), { recursive: true });
mkdirSync(join(out, 'draco'), { recursive: true });
await esbuild.build({
  entryPoints: [join(here, 'src/main.js')],
  bundle: true,
  format: 'esm',
  minify: true,
  sourcemap: true,
  target: ['chrome110', 'firefox110', 'safari16'],
  outfile: join(out, 'assets/app.js'),
  logLevel: 'warning',
});
copyFileSync(join(here, 'src/index.html'), join(out, 'index.html'));
copyFileSync(join(here, 'src/style.css'), join(out, 'assets/style.css'));
for (const f of ['draco_decoder.wasm', 'draco_wasm_wrapper.js', 'draco_decoder.js']) {
  cpSync(join(here, 'node_modules/three/examples/jsm/libs/draco', f), join(out, 'draco', f));
}
console.log(`web client built into ${out}`);
