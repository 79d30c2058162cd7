// photo_compare.js on synthetic images whose answers are known (no browser, well under a
// second): the inverse distortion, the glTF frame's pixel <-> ray mapping, the area resize,
// undistorting a photo to the pinhole camera and warping a render back to the photo's frame,
// and the edge line-up finding a known shift. real_sets.test.mjs relies on all of these.
import {strict as assert} from 'node:assert';
import {test} from 'node:test';

import * as pc from './photo_compare.js';

const distort = (r, k1, k2) => r * (1 + k1 * r * r + k2 * r ** 4);

test('undistortRadius inverts the distortion inside the monotone range, null beyond', () => {
  for (const [k1, k2] of [[-0.1524, 0.1622], [0.05, -0.01], [-0.3, 0.0], [0.2, 0.1], [0, 0]]) {
    const limit = pc.monotoneRadius(k1, k2);
    const top = Math.min(1.2, 0.999 * limit);
    for (let r = 0; r <= top; r += top / 50) {
      const back = pc.undistortRadius(distort(r, k1, k2), k1, k2);
      assert.ok(Math.abs(back - r) < 1e-9, `k1 ${k1} k2 ${k2}: r ${r} -> ${back}`);
    }
  }
  // k1 = -0.3: r_d(r) = r - 0.3 r^3 peaks at r = 1/sqrt(0.9); farther distorted radii have no
  // preimage.
  const limit = pc.monotoneRadius(-0.3, 0);
  assert.ok(Math.abs(limit - 1 / Math.sqrt(0.9)) < 1e-12);
  assert.equal(pc.undistortRadius(distort(limit, -0.3, 0) + 1e-6, -0.3, 0), null);
  assert.equal(pc.monotoneRadius(0.1, 0.01), Infinity);
});

test('gltfPixel inverts gltfRay, and the centre ray is the optical axis', () => {
  const [W, H, yfov, aspect] = [1024, 683, 0.6, 1.5];
  for (const [u, v] of [[0, 0], [511.5, 341], [1023, 682], [100.25, 600.75]]) {
    const [x, y] = pc.gltfRay(u, v, W, H, yfov, aspect);
    const [u2, v2] = pc.gltfPixel(x, y, W, H, yfov, aspect);
    assert.ok(Math.abs(u2 - u) < 1e-9 && Math.abs(v2 - v) < 1e-9);
  }
  const [x, y] = pc.gltfRay((W - 1) / 2, (H - 1) / 2, W, H, yfov, aspect);
  assert.ok(Math.abs(x) < 1e-12 && Math.abs(y) < 1e-12);
  // The top edge of the frame is half the vertical field above the axis.
  assert.ok(Math.abs(pc.gltfRay(0, -0.5, W, H, yfov, aspect)[1] + Math.tan(yfov / 2)) < 1e-12);
});

test('areaResize averages the pixels each output pixel covers', () => {
  const [sw, sh] = [9, 6];
  const src = new Uint8ClampedArray(sw * sh * 4);
  for (let y = 0; y < sh; ++y) for (let x = 0; x < sw; ++x) src.set([x * 10, y * 20, 7, 255], 4 * (y * sw + x));
  const dst = pc.areaResize(src, sw, sh, 3, 2);
  // Output (1, 1) covers x 3..5 and y 3..5: means 40 and 80.
  assert.deepEqual([...dst.subarray(4 * (1 * 3 + 1), 4 * (1 * 3 + 1) + 4)], [40, 80, 7, 255]);
  // A fractional ratio (9 -> 4) keeps a constant image constant.
  const flat = new Uint8ClampedArray(sw * sh * 4).fill(100);
  assert.ok(pc.areaResize(flat, sw, sh, 4, 3).every((v, i) => v === (i % 4 === 3 ? 255 : 100)));
});

// A scene seen by a camera: Voronoi cells (one seed jittered in each square of 0.05 in
// normalised coordinates, about 13 px at the focal below) of pseudo-random colours, as a
// function of the ray (x, y): edges in every direction, none periodic. Averaged over 2 x 2
// samples per pixel so that edges fall between pixels.
const hash = (i, j, k) => Math.imul((i * 73856093) ^ (j * 19349663) ^ (k * 83492791), 0x9e3779b1) >>> 0;
const cell = (x, y) => {
  const gx = x / 0.05, gy = y / 0.05, i0 = Math.floor(gx), j0 = Math.floor(gy);
  let best = Infinity, colour = null;
  for (let j = j0 - 1; j <= j0 + 1; ++j) for (let i = i0 - 1; i <= i0 + 1; ++i) {
    const sx = i + (hash(i, j, 1) & 1023) / 1024, sy = j + (hash(i, j, 2) & 1023) / 1024;
    const d = (gx - sx) ** 2 + (gy - sy) ** 2;
    if (d < best) { best = d; colour = hash(i, j, 3); }
  }
  return [colour & 255, (colour >>> 8) & 255, (colour >>> 16) & 255];
};
function sample(ray, a, b) {
  const sum = [0, 0, 0];
  for (const sy of [-0.25, 0.25]) for (const sx of [-0.25, 0.25]) {
    const c = cell(...ray(a + sx, b + sy));
    for (let k = 0; k < 3; ++k) sum[k] += c[k] / 4;
  }
  return [...sum, 255];
}
// The photo our camera model takes of it: each pixel's ray through the inverse distortion.
function photoOf(cam) {
  const data = new Uint8ClampedArray(cam.width * cam.height * 4);
  const ray = (a, b) => {
    const xd = (a - cam.cx) / cam.focal, yd = (b - cam.cy) / cam.focal, rd = Math.hypot(xd, yd);
    const s = rd > 0 ? pc.undistortRadius(rd, cam.k1, cam.k2) / rd : 1;
    return [xd * s, yd * s];
  };
  for (let b = 0; b < cam.height; ++b) for (let a = 0; a < cam.width; ++a)
    data.set(sample(ray, a, b), 4 * (b * cam.width + a));
  return {data, width: cam.width, height: cam.height};
}
// The render through the glTF camera: the scene at each pinhole ray, shifted by (sx, sy) px.
function renderOf(W, H, yfov, aspect, sx = 0, sy = 0) {
  const data = new Uint8ClampedArray(W * H * 4);
  const ray = (u, v) => pc.gltfRay(u - sx, v - sy, W, H, yfov, aspect);
  for (let v = 0; v < H; ++v) for (let u = 0; u < W; ++u) data.set(sample(ray, u, v), 4 * (v * W + u));
  return data;
}

