// The page's 3D view of a job's model.glb (core/io/gltf.h): the textured mesh, and each photo's
// camera as a frustum one can click to look through it. three.js comes from the page's own
// server (web/vendor/, copied from npm by scripts/web_deps.sh; index.html's import map), never
// from a CDN. app.js imports this module only when a job has a model, so the page without one
// never loads three.js.
//
// The view renders on demand (when something moved), not in a loop: the page may stay open
// for hours beside a busy worker.
import * as THREE from 'three';
import {GLTFLoader} from 'three/addons/loaders/GLTFLoader.js';
import {OrbitControls} from 'three/addons/controls/OrbitControls.js';

const BACKGROUND = 0x1d2330;  // The view's background.
const BARS = 0x101318;  // Around a photo's view where the canvas is wider or taller.
const FRUSTUM = 0xffc94d;
const FRUSTUM_SELECTED = 0x5fd3ff;
const OVERVIEW_FOV = 50;  // Degrees, vertical.
// A press that moves less than this (px) is a click, not a drag.
const CLICK_SLOP = 5;

let current = null;  // The active view (one at a time: WebGL contexts are a scarce resource).

// Frees the GPU memory of everything below `root`.
function dispose(root) {
  root.traverse((object) => {
    if (object.geometry) object.geometry.dispose();
    const materials = Array.isArray(object.material) ? object.material : [object.material];
    for (const material of materials) {
      if (!material) continue;
      for (const value of Object.values(material)) {
        if (value && value.isTexture) value.dispose();
      }
      material.dispose();
    }
  });
}

// A camera's frustum in its own frame (looking down -Z, +Y up): lines from the centre to a
// rectangle `depth` ahead, a small triangle above the rectangle marking the photo's top, and an
// invisible pyramid to click on.
function makeFrustum(camera, depth) {
  const h = depth * Math.tan(THREE.MathUtils.degToRad(camera.fov) / 2);
  const w = h * camera.aspect;
  const z = -depth;
  const corners = [[-w, -h], [w, -h], [w, h], [-w, h]].map(([x, y]) => new THREE.Vector3(x, y, z));
  const apex = new THREE.Vector3(0, 0, 0);
  const points = [];
  for (let i = 0; i < 4; ++i) points.push(apex, corners[i], corners[i], corners[(i + 1) % 4]);
  const top = new THREE.Vector3(0, h * 1.5, z);
  points.push(new THREE.Vector3(-w * 0.4, h * 1.1, z), top, top,
              new THREE.Vector3(w * 0.4, h * 1.1, z));
  const lines = new THREE.LineSegments(
      new THREE.BufferGeometry().setFromPoints(points),
      new THREE.LineBasicMaterial({color: FRUSTUM}));

  const pyramid = new THREE.BufferGeometry().setFromPoints([apex, ...corners]);
  pyramid.setIndex([0, 1, 2, 0, 2, 3, 0, 3, 4, 0, 4, 1, 1, 3, 2, 1, 4, 3]);
  const pick = new THREE.Mesh(pyramid, new THREE.MeshBasicMaterial(
      {side: THREE.DoubleSide, colorWrite: false, depthWrite: false}));
  const frustum = new THREE.Group();
  frustum.add(lines, pick);
  frustum.userData.lines = lines;
  frustum.userData.pick = pick;
  // A point inside the pyramid, for inspect().screenPoint.
  frustum.userData.inside = new THREE.Vector3(0, 0, z * 0.6);
  return frustum;
}

// The photo's name as uploaded: GLTFLoader keeps the node's own name in userData.name (its
// `name` drops characters such as '.').
const photoName = (camera) => camera.userData.name || camera.name;

class ModelView {
  constructor(canvasHolder, callbacks) {
    this.holder = canvasHolder;
    this.callbacks = callbacks;  // {onSelect(name, camera | null)}
    this.renderer = new THREE.WebGLRenderer({antialias: true});
    this.renderer.setPixelRatio(window.devicePixelRatio || 1);
    this.holder.replaceChildren(this.renderer.domElement);
    this.scene = new THREE.Scene();
    this.scene.background = new THREE.Color(BACKGROUND);
    // For a model without texture or colours (a plain lit material); unlit textures ignore them.
    this.scene.add(new THREE.HemisphereLight(0xffffff, 0x444444, 2.5));
    this.view = new THREE.PerspectiveCamera(OVERVIEW_FOV, 1, 0.01, 100);
    this.controls = new OrbitControls(this.view, this.renderer.domElement);
    this.controls.addEventListener('change', () => {
      if (!this.moving) this.leavePhoto();
      this.requestRender();
    });
    this.cameras = [];  // The model's photo cameras, by name.
    this.selected = null;
    this.model = null;
    this.renderPending = false;
    this.listenForClicks();
    this.resizeObserver = new ResizeObserver(() => this.resize());
    this.resizeObserver.observe(this.holder);
    this.resize();
  }

