// model.glb across modules (issue 11): the file core/io/gltf.h writes is valid glTF for the
// Khronos validator, and three.js GLTFLoader in Debian's headless chromium renders it textured
// and, through the glTF camera named after a photo, lined up with our camera model.
//
// Inputs come from write_test_glb (tests/gltf/write_test_glb.cc): model.glb, and for photo
// 0000.jpg at 1024 x 768 the side of the cube each pixel sees by our camera model
// (labels.bin). Everything the browser loads (three.js, the model) is served from this
// machine: tests/gltf/node_modules and the output folder; nothing is downloaded at run time.
// Environment: RECONDUIT_GLTF_WRITER (the writer binary), RECONDUIT_GLTF_OUT (output folder:
// model.glb, the screenshots default.png and camera_0000.jpg.png, validator.json),
// RECONDUIT_CHROMIUM overrides /usr/bin/chromium; without chromium the rendering is skipped.
import {strict as assert} from 'node:assert';
import {execFileSync} from 'node:child_process';
import {existsSync, mkdirSync, readFileSync, writeFileSync} from 'node:fs';
import {createServer} from 'node:http';
import {dirname, extname, join, normalize, resolve} from 'node:path';
import {after, before, test} from 'node:test';
import {fileURLToPath} from 'node:url';

import * as validator from 'gltf-validator';
import {chromium} from 'playwright-core';

const here = dirname(fileURLToPath(import.meta.url));
const out = resolve(process.env.RECONDUIT_GLTF_OUT || join(here, '../../build/ci/tests/gltf'));
const writer = process.env.RECONDUIT_GLTF_WRITER;
const chromiumPath = process.env.RECONDUIT_CHROMIUM || '/usr/bin/chromium';

let expected;
let server;
let baseUrl;

const types = {'.js': 'text/javascript', '.html': 'text/html', '.glb': 'model/gltf-binary',
               '.json': 'application/json', '.bin': 'application/octet-stream'};

