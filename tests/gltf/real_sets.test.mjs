// model.glb of the real photo sets (issue 11): for each of fountain-P11, templeSparseRing and
// kermit present in ../shared/datasets, `reconduit reconstruct` on its photos, then
//   - the Khronos glTF validator on <result>/model.glb: no errors;
//   - in Debian's headless chromium, three.js GLTFLoader loads it and renders through the
//     camera node named after the first photo (as the file names it) at 1024 px wide with the
//     node's yfov and aspectRatio, on a transparent background; the photo is decoded in the
//     browser (drawn to a canvas), resized to 1024 px and undistorted to that pinhole camera
//     (k1/k2 of the camera's extras, photo_compare.js); figures: the share of the photo the
//     render covers and the mean absolute colour difference over the covered pixels, against
//     the issue's bounds (fountain >= 75 % at <= 10, temple and kermit >= 8 % at <= 20);
//   - the same figures in the photo's own (distorted) frame, the render warped through the
//     distortion as the C++ renderer does, agree with report.json's texture `renders` for that
//     photo (tolerances below);
//   - line-up without colour: in tiles of the image, the shift that best correlates the
//     render's edges with the undistorted photo's is within a pixel or two of zero.
// Saved in the output folder, per set: render.png (transparent background),
// photo_undistorted.png, side_by_side.png (render | photo undistorted | half-half blend),
// validator.json, figures.json, reconstruct.log, and result/ (the CLI's output folder).
//
// Environment (ctest sets the first two): RECONDUIT_CLI (the reconduit binary),
// RECONDUIT_GLTF_REAL_OUT (output folder), RECONDUIT_DATASETS (default ../shared/datasets
// from the repository root), RECONDUIT_GLTF_REAL_SETS (comma-separated names, default all
// three), RECONDUIT_GLTF_REAL_OPTIONS (pipeline options as JSON, passed with --options),
// RECONDUIT_GLTF_REAL_REUSE=1 (reuse <out>/<set>/result from an earlier run instead of
// reconstructing: for working on this test), RECONDUIT_CHROMIUM (default /usr/bin/chromium).
// A set whose photos are absent is skipped, saying so; so is everything without chromium.
import {strict as assert} from 'node:assert';
import {spawn} from 'node:child_process';
import {createWriteStream, existsSync, mkdirSync, readdirSync, readFileSync, rmSync,
        writeFileSync} from 'node:fs';
import {createServer} from 'node:http';
import {dirname, extname, join, normalize, resolve} from 'node:path';
import {after, before, test} from 'node:test';
import {fileURLToPath} from 'node:url';

import * as validator from 'gltf-validator';
import {chromium} from 'playwright-core';

const here = dirname(fileURLToPath(import.meta.url));
const root = resolve(here, '../..');
const out = resolve(process.env.RECONDUIT_GLTF_REAL_OUT || join(root, 'build/ci/tests/gltf_real'));
const datasets = resolve(process.env.RECONDUIT_DATASETS || join(root, '../shared/datasets'));
const cli = process.env.RECONDUIT_CLI;
const chromiumPath = process.env.RECONDUIT_CHROMIUM || '/usr/bin/chromium';
const reuse = process.env.RECONDUIT_GLTF_REAL_REUSE === '1';
const pipelineOptions = process.env.RECONDUIT_GLTF_REAL_OPTIONS || '';
const WIDTH = 1024;  // The issue's comparison width, as the texture stage's renders.

// The issue's bounds for the first photo (covered share, mean absolute difference).
const SETS = [
  {name: 'fountain-P11', minCovered: 0.75, maxDiff: 10},
  {name: 'templeSparseRing', minCovered: 0.08, maxDiff: 20},
  {name: 'kermit', minCovered: 0.08, maxDiff: 20},
];
const selected = (process.env.RECONDUIT_GLTF_REAL_SETS || SETS.map((s) => s.name).join(','))
    .split(',').filter(Boolean);
for (const name of selected) {
  if (!SETS.some((s) => s.name === name))
    throw new Error(`RECONDUIT_GLTF_REAL_SETS: unknown set ${name} (${SETS.map((s) => s.name).join(', ')})`);
}