  // Loads `url`; onProgress(loaded, total) while it downloads, then resolves with a summary
  // ({faces, cameras}) once it is shown. `bytes` (the file listing's size) stands in for a
  // missing Content-Length.
  load(url, bytes, onProgress) {
    this.manager = new THREE.LoadingManager();
    const loader = new GLTFLoader(this.manager);
    return new Promise((resolve, reject) => {
      loader.load(url, (gltf) => {
        if (this.disposed) {
          dispose(gltf.scene);
          reject(new DOMException('the view was closed', 'AbortError'));
          return;
        }
        resolve(this.show(gltf));
      }, (event) => {
        onProgress(event.loaded, event.lengthComputable ? event.total : bytes);
      }, reject);
    });
  }

  show(gltf) {
    this.model = gltf.scene;
    this.scene.add(this.model);
    this.model.updateMatrixWorld(true);
    let faces = 0;
    const meshBox = new THREE.Box3();
    this.model.traverse((object) => {
      if (!object.isMesh) return;
      const g = object.geometry;
      faces += (g.index ? g.index.count : g.attributes.position.count) / 3;
      meshBox.expandByObject(object);
    });
    this.cameras = gltf.cameras.filter((c) => c.isPerspectiveCamera)
        .sort((a, b) => photoName(a).localeCompare(photoName(b), undefined, {numeric: true}));
    this.frame(meshBox);
    // Frusta a few percent of the scene: visible, without hiding the model.
    const depth = 0.07 * this.radius;
    for (const camera of this.cameras) {
      const frustum = makeFrustum(camera, depth);
      frustum.userData.camera = camera;
      camera.userData.frustum = frustum;
      camera.add(frustum);
    }
    this.model.updateMatrixWorld(true);
    this.overview();
    return {faces, cameras: this.cameras.map(photoName)};
  }

  // What the overview turns around and how far it stands back. The photos' subject is where
  // their optical axes meet (least squares), when they do so in front of the cameras: a far
  // background piece of the mesh (a façade behind a fountain) then neither moves the centre nor
  // shrinks the model; the radius reaches the farthest camera. Otherwise (one camera, parallel
  // axes, a panorama) the bounding box of the mesh and the cameras.
  frame(meshBox) {
    const centres = this.cameras.map((c) => c.getWorldPosition(new THREE.Vector3()));
    const axes = this.cameras.map((c) => c.getWorldDirection(new THREE.Vector3()));
    let centre = null;
    if (this.cameras.length >= 2) {
      // sum (I - d d^T) p = sum (I - d d^T) c over the cameras (centre c, unit direction d).
      const a = new THREE.Matrix3().set(0, 0, 0, 0, 0, 0, 0, 0, 0);
      const b = new THREE.Vector3();
      for (let i = 0; i < centres.length; ++i) {
        const d = axes[i], c = centres[i];
        const m = new THREE.Matrix3().set(1 - d.x * d.x, -d.x * d.y, -d.x * d.z,
                                          -d.y * d.x, 1 - d.y * d.y, -d.y * d.z,
                                          -d.z * d.x, -d.z * d.y, 1 - d.z * d.z);
        for (let k = 0; k < 9; ++k) a.elements[k] += m.elements[k];
        b.add(c.clone().applyMatrix3(m));
      }
      if (Math.abs(a.determinant()) > 1e-6 * centres.length ** 3) {
        const p = b.applyMatrix3(a.clone().invert());
        const inFront = centres.filter((c, i) => p.clone().sub(c).dot(axes[i]) > 0).length;
        if (inFront >= 0.75 * centres.length) centre = p;
      }
    }
    if (centre) {
      this.centre = centre;
      this.radius = Math.max(...centres.map((c) => c.distanceTo(centre)), 1e-6);
      return;
    }
    const everything = meshBox.clone();
    for (const c of centres) everything.expandByPoint(c);
    if (everything.isEmpty()) everything.set(new THREE.Vector3(-1, -1, -1), new THREE.Vector3(1, 1, 1));
    this.centre = (meshBox.isEmpty() ? everything : meshBox).getCenter(new THREE.Vector3());
    this.radius = Math.max(everything.getBoundingSphere(new THREE.Sphere()).radius, 1e-6);
  }