// The page: three.js from node_modules through an import map; window.render(mode) draws the
// model at width x height and returns the pixels' comparison with the expected labels.
const page = `<!doctype html><html><head><style>body{margin:0;background:#000}</style>
<script type="importmap">{"imports": {"three": "/three/build/three.module.js",
  "three/addons/": "/three/examples/jsm/"}}</script></head><body>
<script type="module">
import * as THREE from 'three';
import {GLTFLoader} from 'three/addons/loaders/GLTFLoader.js';
const expected = await (await fetch('/files/expected.json')).json();
const labels = new Uint8Array(await (await fetch('/files/' + expected.labels)).arrayBuffer());
const gltf = await new GLTFLoader().loadAsync('/files/' + expected.model);
const colors = expected.side_colors;
// The side whose colour a pixel has (within 40 per channel), 0 for black, -1 for neither.
function classify(r, g, b) {
  if (r < 20 && g < 20 && b < 20) return 0;
  for (let s = 0; s < colors.length; ++s) {
    const c = colors[s];
    if (Math.abs(r - c[0]) < 40 && Math.abs(g - c[1]) < 40 && Math.abs(b - c[2]) < 40) return s + 1;
  }
  return -1;
}
window.render = async (mode) => {
  const width = expected.width, height = expected.height;
  document.querySelectorAll('canvas').forEach((c) => c.remove());
  const renderer = new THREE.WebGLRenderer({antialias: false, preserveDrawingBuffer: true});
  renderer.setPixelRatio(1);
  renderer.setSize(width, height);
  renderer.setClearColor(0x000000, 1);
  document.body.appendChild(renderer.domElement);
  let camera;
  if (mode === 'default') {
    // A viewer's default: looking down -Z at the model's bounding box from +Z.
    const box = new THREE.Box3().setFromObject(gltf.scene.getObjectByName('mesh'));
    const size = box.getSize(new THREE.Vector3()).length();
    camera = new THREE.PerspectiveCamera(45, width / height, size / 100, size * 100);
    camera.position.copy(box.getCenter(new THREE.Vector3())).add(new THREE.Vector3(0, 0, 2 * size));
    camera.lookAt(box.getCenter(new THREE.Vector3()));
  } else {
    const index = gltf.parser.json.nodes.findIndex((n) => n.name === expected.camera);
    const node = await gltf.parser.getDependency('node', index);
    camera = node.isCamera ? node : node.getObjectByProperty('isCamera', true);
    camera.aspect = width / height;
    camera.updateProjectionMatrix();
  }
  renderer.render(gltf.scene, camera);
  const gl = renderer.getContext();
  const pixels = new Uint8Array(width * height * 4);
  gl.readPixels(0, 0, width, height, gl.RGBA, gl.UNSIGNED_BYTE, pixels);
  const stats = {covered: 0, unknown: 0, mismatched: 0, sides_seen: [], centre: null,
                 centroid_error_px: 0, yfov_deg: camera.fov};
  const sums = {};
  for (let y = 0; y < height; ++y) {
    for (let x = 0; x < width; ++x) {
      const i = 4 * ((height - 1 - y) * width + x);  // readPixels rows start at the bottom.
      const label = classify(pixels[i], pixels[i + 1], pixels[i + 2]);
      if (label !== 0) ++stats.covered;
      if (label < 0) { ++stats.unknown; continue; }
      if (label > 0) {
        const s = (sums['r' + label] ||= [0, 0, 0]);
        s[0] += x; s[1] += y; s[2] += 1;
      }
      if (mode !== 'default' && label !== labels[y * width + x]) ++stats.mismatched;
    }
  }
  const c = 4 * ((height >> 1) * width + (width >> 1));
  stats.centre = [pixels[c], pixels[c + 1], pixels[c + 2]];
  stats.sides_seen = Object.keys(sums).map((k) => Number(k.slice(1)) - 1).sort();
  if (mode !== 'default') {
    // Centroid of each side in the render against its centroid by our camera model.
    const want = {};
    for (let y = 0; y < height; ++y) {
      for (let x = 0; x < width; ++x) {
        const l = labels[y * width + x];
        if (l === 0) continue;
        const s = (want['r' + l] ||= [0, 0, 0]);
        s[0] += x; s[1] += y; s[2] += 1;
      }
    }
    stats.expected_sides = Object.keys(want).map((k) => Number(k.slice(1)) - 1).sort();
    for (const k of Object.keys(want)) {
      const w = want[k], g = sums[k] || [0, 0, 1];
      const d = Math.hypot(g[0] / g[2] - w[0] / w[2], g[1] / g[2] - w[1] / w[2]);
      stats.centroid_error_px = Math.max(stats.centroid_error_px, d);
    }
    stats.expected_covered = labels.reduce((n, l) => n + (l !== 0), 0);
  }
  return stats;
};
window.ready = true;
</script></body></html>`;

before(async () => {
  assert.ok(writer, 'RECONDUIT_GLTF_WRITER is not set (ctest sets it)');
  mkdirSync(out, {recursive: true});
  process.stdout.write(execFileSync(writer, [out]));
  expected = JSON.parse(readFileSync(join(out, 'expected.json'), 'utf8'));
  const three = join(here, 'node_modules/three');
  server = createServer((req, res) => {
    const url = decodeURIComponent(new URL(req.url, 'http://x').pathname);
    let file = null;
    if (url === '/favicon.ico') {
      res.writeHead(204);
      res.end();
      return;
    }
    if (url === '/') {
      res.writeHead(200, {'content-type': 'text/html'});
      res.end(page);
      return;
    }
    if (url.startsWith('/three/')) file = join(three, normalize(url.slice(7)));
    if (url.startsWith('/files/')) file = join(out, normalize(url.slice(7)));
    if (!file || !existsSync(file)) {
      console.log(`server: 404 for ${url}`);
      res.writeHead(404);
      res.end();
      return;
    }
    res.writeHead(200, {'content-type': types[extname(file)] || 'application/octet-stream'});
    res.end(readFileSync(file));
  });
  await new Promise((ok) => server.listen(0, '127.0.0.1', ok));
  baseUrl = `http://127.0.0.1:${server.address().port}/`;
});

after(() => server?.close());