// Agreement with the C++ renderer (report.json) in the photo's frame. Both render the same
// mesh through the same camera at pixel centres, and warp it through k1/k2 the same way, so
// the covered share differs where the two rasterisers disagree along silhouettes (about a
// pixel along each: a few thousand of the frame's 700-790 thousand pixels for these models,
// under half a percentage point; 1 point allows for it), and by the part of the photo the
// glTF camera cannot see: glTF has no off-centre principal point, so the centred pinhole
// misses a strip of the photo on the side the principal point is off to (fountain-P11's is
// 16 and 16 px off at full size: about 1.3 % of the frame), and barrel corners. That part the
// C++ renderer may cover and the page cannot: it widens the bound on one side only. The
// colours differ by more: three.js samples the JPEG (quality 90) atlas pages with mipmaps
// (trilinear), the C++ renderer the pages before encoding, bilinearly, without mipmaps;
// chromium's and OpenCV's JPEG decoders differ by a grey level here and there; and the C++
// side resizes an upsampled photo (temple, kermit: 640 -> 1024) with INTER_AREA, close to,
// not equal to, the page's bilinear. 2 grey levels (of differences of 9-14) covers these; a
// photo compared without its distortion differs by 4.7 on kermit (printed beside), and a
// camera a pixel off is caught by the line-up below.
const COVERED_TOLERANCE = 0.01;
const DIFF_TOLERANCE = 2.0;
// Line-up: each tile's best edge shift within 2 px (at 1024 px wide) and their median within
// 1 px; the sparse model's reprojection error is under a pixel of the original photos, and
// faces textured from other photos carry the mesh's error too.
const MAX_TILE_SHIFT = 2.0;
const MEDIAN_TILE_SHIFT = 1.0;

let browser = null;
let server;
let baseUrl;
let current = {result: null, images: null};  // The folders the server serves now.

const types = {'.js': 'text/javascript', '.mjs': 'text/javascript', '.html': 'text/html',
               '.glb': 'model/gltf-binary', '.json': 'application/json', '.png': 'image/png',
               '.jpg': 'image/jpeg', '.jpeg': 'image/jpeg'};

