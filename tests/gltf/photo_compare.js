// Comparing a render through a photo's glTF camera with the photo (tests/gltf/real_sets.test.mjs).
// Pure functions on RGBA pixel arrays (Uint8ClampedArray/Uint8Array, row-major from the top),
// loaded by the browser page and by node (photo_compare.test.mjs checks them on synthetic
// images).
//
// Two pixel frames at the comparison width W (1024 px):
// - the glTF frame: the pinhole camera three.js renders from the node's yfov and aspectRatio
//   (principal point at the centre, no distortion), W x H pixels;
// - the photo frame: the photo as our camera model sees it (core/geometry/camera.h: focal,
//   cx, cy, k1, k2 from the camera's extras, scaled like Camera::Scaled to W pixels wide),
//   which is where report.json's texture renders are measured.
// Distortion (camera.h): (x_d, y_d) = (x, y) (1 + k1 r^2 + k2 r^4) on normalised coordinates,
// pixel = f x_d + c; pixel centres at integers.

// The camera of the photo scaled to `width` pixels wide (Camera::Scaled: lround of the sizes,
// pixel centres at integers).
export function scaledIntrinsics(extras, width) {
  const s = width / extras.width;
  return {width, height: Math.round(extras.height * s), focal: extras.focal * s,
          cx: (extras.cx + 0.5) * s - 0.5, cy: (extras.cy + 0.5) * s - 0.5,
          k1: extras.k1 || 0, k2: extras.k2 || 0};
}

// The radius below which r -> r (1 + k1 r^2 + k2 r^4) is increasing (Infinity when always):
// the smallest positive root of 1 + 3 k1 s + 5 k2 s^2 = 0 in s = r^2.
export function monotoneRadius(k1, k2) {
  const roots = [];
  if (k2 === 0) {
    if (k1 < 0) roots.push(-1 / (3 * k1));
  } else {
    const disc = 9 * k1 * k1 - 20 * k2;
    if (disc >= 0) {
      const q = Math.sqrt(disc);
      roots.push((-3 * k1 - q) / (10 * k2), (-3 * k1 + q) / (10 * k2));
    }
  }
  const positive = roots.filter((s) => s > 0);
  return positive.length ? Math.sqrt(Math.min(...positive)) : Infinity;
}

export function distortFactor(x, y, k1, k2) {
  const r2 = x * x + y * y;
  return 1 + k1 * r2 + k2 * r2 * r2;
}

// Inverse of the distortion on the radius, by bisection inside the monotone range; null
// beyond where the distortion folds back.
export function undistortRadius(rd, k1, k2, rLimit = monotoneRadius(k1, k2)) {
  if (rd === 0 || (k1 === 0 && k2 === 0)) return rd;
  const dist = (r) => r * (1 + k1 * r * r + k2 * r * r * r * r);
  let lo = 0, hi = rLimit;
  if (!isFinite(hi)) {
    hi = Math.max(1, rd);
    while (dist(hi) < rd) hi *= 2;
  } else if (rd >= dist(rLimit)) {
    return null;
  }
  for (let i = 0; i < 64; ++i) {
    const mid = 0.5 * (lo + hi);
    if (dist(mid) < rd) lo = mid; else hi = mid;
  }
  return 0.5 * (lo + hi);
}

// The glTF frame's pixel (u, v) <-> normalised camera coordinates (x right, y down), for a
// three.js PerspectiveCamera of vertical field `yfov` (radians) and `aspect`, drawn on W x H.
export function gltfRay(u, v, W, H, yfov, aspect) {
  const t = Math.tan(yfov / 2);
  return [(2 * (u + 0.5) / W - 1) * t * aspect, (2 * (v + 0.5) / H - 1) * t];
}
export function gltfPixel(x, y, W, H, yfov, aspect) {
  const t = Math.tan(yfov / 2);
  return [(x / (t * aspect) + 1) * W / 2 - 0.5, (y / t + 1) * H / 2 - 0.5];
}