  // The whole scene (model and cameras), seen from the side the photos saw (+Z, a little above).
  overview() {
    this.leavePhoto();
    this.moving = true;
    // Close enough that the model is not lost among the cameras; they may reach the edges.
    const distance = this.radius / Math.sin(THREE.MathUtils.degToRad(OVERVIEW_FOV) / 2) * 0.8;
    this.view.fov = OVERVIEW_FOV;
    this.view.near = distance / 1000;
    this.view.far = distance * 10;
    this.view.position.copy(this.centre)
        .addScaledVector(new THREE.Vector3(0, 0.35, 1).normalize(), distance);
    this.controls.target.copy(this.centre);
    this.controls.update();
    this.moving = false;
    this.resize();
  }

  // Looks through the photo's camera: its centre, orientation, vertical field of view and
  // aspect (the view shows bars where the canvas is wider or taller than the photo).
  lookThrough(name) {
    const camera = this.cameras.find((c) => photoName(c) === name);
    if (!camera) return false;
    this.leavePhoto();
    this.moving = true;
    camera.updateMatrixWorld(true);
    camera.matrixWorld.decompose(this.view.position, this.view.quaternion, new THREE.Vector3());
    this.view.fov = camera.fov;
    this.view.near = camera.near;
    this.view.far = camera.far;
    // Orbiting from here turns around the model's centre as seen along this camera's axis.
    const forward = new THREE.Vector3(0, 0, -1).applyQuaternion(this.view.quaternion);
    const ahead = Math.max(this.centre.clone().sub(this.view.position).dot(forward), 0.1 * this.radius);
    this.controls.target.copy(this.view.position).addScaledVector(forward, ahead);
    this.selected = camera;
    camera.userData.frustum.visible = false;  // The view is inside it.
    this.resize();
    this.moving = false;
    this.callbacks.onSelect(name, camera);
    return true;
  }

  leavePhoto() {
    if (!this.selected) return;
    this.selected.userData.frustum.visible = true;
    this.selected = null;
    this.resize();
    this.callbacks.onSelect(null, null);
  }

  // The part of the canvas the scene is drawn in (CSS pixels from the canvas's top left): all
  // of it, or the photo's aspect centred in it.
  viewport() {
    const width = this.holder.clientWidth, height = this.holder.clientHeight;
    if (!this.selected) return {x: 0, y: 0, width, height};
    const aspect = this.selected.aspect;
    let w = width, h = width / aspect;
    if (h > height) { h = height; w = height * aspect; }
    return {x: (width - w) / 2, y: (height - h) / 2, width: w, height: h};
  }

  resize() {
    const width = this.holder.clientWidth, height = this.holder.clientHeight;
    if (width === 0 || height === 0) return;
    this.renderer.setSize(width, height, false);
    const rect = this.viewport();
    this.view.aspect = this.selected ? this.selected.aspect : rect.width / rect.height;
    this.view.updateProjectionMatrix();
    this.requestRender();
  }

  requestRender() {
    if (this.renderPending || this.disposed) return;
    this.renderPending = true;
    requestAnimationFrame(() => {
      this.renderPending = false;
      this.render();
    });
  }

  render() {
    if (this.disposed) return;
    const r = this.renderer;
    const width = this.holder.clientWidth, height = this.holder.clientHeight;
    const rect = this.viewport();
    // WebGL's viewport starts at the bottom left.
    const y = height - rect.y - rect.height;
    r.setScissorTest(false);
    r.setViewport(0, 0, width, height);
    r.setClearColor(this.selected ? BARS : BACKGROUND, 1);
    r.clear();
    r.setViewport(rect.x, y, rect.width, rect.height);
    r.setScissor(rect.x, y, rect.width, rect.height);
    r.setScissorTest(true);
    r.render(this.scene, this.view);
    r.setScissorTest(false);
  }

  // A press and release in (nearly) the same place is a click: the nearest frustum under it, if
  // any, becomes the view.
  listenForClicks() {
    const canvas = this.renderer.domElement;
    let down = null;
    canvas.addEventListener('pointerdown', (e) => { down = {x: e.clientX, y: e.clientY}; });
    canvas.addEventListener('pointerup', (e) => {
      if (!down || Math.hypot(e.clientX - down.x, e.clientY - down.y) > CLICK_SLOP) return;
      down = null;
      const name = this.frustumAt(e.clientX, e.clientY);
      if (name) this.lookThrough(name);
    });
  }