const page = `<!doctype html><html><head><style>body{margin:0;background:#000}</style>
<script type="importmap">{"imports": {"three": "/three/build/three.module.js",
  "three/addons/": "/three/examples/jsm/"}}</script></head><body>
<script type="module">
import * as THREE from 'three';
import {GLTFLoader} from 'three/addons/loaders/GLTFLoader.js';
import * as pc from '/lib/photo_compare.js';

function png(rgba, w, h) {
  const canvas = document.createElement('canvas');
  canvas.width = w; canvas.height = h;
  canvas.getContext('2d').putImageData(new ImageData(new Uint8ClampedArray(rgba), w, h), 0, 0);
  return canvas.toDataURL('image/png');
}

async function decodePhoto(url) {
  const blob = await (await fetch(url)).blob();
  const bitmap = await createImageBitmap(blob, {colorSpaceConversion: 'none', premultiplyAlpha: 'none'});
  const canvas = new OffscreenCanvas(bitmap.width, bitmap.height);
  const ctx = canvas.getContext('2d');
  ctx.drawImage(bitmap, 0, 0);
  return {data: ctx.getImageData(0, 0, bitmap.width, bitmap.height).data, width: bitmap.width,
          height: bitmap.height};
}

window.compareWithPhoto = async ({model, photo, camera, width}) => {
  const seconds = {};
  let t = performance.now();
  const lap = (name) => { const now = performance.now(); seconds[name] = (now - t) / 1000; t = now; };
  const gltf = await new GLTFLoader().loadAsync(model);
  lap('load');
  const json = gltf.parser.json;
  const index = json.nodes.findIndex((n) => n.name === camera);
  if (index < 0) return {error: 'model.glb has no node named ' + camera};
  const node = await gltf.parser.getDependency('node', index);
  const cam = node.isCamera ? node : node.getObjectByProperty('isCamera', true);
  if (!cam) return {error: 'node ' + camera + ' has no camera'};
  const extras = json.cameras[json.nodes[index].camera].extras;
  const yfov = THREE.MathUtils.degToRad(cam.fov), aspect = cam.aspect;
  const photoCam = pc.scaledIntrinsics(extras, width);
  const W = width, H = photoCam.height, n = W * H;

  const canvas = document.createElement('canvas');
  document.body.appendChild(canvas);
  const renderer = new THREE.WebGLRenderer({canvas, antialias: false, alpha: true,
                                            preserveDrawingBuffer: true});
  renderer.setPixelRatio(1);
  renderer.setSize(W, H, false);
  renderer.setClearColor(0x000000, 0);
  renderer.render(gltf.scene, cam);
  const gl = renderer.getContext();
  const flipped = new Uint8Array(n * 4);
  gl.readPixels(0, 0, W, H, gl.RGBA, gl.UNSIGNED_BYTE, flipped);
  const render = new Uint8ClampedArray(n * 4);  // Rows from the top.
  for (let y = 0; y < H; ++y) render.set(flipped.subarray((H - 1 - y) * W * 4, (H - y) * W * 4), y * W * 4);
  const covered = new Uint8Array(n);
  let blank = true;
  for (let i = 0; i < n; ++i) {
    covered[i] = render[4 * i + 3] === 255 ? 1 : 0;
    if (covered[i] && (render[4 * i] > 8 || render[4 * i + 1] > 8 || render[4 * i + 2] > 8)) blank = false;
  }
  let distinct = new Set();
  for (let i = 0; i < n && distinct.size < 1000; i += 7) if (covered[i]) distinct.add((render[4 * i] << 16) | (render[4 * i + 1] << 8) | render[4 * i + 2]);
  lap('render');

  const full = await decodePhoto(photo);
  if (full.width !== extras.width || full.height !== extras.height)
    return {error: 'the photo is ' + full.width + ' x ' + full.height + ', the camera ' + extras.width + ' x ' + extras.height};
  // The photo at the comparison size, as the texture stage resizes it (INTER_AREA when
  // shrinking; bilinear when enlarging), and the camera of the array sampled.
  let src = full, srcCam = {focal: extras.focal, cx: extras.cx, cy: extras.cy, k1: photoCam.k1, k2: photoCam.k2};
  let photoFrame;
  if (full.width > W) {
    photoFrame = pc.areaResize(full.data, full.width, full.height, W, H);
    src = {data: photoFrame, width: W, height: H};
    srcCam = photoCam;
  } else {
    photoFrame = new Uint8ClampedArray(n * 4);
    const rgb = [0, 0, 0];
    for (let b = 0; b < H; ++b) for (let a = 0; a < W; ++a) {
      pc.bilinear(full.data, full.width, full.height, (a + 0.5) * full.width / W - 0.5, (b + 0.5) * full.height / H - 0.5, rgb);
      const o = 4 * (b * W + a);
      photoFrame[o] = rgb[0]; photoFrame[o + 1] = rgb[1]; photoFrame[o + 2] = rgb[2]; photoFrame[o + 3] = 255;
    }
  }
  lap('photo');

  // The glTF frame: the photo undistorted to the node's pinhole camera, and merely resized.
  const undist = pc.photoInGltfFrame(src, srcCam, W, H, yfov, aspect, true);
  const plain = pc.photoInGltfFrame(src, srcCam, W, H, yfov, aspect, false);
  const gltfFrame = pc.coverageAndDifference(render, undist.data, covered, undist.valid, n);
  const uncorrected = pc.coverageAndDifference(render, plain.data, covered, plain.valid, n);
  // The photo's frame, as the C++ renderer measures.
  const warped = pc.renderInPhotoFrame(render, W, H, yfov, aspect, photoCam);
  const cppFrame = pc.coverageAndDifference(warped.data, photoFrame, warped.covered, null, n);
  cppFrame.outside = warped.outside;
  lap('compare');

  const renderMask = new Uint8Array(n);
  for (let i = 0; i < n; ++i) renderMask[i] = covered[i] && undist.valid[i];
  const gRender = pc.gradient(render, W, H, renderMask);
  const tiles = pc.tileShifts(gRender, pc.gradient(undist.data, W, H, undist.valid), W, H);
  const tilesUncorrected = pc.tileShifts(gRender, pc.gradient(plain.data, W, H, plain.valid), W, H);
  lap('lineup');

  const side = new Uint8ClampedArray(3 * n * 4);
  for (let y = 0; y < H; ++y) for (let x = 0; x < W; ++x) {
    const i = 4 * (y * W + x);
    for (let c = 0; c < 3; ++c) {
      const r = covered[y * W + x] ? render[i + c] : 0, p = undist.data[i + c];
      side[4 * (y * 3 * W + x) + c] = r;
      side[4 * (y * 3 * W + W + x) + c] = p;
      side[4 * (y * 3 * W + 2 * W + x) + c] = covered[y * W + x] ? (r + p) / 2 : p;
    }
    for (let k = 0; k < 3; ++k) side[4 * (y * 3 * W + k * W + x) + 3] = 255;
  }
  const images = {render: png(render, W, H), photo_undistorted: png(undist.data, W, H),
                  side_by_side: png(side, 3 * W, H)};
  lap('images');
  return {width: W, height: H, yfov, aspect, extras, blank, distinct_colours: distinct.size,
          node_count: json.nodes.length, camera_names: json.nodes.filter((nd) => nd.camera !== undefined).map((nd) => nd.name),
          max_distortion_shift_px: undist.maxShiftPx, gltf_frame: gltfFrame, uncorrected,
          photo_frame: cppFrame, tiles, tiles_uncorrected: tilesUncorrected, seconds, images};
};
window.ready = true;
</script></body></html>`;