// OpenCV's INTER_AREA for shrinking: each output pixel the area-weighted mean of the input
// pixels it covers. RGBA in, RGBA out (alpha 255).
export function areaResize(src, sw, sh, dw, dh) {
  const weights = (n, m) => {  // For each output index, [[input index, weight], ...].
    const scale = n / m, out = [];
    for (let i = 0; i < m; ++i) {
      const a = i * scale, b = (i + 1) * scale, list = [];
      for (let j = Math.floor(a); j < Math.min(n, Math.ceil(b)); ++j) {
        const w = Math.min(b, j + 1) - Math.max(a, j);
        if (w > 1e-12) list.push([j, w / scale]);
      }
      out.push(list);
    }
    return out;
  };
  const wx = weights(sw, dw), wy = weights(sh, dh);
  const rows = new Float32Array(sh * dw * 3);  // Horizontal pass.
  for (let y = 0; y < sh; ++y) {
    for (let x = 0; x < dw; ++x) {
      let r = 0, g = 0, b = 0;
      for (const [j, w] of wx[x]) {
        const i = 4 * (y * sw + j);
        r += w * src[i]; g += w * src[i + 1]; b += w * src[i + 2];
      }
      const o = 3 * (y * dw + x);
      rows[o] = r; rows[o + 1] = g; rows[o + 2] = b;
    }
  }
  const dst = new Uint8ClampedArray(dw * dh * 4);
  for (let y = 0; y < dh; ++y) {
    for (let x = 0; x < dw; ++x) {
      let r = 0, g = 0, b = 0;
      for (const [j, w] of wy[y]) {
        const i = 3 * (j * dw + x);
        r += w * rows[i]; g += w * rows[i + 1]; b += w * rows[i + 2];
      }
      const o = 4 * (y * dw + x);
      dst[o] = Math.round(r); dst[o + 1] = Math.round(g); dst[o + 2] = Math.round(b); dst[o + 3] = 255;
    }
  }
  return dst;
}

// Bilinear sample of RGBA `img` (w x h) at (x, y), clamped at the edges, into out[0..2].
export function bilinear(img, w, h, x, y, out) {
  x = Math.min(Math.max(x, 0), w - 1);
  y = Math.min(Math.max(y, 0), h - 1);
  const x0 = Math.floor(x), y0 = Math.floor(y), fx = x - x0, fy = y - y0;
  const x1 = Math.min(x0 + 1, w - 1), y1 = Math.min(y0 + 1, h - 1);
  for (let c = 0; c < 3; ++c) {
    const a = img[4 * (y0 * w + x0) + c], b = img[4 * (y0 * w + x1) + c];
    const d = img[4 * (y1 * w + x0) + c], e = img[4 * (y1 * w + x1) + c];
    out[c] = (a * (1 - fx) + b * fx) * (1 - fy) + (d * (1 - fx) + e * fx) * fy;
  }
  return out;
}

// The photo resampled to the glTF frame (W x H, yfov, aspect): each pixel's ray distorted by
// the photo's camera `cam` (scaled to the photo's `photo` size: {data, width, height}, already
// at the comparison width or larger). With `undistort` false the photo is only resized (the
// pinhole's ray projected without distortion), to show what ignoring k1/k2 costs.
// Returns {data (RGBA), valid (1 where the ray lands inside the photo), maxShiftPx (largest
// displacement the distortion causes over the valid pixels, in glTF-frame pixels)}.
export function photoInGltfFrame(photo, cam, W, H, yfov, aspect, undistort = true) {
  const data = new Uint8ClampedArray(W * H * 4), valid = new Uint8Array(W * H);
  const rLimit = monotoneRadius(cam.k1, cam.k2), rgb = [0, 0, 0];
  let maxShiftPx = 0;
  for (let v = 0; v < H; ++v) {
    for (let u = 0; u < W; ++u) {
      const [x, y] = gltfRay(u, v, W, H, yfov, aspect);
      const r = Math.hypot(x, y);
      if (undistort && r >= rLimit) continue;
      const d = undistort ? distortFactor(x, y, cam.k1, cam.k2) : 1;
      const px = cam.focal * x * d + cam.cx, py = cam.focal * y * d + cam.cy;
      if (!(px >= -0.5 && py >= -0.5 && px < photo.width - 0.5 && py < photo.height - 0.5)) continue;
      const i = v * W + u;
      valid[i] = 1;
      maxShiftPx = Math.max(maxShiftPx, Math.abs(d - 1) * r * cam.focal * W / photo.width);
      bilinear(photo.data, photo.width, photo.height, px, py, rgb);
      data[4 * i] = rgb[0]; data[4 * i + 1] = rgb[1]; data[4 * i + 2] = rgb[2]; data[4 * i + 3] = 255;
    }
  }
  return {data, valid, maxShiftPx};
}

