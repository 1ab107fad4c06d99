// Bundles the page into dist/ (index.html + assets/): main.js (three.js, urdf-loader, the page),
// test-hooks.js (window.hrcTest, a chunk main.js loads only with ?test=...; three.js in a chunk
// both share) and iwer.js (the WebXR emulation, loaded only with ?test=iwer). Run by
// scripts/setup.sh.
import { build } from 'esbuild';
import { copyFileSync, mkdirSync, rmSync } from 'node:fs';
import { dirname, join } from 'node:path';
import { fileURLToPath } from 'node:url';

const here = dirname(fileURLToPath(import.meta.url));
// --out DIR: build elsewhere (a developer's build beside the one a trial serves; HRC_CLIENT_DIST)
const outAt = process.argv.indexOf('--out');
const dist = outAt > 0 ? process.argv[outAt + 1] : join(here, 'dist');
rmSync(dist, { recursive: true, force: true });
mkdirSync(join(dist, 'assets'), { recursive: true });
const common = {
  bundle: true,
  format: 'esm',
  minify: !process.env.HRC_NO_MINIFY, // HRC_NO_MINIFY=1: readable stack traces while debugging
  sourcemap: false,
  target: ['chrome110', 'firefox115', 'safari16'],
  logLevel: 'warning',
  legalComments: 'none',
};
await build({
  ...common,
  entryPoints: [join(here, 'src/main.js')],
  outdir: join(dist, 'assets'),
  splitting: true, // the dynamic import of test-hooks.js becomes a chunk of its own
  entryNames: '[name]',
  chunkNames: '[name]-[hash]',
});
await build({ ...common, entryPoints: [join(here, 'src/iwer.js')], outfile: join(dist, 'assets/iwer.js') });
copyFileSync(join(here, 'index.html'), join(dist, 'index.html'));