function serve(req, res) {
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
  if (url === '/lib/photo_compare.js') file = join(here, 'photo_compare.js');
  if (url.startsWith('/three/')) file = join(here, 'node_modules/three', normalize(url.slice(7)));
  if (url.startsWith('/result/') && current.result) file = join(current.result, normalize(url.slice(8)));
  if (url.startsWith('/images/') && current.images) file = join(current.images, normalize(url.slice(8)));
  if (!file || !existsSync(file)) {
    console.log(`server: 404 for ${url}`);
    res.writeHead(404);
    res.end();
    return;
  }
  res.writeHead(200, {'content-type': types[extname(file).toLowerCase()] || 'application/octet-stream'});
  res.end(readFileSync(file));
}

before(async () => {
  mkdirSync(out, {recursive: true});
  server = createServer(serve);
  await new Promise((ok) => server.listen(0, '127.0.0.1', ok));
  baseUrl = `http://127.0.0.1:${server.address().port}/`;
  if (existsSync(chromiumPath)) {
    browser = await chromium.launch({
      executablePath: chromiumPath,
      args: ['--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
             '--ignore-gpu-blocklist'],
    });
  }
});

after(async () => {
  await browser?.close();
  server?.close();
});

// Runs the CLI, its output into `log`; resolves with the exit status.
function reconstruct(images, result, log, optionsFile) {
  const args = ['reconstruct', images, result];
  if (optionsFile) args.push('--options', optionsFile);
  return new Promise((ok, fail) => {
    const stream = createWriteStream(log);
    const child = spawn(cli, args, {stdio: ['ignore', 'pipe', 'pipe']});
    child.stdout.pipe(stream);
    child.stderr.pipe(stream);
    child.on('error', fail);
    child.on('close', (code) => stream.end(() => ok(code)));
  });
}

const pct = (x) => `${(100 * x).toFixed(1)} %`;
const fix = (x, d = 2) => (x === null || x === undefined ? 'null' : x.toFixed(d));
const median = (v) => { const s = [...v].sort((a, b) => a - b); return s.length ? s[s.length >> 1] : NaN; };