// The render (glTF frame, RGBA with alpha 255 where a face is drawn) warped to the photo frame
// of `cam` (W x cam.height), as core/texture/render_textured_mesh.cc warps its pinhole render:
// colour bilinear (background black), coverage nearest; pixels whose ray folds back or falls
// outside the render are uncovered, and counted in `outside`: the part of the photo the glTF
// camera does not see (glTF's camera has no off-centre principal point and no distortion).
export function renderInPhotoFrame(render, W, H, yfov, aspect, cam) {
  const data = new Uint8ClampedArray(cam.width * cam.height * 4);
  const covered = new Uint8Array(cam.width * cam.height);
  const rLimit = monotoneRadius(cam.k1, cam.k2), rgb = [0, 0, 0];
  let outside = 0;
  for (let b = 0; b < cam.height; ++b) {
    for (let a = 0; a < cam.width; ++a) {
      const xd = (a - cam.cx) / cam.focal, yd = (b - cam.cy) / cam.focal;
      const rd = Math.hypot(xd, yd);
      const r = undistortRadius(rd, cam.k1, cam.k2, rLimit);
      if (r === null) { ++outside; continue; }
      const s = rd > 0 ? r / rd : 1;
      const [u, v] = gltfPixel(xd * s, yd * s, W, H, yfov, aspect);
      const un = Math.round(u), vn = Math.round(v);
      if (un < 0 || vn < 0 || un >= W || vn >= H) { ++outside; continue; }
      const o = b * cam.width + a;
      covered[o] = render[4 * (vn * W + un) + 3] === 255 ? 1 : 0;
      if (!covered[o]) continue;
      // Bilinear with the background (black) outside the drawn faces, like cv::remap.
      const x0 = Math.floor(u), y0 = Math.floor(v), fx = u - x0, fy = v - y0;
      rgb[0] = rgb[1] = rgb[2] = 0;
      for (const [dx, dy, w] of [[0, 0, (1 - fx) * (1 - fy)], [1, 0, fx * (1 - fy)],
                                 [0, 1, (1 - fx) * fy], [1, 1, fx * fy]]) {
        const xx = x0 + dx, yy = y0 + dy;
        if (xx < 0 || yy < 0 || xx >= W || yy >= H) continue;
        const i = 4 * (yy * W + xx);
        if (render[i + 3] !== 255) continue;
        rgb[0] += w * render[i]; rgb[1] += w * render[i + 1]; rgb[2] += w * render[i + 2];
      }
      data[4 * o] = rgb[0]; data[4 * o + 1] = rgb[1]; data[4 * o + 2] = rgb[2]; data[4 * o + 3] = 255;
    }
  }
  return {data, covered, outside: outside / (cam.width * cam.height)};
}

// Covered share over the pixels where `valid` (all when null) and the mean absolute
// difference (0-255, mean of the three channels) over the covered ones.
export function coverageAndDifference(a, b, covered, valid, n) {
  let inside = 0, count = 0, sum = 0;
  for (let i = 0; i < n; ++i) {
    if (valid && !valid[i]) continue;
    ++inside;
    if (!covered[i]) continue;
    ++count;
    sum += Math.abs(a[4 * i] - b[4 * i]) + Math.abs(a[4 * i + 1] - b[4 * i + 1]) +
           Math.abs(a[4 * i + 2] - b[4 * i + 2]);
  }
  return {covered: inside ? count / inside : 0, mean_abs_diff: count ? sum / (3 * count) : null,
          pixels: inside};
}