  frustumAt(clientX, clientY) {
    const bounds = this.renderer.domElement.getBoundingClientRect();
    const rect = this.viewport();
    const x = ((clientX - bounds.left - rect.x) / rect.width) * 2 - 1;
    const y = -((clientY - bounds.top - rect.y) / rect.height) * 2 + 1;
    if (Math.abs(x) > 1 || Math.abs(y) > 1) return null;
    const raycaster = new THREE.Raycaster();
    raycaster.setFromCamera(new THREE.Vector2(x, y), this.view);
    const picks = this.cameras.filter((c) => c.userData.frustum.visible)
        .map((c) => c.userData.frustum.userData.pick);
    const hit = raycaster.intersectObjects(picks, false)[0];
    return hit ? photoName(hit.object.parent.userData.camera) : null;
  }

  // What the view holds, for the page's browser test (tests/web): the frusta in the scene, the
  // photos' camera centres and fields of view, and the view's own camera.
  state() {
    const frusta = [];
    this.scene.traverse((object) => { if (object.userData.pick) frusta.push(object); });
    const position = (object) => object.getWorldPosition(new THREE.Vector3()).toArray();
    return {
      frusta: frusta.length,
      cameras: this.cameras.map((c) => ({name: photoName(c), position: position(c), fov: c.fov,
                                         aspect: c.aspect})),
      selected: this.selected ? photoName(this.selected) : null,
      view: {position: this.view.position.toArray(), fov: this.view.fov, aspect: this.view.aspect},
    };
  }

  // Where on the screen (client pixels) a point inside the named camera's frustum appears.
  screenPoint(name) {
    const camera = this.cameras.find((c) => photoName(c) === name);
    const frustum = camera.userData.frustum;
    const p = frustum.localToWorld(frustum.userData.inside.clone()).project(this.view);
    const bounds = this.renderer.domElement.getBoundingClientRect();
    const rect = this.viewport();
    return {x: bounds.left + rect.x + (p.x + 1) / 2 * rect.width,
            y: bounds.top + rect.y + (1 - p.y) / 2 * rect.height, depth: p.z};
  }

  // Draws now and counts the drawn pixels that are neither the background nor the bars, and
  // the distinct colours among them (in steps of 16 levels).
  pixels() {
    this.render();
    const gl = this.renderer.getContext();
    const width = gl.drawingBufferWidth, height = gl.drawingBufferHeight;
    const data = new Uint8Array(width * height * 4);
    gl.readPixels(0, 0, width, height, gl.RGBA, gl.UNSIGNED_BYTE, data);
    // The background and the bars as drawn: the sRGB bytes of their hex values.
    const rgb = (hex) => [16, 8, 0].map((shift) => (hex >> shift) & 255);
    const near = (i, [r, g, b]) =>
        Math.abs(data[i] - r) + Math.abs(data[i + 1] - g) + Math.abs(data[i + 2] - b) <= 6;
    const background = rgb(BACKGROUND), bars = rgb(BARS);
    let other = 0;
    const colours = new Set();
    for (let i = 0; i < data.length; i += 4) {
      if (near(i, background) || near(i, bars)) continue;
      ++other;
      colours.add((data[i] >> 4) << 8 | (data[i + 1] >> 4) << 4 | (data[i + 2] >> 4));
    }
    return {width, height, nonBackground: other, colours: colours.size};
  }

  dispose() {
    this.disposed = true;
    if (this.manager) this.manager.abort();
    this.resizeObserver.disconnect();
    this.controls.dispose();
    dispose(this.scene);
    this.renderer.dispose();
    this.renderer.forceContextLoss();
    this.renderer.domElement.remove();
  }
}

// Shows `url` (a job's model.glb of `bytes` bytes) in `holder`, replacing the previous view.
// Resolves with {faces, cameras} once shown; rejects when it cannot be loaded. `callbacks`:
// onProgress(loaded, total), onSelect(name | null, camera | null).
export async function open(holder, url, bytes, callbacks) {
  close();
  const view = new ModelView(holder, callbacks);
  current = view;
  return view.load(url, bytes, callbacks.onProgress);
}

// Removes the view (another job was opened, or this one has no model any more).
export function close() {
  if (current) current.dispose();
  current = null;
}

export const lookThrough = (name) => current !== null && current.lookThrough(name);
export const overview = () => { if (current && current.model) current.overview(); };

// The test's window into the view (null before one is open).
export function inspect() {
  if (!current || !current.model) return null;
  return {state: () => current.state(), screenPoint: (name) => current.screenPoint(name),
          pixels: () => current.pixels()};
}