for (const set of SETS) {
  if (!selected.includes(set.name)) continue;
  test(`${set.name}: model.glb validates, renders textured and lines up with its first photo`, async (t) => {
    const images = join(datasets, set.name, 'images');
    if (!existsSync(images)) {
      t.skip(`${images} is absent: the ${set.name} photos are needed`);
      return;
    }
    if (!browser) {
      t.skip(`${chromiumPath} is absent: rendering needs chromium (bash docker/install-deps.sh test)`);
      return;
    }
    assert.ok(cli, 'RECONDUIT_CLI is not set (ctest sets it)');
    const dir = join(out, set.name), result = join(dir, 'result');
    mkdirSync(dir, {recursive: true});
    const figures = {set: set.name, options: pipelineOptions ? JSON.parse(pipelineOptions) : {}};

    const started = Date.now();
    if (!(reuse && existsSync(join(result, 'model.glb')))) {
      rmSync(result, {recursive: true, force: true});
      rmSync(`${result}.work`, {recursive: true, force: true});
      let optionsFile = null;
      if (pipelineOptions) {
        optionsFile = join(dir, 'options.json');
        writeFileSync(optionsFile, pipelineOptions);
      }
      const code = await reconstruct(images, result, join(dir, 'reconstruct.log'), optionsFile);
      assert.equal(code, 0, `reconduit reconstruct failed (exit ${code}); see ${join(dir, 'reconstruct.log')}`);
      figures.reconstruct_seconds = (Date.now() - started) / 1000;
    }
    assert.ok(existsSync(join(result, 'model.glb')), 'no model.glb in the result');
    const report = JSON.parse(readFileSync(join(result, 'report.json'), 'utf8'));
    const textureStage = report.stages.find((s) => s.name === 'texture');
    assert.equal(textureStage?.status, 'success', 'the texture stage did not succeed');

    // The first photo as the folder names it.
    const photo = readdirSync(images).filter((f) => !f.startsWith('.')).sort()[0];
    const cppRender = textureStage.summary.renders.find((r) => r.name === photo);
    assert.ok(cppRender, `report.json has no render for ${photo} (not registered?)`);

    const vStarted = Date.now();
    const bytes = new Uint8Array(readFileSync(join(result, 'model.glb')));
    const vreport = await validator.validateBytes(bytes, {uri: 'model.glb', maxIssues: 1000});
    writeFileSync(join(dir, 'validator.json'), JSON.stringify(vreport, null, 2));
    const issues = vreport.issues;
    figures.validator = {errors: issues.numErrors, warnings: issues.numWarnings, infos: issues.numInfos,
                         hints: issues.numHints, seconds: (Date.now() - vStarted) / 1000,
                         bytes: bytes.length, vertices: vreport.info.totalVertexCount,
                         triangles: vreport.info.totalTriangleCount};
    console.log(`${set.name}: validator ${vreport.validatorVersion} on ${(bytes.length / 1e6).toFixed(1)} MB: ` +
                `${issues.numErrors} errors, ${issues.numWarnings} warnings, ${issues.numInfos} infos; ` +
                `${vreport.info.totalTriangleCount} triangles, ${vreport.info.materialCount} materials`);
    for (const m of issues.messages.filter((m) => m.severity <= 1).slice(0, 20))
      console.log(`  ${m.severity === 0 ? 'error' : 'warning'} ${m.code} ${m.pointer || ''}: ${m.message}`);
    assert.equal(issues.numErrors, 0, 'the validator reports errors (validator.json)');

    current = {result, images};
    const tab = await browser.newPage({viewport: {width: WIDTH, height: 800}, deviceScaleFactor: 1});
    const errors = [];
    tab.on('pageerror', (e) => errors.push(String(e)));
    tab.on('console', (m) => { if (m.type() === 'error') errors.push(m.text()); });
    const bStarted = Date.now();
    let r;
    try {
      await tab.goto(baseUrl);
      await tab.waitForFunction(() => window.ready === true, null, {timeout: 60000});
      r = await tab.evaluate((a) => window.compareWithPhoto(a),
                             {model: '/result/model.glb', photo: `/images/${encodeURIComponent(photo)}`,
                              camera: photo, width: WIDTH});
    } finally {
      await tab.close();
    }
    figures.browser_seconds = (Date.now() - bStarted) / 1000;
    assert.deepEqual(errors, []);
    assert.ok(!r.error, r.error);
    for (const [name, url] of Object.entries(r.images))
      writeFileSync(join(dir, `${name}.png`), Buffer.from(url.slice(url.indexOf(',') + 1), 'base64'));
    delete r.images;
    Object.assign(figures, r, {photo, cpp: cppRender});
    writeFileSync(join(dir, 'figures.json'), JSON.stringify(figures, null, 2));

    const g = r.gltf_frame, p = r.photo_frame, u = r.uncorrected;
    const shifts = r.tiles.map((k) => Math.hypot(k.dx, k.dy));
    const shiftsUncorrected = r.tiles_uncorrected.map((k) => Math.hypot(k.dx, k.dy));
    console.log(`${set.name}: reconstruct ${fix(figures.reconstruct_seconds, 1)} s, browser ` +
                `${fix(figures.browser_seconds, 1)} s (${Object.entries(r.seconds).map(([k, v]) => `${k} ${v.toFixed(1)}`).join(', ')})`);
    console.log(`${set.name}: ${photo} at ${r.width} x ${r.height}, yfov ${fix(r.yfov * 180 / Math.PI, 3)} deg, ` +
                `k1 ${fix(r.extras.k1, 4)} k2 ${fix(r.extras.k2, 4)} (up to ${fix(r.max_distortion_shift_px, 1)} px)`);
    console.log(`  undistorted to the glTF camera: ${pct(g.covered)} covered, mean abs diff ${fix(g.mean_abs_diff)} ` +
                `(bounds >= ${pct(set.minCovered)}, <= ${set.maxDiff}); merely resized: ${pct(u.covered)}, ${fix(u.mean_abs_diff)}`);
    console.log(`  photo frame (render warped through k1/k2): ${pct(p.covered)} at ${fix(p.mean_abs_diff)} ` +
                `(${pct(p.outside)} of the photo outside the glTF view); ` +
                `report.json: ${pct(cppRender.covered)} at ${fix(cppRender.mean_abs_diff)}`);
    console.log(`  edge line-up, ${r.tiles.length} of 12 tiles: shifts median ${fix(median(shifts))} px, max ` +
                `${fix(Math.max(...shifts))} px [${r.tiles.map((k) => `${fix(k.dx, 1)},${fix(k.dy, 1)}`).join(' ')}]; ` +
                `without undistortion median ${fix(median(shiftsUncorrected))}, max ${fix(Math.max(...shiftsUncorrected))}`);

    // The file: every registered photo has its camera node, named as uploaded.
    for (const name of textureStage.summary.renders.map((x) => x.name))
      assert.ok(r.camera_names.includes(name), `no camera node named ${name}`);
    assert.ok(Math.abs(r.yfov - 2 * Math.atan(0.5 * r.extras.height / r.extras.focal)) < 1e-6,
              'yfov does not match the extras\' focal');
    assert.ok(Math.abs(r.aspect - r.extras.width / r.extras.height) < 1e-9, 'aspectRatio is not the photo\'s');
    // Textured and non-blank.
    assert.ok(!r.blank && r.distinct_colours > 100, `the render is blank or flat (${r.distinct_colours} colours)`);
    // The issue's bounds, against the photo undistorted to the glTF camera.
    assert.ok(g.covered >= set.minCovered, `covered ${pct(g.covered)} < ${pct(set.minCovered)}`);
    assert.ok(g.mean_abs_diff <= set.maxDiff, `mean abs diff ${fix(g.mean_abs_diff)} > ${set.maxDiff}`);
    // The same as the C++ renderer, in the photo's frame.
    assert.ok(p.covered - cppRender.covered <= COVERED_TOLERANCE &&
              cppRender.covered - p.covered <= COVERED_TOLERANCE + p.outside,
              `covered ${pct(p.covered)} vs report.json ${pct(cppRender.covered)} ` +
              `(${pct(p.outside)} of the photo outside the glTF camera's view)`);
    assert.ok(Math.abs(p.mean_abs_diff - cppRender.mean_abs_diff) <= DIFF_TOLERANCE,
              `mean abs diff ${fix(p.mean_abs_diff)} vs report.json ${fix(cppRender.mean_abs_diff)}`);
    // Lined up: edges agree without colour.
    assert.ok(r.tiles.length >= 2, `only ${r.tiles.length} tiles have edges to line up`);
    assert.ok(median(shifts) <= MEDIAN_TILE_SHIFT, `median tile shift ${fix(median(shifts))} px`);
    assert.ok(Math.max(...shifts) <= MAX_TILE_SHIFT, `largest tile shift ${fix(Math.max(...shifts))} px`);
    // Undistorting is the right direction: where k1/k2 move pixels by more than 2 px, the
    // undistorted photo matches better than the merely resized one.
    if (r.max_distortion_shift_px > 2)
      assert.ok(g.mean_abs_diff < u.mean_abs_diff, 'the undistorted photo matches worse than the resized one');
  });
}