// Gradient magnitude (|dx| + |dy| of central differences of the luma) of an RGBA image, 0 where
// the 3 x 3 neighbourhood leaves `mask` (so silhouettes and the photo's border add no edges).
export function gradient(img, w, h, mask) {
  const luma = new Float32Array(w * h);
  for (let i = 0; i < w * h; ++i) luma[i] = 0.299 * img[4 * i] + 0.587 * img[4 * i + 1] + 0.114 * img[4 * i + 2];
  const g = new Float32Array(w * h), ok = new Uint8Array(w * h);
  for (let y = 1; y < h - 1; ++y) {
    for (let x = 1; x < w - 1; ++x) {
      const i = y * w + x;
      let inside = true;
      for (let dy = -1; dy <= 1 && inside; ++dy)
        for (let dx = -1; dx <= 1; ++dx) if (!mask[i + dy * w + dx]) { inside = false; break; }
      if (!inside) continue;
      ok[i] = 1;
      g[i] = Math.abs(luma[i + 1] - luma[i - 1]) + Math.abs(luma[i + w] - luma[i - w]);
    }
  }
  return {g, ok};
}

// Line-up without colour: the image is cut into cols x rows tiles; in each, the shift (dx, dy)
// within +-range px that best correlates the render's edges (gradient magnitude) with the
// photo's (normalised cross-correlation over the pixels both have), refined to a fraction of a
// pixel by a parabola through the peak. A tile counts when at least minShare of it has edges
// of both and the peak correlation reaches minPeak (a tile of sky or of grey unseen faces
// has nothing to line up). Returns [{col, row, dx, dy, peak, pixels}] for the counted tiles.
export function tileShifts(a, b, w, h, {cols = 4, rows = 3, range = 8, minShare = 0.25, minPeak = 0.3} = {}) {
  const out = [];
  for (let ty = 0; ty < rows; ++ty) {
    for (let tx = 0; tx < cols; ++tx) {
      const x0 = Math.max(range, Math.floor(tx * w / cols)), x1 = Math.min(w - range, Math.floor((tx + 1) * w / cols));
      const y0 = Math.max(range, Math.floor(ty * h / rows)), y1 = Math.min(h - range, Math.floor((ty + 1) * h / rows));
      const pts = [];
      for (let y = y0; y < y1; ++y) for (let x = x0; x < x1; ++x) if (a.ok[y * w + x]) pts.push(y * w + x);
      if (pts.length < minShare * (x1 - x0) * (y1 - y0)) continue;
      const n = 2 * range + 1, score = new Float64Array(n * n).fill(-2);
      for (let dy = -range; dy <= range; ++dy) {
        for (let dx = -range; dx <= range; ++dx) {
          const off = dy * w + dx;
          let c = 0, sa = 0, sb = 0, saa = 0, sbb = 0, sab = 0;
          for (const i of pts) {
            if (!b.ok[i + off]) continue;
            const p = a.g[i], q = b.g[i + off];
            ++c; sa += p; sb += q; saa += p * p; sbb += q * q; sab += p * q;
          }
          if (c < 0.5 * pts.length) continue;
          const va = saa - sa * sa / c, vb = sbb - sb * sb / c;
          if (va <= 0 || vb <= 0) continue;
          score[(dy + range) * n + dx + range] = (sab - sa * sb / c) / Math.sqrt(va * vb);
        }
      }
      let best = 0;
      for (let k = 1; k < n * n; ++k) if (score[k] > score[best]) best = k;
      const bx = best % n, by = Math.floor(best / n), peak = score[best];
      if (peak < minPeak) continue;
      const refine = (m, c0, p) => {
        if (c0 <= 0 || c0 >= n - 1 || m < -1 || p < -1) return 0;
        const den = m - 2 * score[best] + p;
        return den < 0 ? 0.5 * (m - p) / den : 0;
      };
      const fx = refine(bx > 0 ? score[best - 1] : -2, bx, bx < n - 1 ? score[best + 1] : -2);
      const fy = refine(by > 0 ? score[best - n] : -2, by, by < n - 1 ? score[best + n] : -2);
      out.push({col: tx, row: ty, dx: bx - range + fx, dy: by - range + fy, peak, pixels: pts.length});
    }
  }
  return out;
}