test('the Khronos glTF validator reports no errors', async () => {
  const bytes = new Uint8Array(readFileSync(join(out, expected.model)));
  const report = await validator.validateBytes(bytes, {uri: expected.model, maxIssues: 1000});
  writeFileSync(join(out, 'validator.json'), JSON.stringify(report, null, 2));
  const issues = report.issues;
  console.log(`validator ${report.validatorVersion}: ${issues.numErrors} errors, ` +
              `${issues.numWarnings} warnings, ${issues.numInfos} infos, ${issues.numHints} hints; ` +
              `${report.info.drawCallCount} draw calls, ${report.info.totalVertexCount} vertices, ` +
              `${report.info.totalTriangleCount} triangles, ${report.info.materialCount} materials`);
  for (const m of issues.messages) console.log(`  ${m.severity} ${m.code} ${m.pointer || ''}: ${m.message}`);
  assert.equal(issues.numErrors, 0);
  assert.equal(issues.numWarnings, 0);
  assert.equal(report.info.totalVertexCount, expected.num_vertices);
  assert.deepEqual(report.info.extensionsUsed, ['KHR_materials_unlit']);
});

test('three.js renders the model textured, and the photo\'s camera lines up', async (t) => {
  if (!existsSync(chromiumPath)) {
    t.skip(`${chromiumPath} is absent: rendering needs chromium (bash docker/install-deps.sh test)`);
    return;
  }
  const browser = await chromium.launch({
    executablePath: chromiumPath,
    args: ['--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
           '--ignore-gpu-blocklist'],
  });
  try {
    const tab = await browser.newPage({viewport: {width: expected.width, height: expected.height},
                                       deviceScaleFactor: 1});
    const errors = [];
    tab.on('pageerror', (e) => errors.push(String(e)));
    tab.on('console', (m) => { if (m.type() === 'error') errors.push(m.text()); });
    await tab.goto(baseUrl);
    await tab.waitForFunction(() => window.ready === true, null, {timeout: 60000});
    assert.deepEqual(errors, []);

    // The default view: non-blank, textured (the centre shows a side's texture colour).
    const view = await tab.evaluate(() => window.render('default'));
    await tab.locator('canvas').screenshot({path: join(out, 'default.png')});
    const total = expected.width * expected.height;
    console.log(`default view: ${(100 * view.covered / total).toFixed(1)} % covered, ` +
                `sides ${view.sides_seen}, centre rgb ${view.centre}, ${view.unknown} other pixels`);
    assert.ok(view.covered > 0.02 * total, 'the default view is blank');
    assert.ok(view.sides_seen.length >= 1);
    const centreSide = expected.side_colors.findIndex(
        (c) => c.every((v, k) => Math.abs(v - view.centre[k]) < 40));
    assert.ok(centreSide >= 0, `the centre ${view.centre} is not a texture colour`);
    assert.ok(view.unknown < 0.01 * view.covered, 'pixels of neither texture nor background');

    // Through the camera named after the photo, at its 1024 x 768: every pixel sees the side
    // our camera model says it sees, but for the anti-aliasing-free edge pixels.
    const cam = await tab.evaluate(() => window.render('camera'));
    await tab.locator('canvas').screenshot({path: join(out, `camera_${expected.camera}.png`)});
    console.log(`camera ${expected.camera}: ${cam.covered} px covered (expected ` +
                `${cam.expected_covered}), sides ${cam.sides_seen} (expected ${cam.expected_sides}), ` +
                `${cam.mismatched} px on another side than ours, ${cam.unknown} other, ` +
                `side centroids within ${cam.centroid_error_px.toFixed(3)} px, yfov ${cam.yfov_deg} deg`);
    assert.deepEqual(cam.sides_seen, cam.expected_sides);
    assert.ok(cam.expected_covered > 0.05 * total);
    assert.ok(cam.mismatched < 0.005 * cam.expected_covered, `${cam.mismatched} pixels disagree`);
    assert.ok(cam.centroid_error_px < 0.25, `centroids ${cam.centroid_error_px} px off`);
  } finally {
    await browser.close();
  }
});