test('a distorted photo, undistorted to the glTF camera, matches the render and lines up', () => {
  // kermit's intrinsics at 240 x 180; the principal point off the centre, which glTF's
  // camera cannot say and the undistortion must take care of.
  const cam = {width: 240, height: 180, focal: 259.1, cx: 122.3, cy: 88.6, k1: -0.1524, k2: 0.1622};
  const yfov = 2 * Math.atan(0.5 * cam.height / cam.focal), aspect = cam.width / cam.height;
  const [W, H] = [cam.width, cam.height];
  const photo = photoOf(cam), render = renderOf(W, H, yfov, aspect);
  const covered = new Uint8Array(W * H).fill(1);

  const undist = pc.photoInGltfFrame(photo, cam, W, H, yfov, aspect, true);
  const plain = pc.photoInGltfFrame(photo, cam, W, H, yfov, aspect, false);
  const good = pc.coverageAndDifference(render, undist.data, covered, undist.valid, W * H);
  const bad = pc.coverageAndDifference(render, plain.data, covered, plain.valid, W * H);
  assert.ok(undist.maxShiftPx > 4, `distortion moves pixels by ${undist.maxShiftPx} px`);
  assert.ok(good.covered > 0.97, `${good.covered} of the frame lands inside the photo`);
  assert.ok(good.mean_abs_diff < 3, `undistorted: ${good.mean_abs_diff}`);
  assert.ok(bad.mean_abs_diff > 3 * good.mean_abs_diff, `resized only: ${bad.mean_abs_diff}`);

  // Back to the photo's frame, as the C++ renderer measures: the same colours again; the
  // photo's corners see past the pinhole frame (barrel distortion), so they stay uncovered.
  const warped = pc.renderInPhotoFrame(render, W, H, yfov, aspect, cam);
  const back = pc.coverageAndDifference(warped.data, photo.data, warped.covered, null, W * H);
  assert.ok(back.covered > 0.9 && back.covered < 0.99 && back.mean_abs_diff < 3, JSON.stringify(back));
  assert.ok(Math.abs(warped.outside - (1 - back.covered)) < 1e-12);  // The render covers its frame.
  for (const [a, b] of [[0, 0], [W - 1, 0], [0, H - 1], [W - 1, H - 1]]) assert.equal(warped.covered[b * W + a], 0);
  assert.equal(warped.covered[(H >> 1) * W + (W >> 1)], 1);

  const gRender = pc.gradient(render, W, H, covered);
  const tiles = pc.tileShifts(gRender, pc.gradient(undist.data, W, H, undist.valid), W, H);
  assert.ok(tiles.length >= 10, `${tiles.length} tiles`);
  for (const k of tiles) assert.ok(Math.hypot(k.dx, k.dy) < 0.3, JSON.stringify(k));
  // Without undistortion the corners are off by several pixels.
  const off = pc.tileShifts(gRender, pc.gradient(plain.data, W, H, plain.valid), W, H);
  assert.ok(Math.max(...off.map((k) => Math.hypot(k.dx, k.dy))) > 2);
});

test('the edge line-up finds a known shift, to a fraction of a pixel', () => {
  const [W, H, yfov, aspect] = [240, 180, 0.65, 240 / 180];
  const photo = renderOf(W, H, yfov, aspect);
  const shifted = renderOf(W, H, yfov, aspect, -2.5, 1.25);  // Render content 2.5 px left, 1.25 down.
  const all = new Uint8Array(W * H).fill(1);
  const tiles = pc.tileShifts(pc.gradient(shifted, W, H, all), pc.gradient(photo, W, H, all), W, H);
  assert.ok(tiles.length >= 10);
  for (const k of tiles) {
    assert.ok(Math.abs(k.dx - 2.5) < 0.35 && Math.abs(k.dy + 1.25) < 0.35, JSON.stringify(k));
  }
  // Beyond the search range the peak sits on its border: reported as that large, not as 0.
  const far = renderOf(W, H, yfov, aspect, 12, 0);
  const farTiles = pc.tileShifts(pc.gradient(far, W, H, all), pc.gradient(photo, W, H, all), W, H);
  for (const k of farTiles) assert.ok(Math.hypot(k.dx, k.dy) >= 5, JSON.stringify(k));
});
