// The web page (web/) in a real browser: Debian's chromium driven by playwright-core, against
// a real reconduit-server and reconduit-worker on a temporary data folder. A person's path:
// open the page, see that the service is up, pick photos (../shared/datasets/kermit; that part
// is skipped without them), upload them, watch the job run to
// the end, look at the cameras, pictures, files and log, then delete the job; and the errors
// a person can make: a zip together with photos, a file that is not a photo.
//
// The finished job's 3D view: model.glb loads with progress, the WebGL canvas shows it, one
// frustum per registered photo, and looking through a photo's camera (a click on its frustum
// or its name) puts the view at that camera, checked against the file's own camera nodes.
//
// A server started with --token (its own, with a worker that runs only the ingest stage): the
// page asks for the token, asks again after a wrong one, uploads, follows the job and downloads
// result.zip and a file with it, and never puts it in a URL; "Forget the token" clears it.
//
// Run by ctest (tests/CMakeLists.txt), which passes the binaries' paths:
//   RECONDUIT_SERVER_BINARY, RECONDUIT_WORKER_BINARY, RECONDUIT_WEB_DIR, RECONDUIT_SOURCE_DIR,
//   and RECONDUIT_TEST_OUTPUT_DIR for the screenshots (default: the system's temporary folder);
//   RECONDUIT_CHROMIUM overrides /usr/bin/chromium. `npm ci` in this folder installs
//   playwright-core, and scripts/web_deps.sh the page's three.js (scripts/test.sh does both).
import {after, before, test} from 'node:test';
import assert from 'node:assert/strict';
import {spawn} from 'node:child_process';
import crypto from 'node:crypto';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import readline from 'node:readline';

import {chromium} from 'playwright-core';

import {checkExtractedReport} from './report.mjs';

const env = (name) => {
  const value = process.env[name];
  if (!value) throw new Error(`${name} is not set (run this test through ctest)`);
  return value;
};

const dataDir = fs.mkdtempSync(path.join(os.tmpdir(), 'reconduit-web-test-'));
const dataDirs = [dataDir];
const outDir = process.env.RECONDUIT_TEST_OUTPUT_DIR || os.tmpdir();
fs.mkdirSync(outDir, {recursive: true});
const children = [];
let baseUrl;
let browser;

// Starts a program; resolves with the first line of its standard output matching `pattern`.
function start(binary, args, pattern) {
  const child = spawn(binary, args, {stdio: ['ignore', 'pipe', 'inherit']});
  children.push(child);
  if (!pattern) {
    child.stdout.resume();
    return Promise.resolve(null);
  }
  return new Promise((resolve, reject) => {
    const lines = readline.createInterface({input: child.stdout});
    lines.on('line', (line) => {
      const match = line.match(pattern);
      if (match) resolve(match);
    });
    child.on('exit', (code) => reject(new Error(`${binary} exited with ${code} before starting`)));
  });
}

before(async () => {
  const listening = await start(
      env('RECONDUIT_SERVER_BINARY'),
      ['--port', '0', '--data', dataDir, '--web', env('RECONDUIT_WEB_DIR')],
      /listening on (http:\/\/\S+)/);
  baseUrl = listening[1];
  await start(env('RECONDUIT_WORKER_BINARY'), ['--data', dataDir, '--poll', '0.2'], null);
  browser = await chromium.launch({
    executablePath: process.env.RECONDUIT_CHROMIUM || '/usr/bin/chromium',
    // WebGL for the 3D view without a GPU: SwiftShader (as tests/gltf).
    args: ['--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
           '--ignore-gpu-blocklist'],
  });
});

after(async () => {
  if (browser) await browser.close();
  for (const child of children) child.kill('SIGTERM');
  await Promise.all(children.map((c) => new Promise((resolve) => {
    if (c.exitCode !== null || c.signalCode !== null) resolve();
    else c.on('exit', resolve);
  })));
  for (const dir of dataDirs) fs.rmSync(dir, {recursive: true, force: true});
});

// A page that fails the test on any script error.
async function openPage() {
  const page = await browser.newPage({viewport: {width: 1200, height: 1600}});
  const errors = [];
  page.on('pageerror', (error) => errors.push(error.message));
  page.on('dialog', (dialog) => dialog.accept());
  await page.goto(baseUrl + '/');
  await page.waitForSelector('#health.ok');
  return {page, errors};
}

test('refuses a zip together with photos, and a file that is not a photo', async () => {
  const {page, errors} = await openPage();
  const zip = path.join(dataDir, 'photos.zip');
  const text = path.join(dataDir, 'notes.jpg');
  fs.writeFileSync(zip, 'PK\u0005\u0006' + '\0'.repeat(18));
  fs.writeFileSync(text, 'these are notes, not a photo');

  await page.setInputFiles('#files', [zip, text]);
  await page.click('#submit');
  assert.match(await page.textContent('#upload-status'), /either photos or one zip/);

  await page.setInputFiles('#files', [text]);
  await page.click('#submit');
  await page.waitForSelector('#upload-status.error:has-text("Not accepted")');
  // The service's own reason reaches the person: the file is named.
  assert.match(await page.textContent('#upload-status'), /notes\.jpg/);
  assert.equal(await page.isEnabled('#submit'), true, 'the person can try again');
  assert.deepEqual(errors, []);
  await page.close();
});

test('uploads photos, follows the job to the end, shows the results, deletes the job',
     async (t) => {
  // kermit: 11 small photos that calibrate well (the focal comes with its precision).
  const images = path.join(env('RECONDUIT_SOURCE_DIR'), '..', 'shared', 'datasets', 'kermit',
                           'images');
  if (!fs.existsSync(images)) {
    t.skip(`${images} is absent: the upload test needs the kermit photos`);
    return;
  }
  const photos = fs.readdirSync(images).filter((f) => f.endsWith('.jpg')).sort()
                     .map((f) => path.join(images, f));
  assert.equal(photos.length, 11);
  const {page, errors} = await openPage();
  await recordModelStatus(page);
  await page.setInputFiles('#files', photos);
  assert.match(await page.textContent('#drop-text'), /^11 files/);
  // Depth maps at 320 px keep the test short (11 maps of 640 x 480 photos take minutes). The
  // lean result.zip (no dense.ply, depth/, quality/) is checked below with its report.html.
  await page.click('#upload-form details summary');
  await page.fill('#options', '{"dense_max_image_side": 320, "package_dense_files": false}');
  await page.click('#submit');

  // The new job opens by itself and runs to the end.
  await page.waitForSelector('#job:not([hidden])');
  await page.waitForSelector('#job-summary .badge.succeeded, #job-summary .badge.failed',
                             {timeout: 180000});
  const summary = await page.textContent('#job-summary');
  assert.match(summary, /^succeeded/, summary);
  assert.match(summary, /11 photos, 11 cameras recovered, \d+ points/);
  assert.match(await page.textContent('#job'), /Computing depth maps: 11 maps/);
  assert.match(page.url(), /#[0-9a-f]{32}$/);

  // Every stage finished (dense, mesh and texture included), the camera table shows a focal
  // length, the pictures load.
  const statuses = await page.$$eval('#stage-rows tr td:nth-child(2)', (cells) =>
      cells.map((cell) => cell.textContent));
  assert.deepEqual(statuses, Array(10).fill('success'));
  // The focal length with its precision (one standard deviation).
  assert.match(await page.textContent('#cameras'), /\d+\.\d\d ± \d+\.\d\d/);
  // The two matching pictures, a depth and a quality preview per photo, and report.html's
  // thumbnails (one per photo) and four renders beside their photos (lazy: scrolled to).
  await page.waitForFunction(
      () => document.querySelectorAll('#pictures img').length === 2 + 2 * 11 + 11 + 2 * 4);
  for (const name of ['report/similarity.png', 'report/dense/kermit010_depth.jpg',
                      'report/dense/kermit010_quality.png']) {
    const img = page.locator(`#pictures img[alt="${name}"]`);
    await img.scrollIntoViewIfNeeded();
    await page.waitForFunction((alt) => {
      const i = document.querySelector(`#pictures img[alt="${alt}"]`);
      return i.complete && i.naturalWidth > 0;
    }, name);
  }
  assert.match(await page.textContent('#pictures'), /kermit010: depth \(red near, blue far/);
  assert.match(await page.textContent('#pictures'),
               /kermit000: the model seen through this photo's camera/);
  assert.match(await page.textContent('#pictures'), /kermit000: the photo the model is compared/);
  const files = await page.$$eval('#files-list a', (links) => links.map((a) => a.textContent));
  for (const name of ['cameras.json', 'sparse.ply', 'report.json', 'dense.ply', 'model.glb']) {
    assert.ok(files.includes(name), name);
  }
  const download = await page.getAttribute('#job-actions a', 'href');
  const zip = await fetch(baseUrl + download);
  assert.equal(zip.status, 200);
  assert.equal(zip.headers.get('content-type'), 'application/zip');
  await checkReport(Buffer.from(await zip.arrayBuffer()));
  assert.match(await page.textContent('#log'), /queued with 11 photos/);
  await page.screenshot({path: path.join(outDir, 'reconduit-web-test.png'), fullPage: true});

  const id = page.url().split('#')[1];
  await checkModelView(page, id);

  // Delete: the job leaves the list and the service.
  await page.click('#job-actions button:has-text("Delete")');
  await page.waitForSelector('#job', {state: 'hidden'});
  assert.equal((await fetch(`${baseUrl}/api/v1/jobs/${id}`)).status, 404);
  await page.waitForFunction(() => document.querySelectorAll('#job-rows tr').length === 0);
  assert.deepEqual(errors, []);
  await page.close();
});

// The kermit job's result.zip, extracted, its report.html opened from file:// (report.mjs).
async function checkReport(zipBytes) {
  const {text, files, images} =
      await checkExtractedReport(browser, zipBytes, path.join(dataDir, 'extracted-result'));
  // Lean: the heavy dense files stay on the server (the files list above has dense.ply).
  for (const name of ['dense.ply', 'depth/kermit000.png', 'quality/kermit000.png'])
    assert.ok(!files.includes(name), `${name} left out of result.zip`);
  const manifest = JSON.parse(fs.readFileSync(
      path.join(dataDir, 'extracted-result', 'extracted', 'manifest.json'), 'utf8'));
  assert.deepEqual(manifest.files.map((f) => f.name).sort(),
                   files.filter((f) => f !== 'manifest.json').sort(), 'the manifest is the zip');
  // A thumbnail, a depth and a quality preview per photo, the two matching pictures, and
  // renders of the model beside their photos.
  const sources = images.map((img) => img.src);
  for (let k = 0; k <= 10; ++k) {
    const stem = `kermit${String(k).padStart(3, '0')}`;
    for (const file of [`report/photos/${stem}.jpg`, `report/dense/${stem}_depth.jpg`,
                        `report/dense/${stem}_quality.png`])
      assert.ok(sources.includes(`./${file}`), file);
  }
  for (const file of ['report/similarity.png', 'report/match_graph.png',
                      'report/texture/kermit000_render.jpg', 'report/texture/kermit000_photo.jpg'])
    assert.ok(sources.includes(`./${file}`), file);
  assert.match(text, /registered photos\s*11/);
  assert.match(text, /kermit000\.jpg: covered \d+\.\d %, difference \d+\.\d/);
  assert.match(text, /Left out of this archive \(option package_dense_files\): dense\.ply, depth\/, quality\//);
}

// ---------------------------------------------------------------------------------------------
// The 3D view

// Keeps every text the 3D view's status line shows, in window.modelStatusTexts.
function recordModelStatus(page) {
  return page.evaluate(() => {
    const status = document.getElementById('model-status');
    const seen = window.modelStatusTexts = [];
    new MutationObserver(() => seen.push(status.textContent))
        .observe(status, {childList: true, characterData: true, subtree: true});
  });
}

// The camera nodes of a GLB file: [{name, translation}] (the JSON chunk, read here in node).
function glbCameraNodes(buffer) {
  assert.equal(buffer.toString('ascii', 0, 4), 'glTF');
  const length = buffer.readUInt32LE(12);
  assert.equal(buffer.toString('ascii', 16, 20), 'JSON');
  const json = JSON.parse(buffer.toString('utf8', 20, 20 + length));
  return json.nodes.filter((n) => n.camera !== undefined)
      .map((n) => ({name: n.name, translation: n.translation,
                    yfov: json.cameras[n.camera].perspective.yfov,
                    aspect: json.cameras[n.camera].perspective.aspectRatio}));
}

// What viewer.js reports of the open view (the same module instance the page imported).
const viewState = (page) => page.evaluate(async () => {
  const view = (await import('./viewer.js')).inspect();
  return view && view.state();
});

function assertNear(actual, expected, tolerance, what) {
  assert.equal(actual.length, expected.length, what);
  for (let i = 0; i < expected.length; ++i) {
    assert.ok(Math.abs(actual[i] - expected[i]) <= tolerance,
              `${what}: ${JSON.stringify(actual)} is not ${JSON.stringify(expected)}`);
  }
}

// The view looks through the photo `node` (from the file): at its centre, with its fov/aspect.
async function assertLooksThrough(page, node) {
  await page.waitForFunction(async (name) =>
      (await import('./viewer.js')).inspect().state().selected === name, node.name);
  const state = await viewState(page);
  assertNear(state.view.position, node.translation, 1e-9, `the view at ${node.name}`);
  assert.ok(Math.abs(state.view.fov - node.yfov * 180 / Math.PI) < 1e-9, 'the photo\'s yfov');
  assert.ok(Math.abs(state.view.aspect - node.aspect) < 1e-12, 'the photo\'s aspect');
  assert.match(await page.textContent('#model-photo'),
               new RegExp(`^Seen from ${node.name.replaceAll('.', '\\.')}, 640 × 480 px`));
  assert.equal(await page.getAttribute(`#model-cameras button[data-photo="${node.name}"]`,
                                       'aria-pressed'), 'true');
}

async function checkModelView(page, id) {
  const started = Date.now();
  // While the job ran the view said why it was empty; then the download showed its progress.
  const model = await fetch(`${baseUrl}/api/v1/jobs/${id}/files/model.glb`);
  assert.equal(model.status, 200);
  const nodes = glbCameraNodes(Buffer.from(await model.arrayBuffer()));
  const job = await (await fetch(`${baseUrl}/api/v1/jobs/${id}`)).json();
  assert.equal(nodes.length, job.counts.registered, 'one camera node per registered photo');
  await page.waitForFunction(() => /triangles/.test(document.getElementById('model-status').textContent),
                             null, {timeout: 30000});
  const texts = await page.evaluate(() => window.modelStatusTexts);
  assert.ok(texts.some((t) => /^The 3D model appears here once the job has succeeded; it is (waiting|running)/.test(t)),
            JSON.stringify(texts.slice(0, 5)));
  assert.ok(texts.some((t) => /^Loading the model: [\d.]+ (B|KiB|MiB) of \d+\.\d MiB$/.test(t)),
            JSON.stringify(texts.filter((t) => /Loading/.test(t))));
  assert.match(await page.textContent('#model-status'), /^[\d,]+ triangles; 11 photo cameras\./);

  // A frustum per registered photo, at the file's camera centres; the canvas shows the model.
  let state = await viewState(page);
  assert.equal(state.frusta, job.counts.registered);
  assert.deepEqual(state.cameras.map((c) => c.name), nodes.map((n) => n.name).sort());
  for (const node of nodes) {
    assertNear(state.cameras.find((c) => c.name === node.name).position, node.translation, 1e-9,
               node.name);
  }
  assert.equal(state.selected, null);
  const pixels = await page.evaluate(async () => (await import('./viewer.js')).inspect().pixels());
  const share = pixels.nonBackground / (pixels.width * pixels.height);
  assert.ok(share > 0.03, `only ${(share * 100).toFixed(2)} % of the canvas is not background`);
  assert.ok(pixels.colours > 100, `only ${pixels.colours} colours: not the textured model`);
  await page.locator('#model').scrollIntoViewIfNeeded();
  await page.locator('#model').screenshot({path: path.join(outDir, 'reconduit-web-test-3d.png')});

  // A click on a frustum (the one farthest on screen from the others, so that none hides it)
  // looks through that photo's camera.
  const points = await page.evaluate(async (names) => {
    const view = (await import('./viewer.js')).inspect();
    return names.map((name) => ({name, ...view.screenPoint(name)}));
  }, state.cameras.map((c) => c.name));
  const spacing = (p) => Math.min(...points.filter((q) => q !== p)
                                            .map((q) => Math.hypot(p.x - q.x, p.y - q.y)));
  const lone = points.reduce((best, p) => (spacing(p) > spacing(best) ? p : best));
  await page.mouse.click(lone.x, lone.y);
  await assertLooksThrough(page, nodes.find((n) => n.name === lone.name));
  await page.locator('#model').screenshot({path: path.join(outDir, 'reconduit-web-test-3d-camera.png')});

  // Choosing a photo in the list does the same.
  const other = nodes.find((n) => n.name !== lone.name);
  await page.click(`#model-cameras button[data-photo="${other.name}"]`);
  await assertLooksThrough(page, other);

  // Dragging leaves the photo's view (and its frustum shows again); "Whole scene" goes back.
  const canvas = await page.locator('#model-canvas canvas').boundingBox();
  await page.mouse.move(canvas.x + canvas.width / 2, canvas.y + canvas.height / 2);
  await page.mouse.down();
  await page.mouse.move(canvas.x + canvas.width / 2 + 60, canvas.y + canvas.height / 2, {steps: 4});
  await page.mouse.up();
  state = await viewState(page);
  assert.equal(state.selected, null);
  assert.equal(await page.textContent('#model-photo'), '');
  await page.click('#model-overview');
  state = await viewState(page);
  assert.equal(state.frusta, job.counts.registered);
  for (const node of nodes) {
    assert.ok(Math.hypot(...state.view.position.map((v, i) => v - node.translation[i])) > 0.1,
              'the whole scene is seen from outside the cameras');
  }
  console.log(`the 3D view's checks took ${((Date.now() - started) / 1000).toFixed(1)} s; the ` +
              `whole scene covered ${(share * 100).toFixed(1)} % of the canvas in ` +
              `${pixels.colours} colours`);
}

test('serves the page\'s three.js from web/vendor/ only, as JavaScript, the version tests/gltf pins',
     async () => {
  const module = await fetch(`${baseUrl}/vendor/three/build/three.module.js`);
  assert.equal(module.status, 200);
  assert.equal(module.headers.get('content-type'), 'text/javascript; charset=utf-8');
  for (const addon of ['loaders/GLTFLoader.js', 'controls/OrbitControls.js']) {
    assert.equal((await fetch(`${baseUrl}/vendor/three/examples/jsm/${addon}`)).status, 200, addon);
  }
  // The npm folder itself is not served, nor what the page does not load.
  assert.equal((await fetch(`${baseUrl}/.deps/node_modules/three/build/three.module.js`)).status, 400);
  assert.equal((await fetch(`${baseUrl}/vendor/three/src/Three.js`)).status, 404);
  const version = (lock) => JSON.parse(fs.readFileSync(path.join(env('RECONDUIT_SOURCE_DIR'), lock)))
      .packages['node_modules/three'].version;
  assert.equal(version('web/.deps/package-lock.json'), version('tests/gltf/package-lock.json'));
});

// ---------------------------------------------------------------------------------------------
// A service started with --token: the page asks for the token and sends it with every request.
// A server and worker of its own; the worker runs only the ingest stage (--until ingest), so
// the job succeeds in a second or two, with a result.zip.

const kermitImages = () => path.join(env('RECONDUIT_SOURCE_DIR'), '..', 'shared', 'datasets',
                                     'kermit', 'images');

test('with a token: asks for it, asks again after a wrong one, uploads, follows the job and ' +
     'downloads with it, never puts it in a URL, forgets it', async (t) => {
  const started = Date.now();
  const token = `t0ken-${crypto.randomBytes(12).toString('hex')}`;
  const tokenDir = fs.mkdtempSync(path.join(os.tmpdir(), 'reconduit-web-token-test-'));
  dataDirs.push(tokenDir);
  const listening = await start(
      env('RECONDUIT_SERVER_BINARY'),
      ['--port', '0', '--data', tokenDir, '--web', env('RECONDUIT_WEB_DIR'), '--token', token],
      /listening on (http:\/\/\S+)/);
  const url = listening[1];
  await start(env('RECONDUIT_WORKER_BINARY'),
              ['--data', tokenDir, '--poll', '0.2', '--until', 'ingest'], null);
  const auth = {headers: {Authorization: `Bearer ${token}`}};

  // The page's files and /healthz need no token; the API, and any other path, does.
  for (const file of ['/', '/index.html', '/app.js', '/viewer.js', '/style.css',
                      '/vendor/three/build/three.module.js']) {
    assert.equal((await fetch(url + file)).status, 200, file);
  }
  assert.equal((await fetch(`${url}/healthz`)).status, 200);
  for (const refused of ['/api/v1/jobs', '/metrics', '/missing.js', '/vendor/three/src/Three.js']) {
    const response = await fetch(url + refused);
    assert.equal(response.status, 401, refused);
    assert.equal((await response.json()).error.code, 'unauthorized', refused);
  }

  const page = await browser.newPage({viewport: {width: 1200, height: 1600}});
  const errors = [];
  page.on('pageerror', (error) => errors.push(error.message));
  page.on('console', (message) => {
    if (/Content Security Policy/i.test(message.text())) errors.push(message.text());
  });
  const requested = [];
  page.on('request', (request) => requested.push(request.url()));
  await page.goto(url + '/');
  await page.waitForSelector('#health.ok');

  // Asked for at the first 401; a wrong token is refused and asked for again, not kept.
  await page.waitForSelector('#token-dialog[open]');
  assert.match(await page.textContent('#token-message'), /needs an access token/);
  assert.equal(await page.isVisible('#token-state'), false);
  await page.fill('#token-input', 'not-the-token');
  await page.click('#token-submit');
  await page.waitForSelector(
      '#token-dialog[open] #token-message:has-text("refused this token (invalid bearer token)")');
  assert.equal(await page.evaluate(() => sessionStorage.getItem('reconduit.token')), null);
  await page.fill('#token-input', token);
  await page.click('#token-submit');
  await page.waitForSelector('#token-dialog', {state: 'hidden'});
  await page.waitForSelector('#jobs-empty:has-text("No jobs yet")');
  assert.equal(await page.isVisible('#token-state'), true);
  // Kept for this tab only: sessionStorage, no localStorage, no cookie.
  assert.equal(await page.evaluate(() => sessionStorage.getItem('reconduit.token')), token);
  assert.equal(await page.evaluate(() => localStorage.length), 0);
  assert.deepEqual(await page.context().cookies(), []);

  const images = kermitImages();
  if (fs.existsSync(images)) {
    // Upload (XMLHttpRequest), then the job's status and log as they change (fetch).
    const photos = fs.readdirSync(images).filter((f) => f.endsWith('.jpg')).sort().slice(0, 3)
                       .map((f) => path.join(images, f));
    await page.evaluate(() => {
      const seen = window.badgesSeen = [];
      new MutationObserver(() => {
        const badge = document.querySelector('#job-summary .badge');
        if (badge && seen[seen.length - 1] !== badge.textContent) seen.push(badge.textContent);
      }).observe(document.getElementById('job-summary'), {childList: true, subtree: true});
    });
    await page.setInputFiles('#files', photos);
    await page.click('#submit');
    await page.waitForSelector('#upload-status:has-text("Job created with 3 photos")');
    await page.waitForSelector('#job-summary .badge.succeeded, #job-summary .badge.failed',
                               {timeout: 30000});
    assert.match(await page.textContent('#job-summary'), /^succeeded/);
    assert.equal(await page.textContent('#stage-rows tr[data-stage="ingest"] td:nth-child(2)'),
                 'success');
    await page.waitForFunction(() => /queued with 3 photos/.test(document.getElementById('log').textContent));
    const id = page.url().split('#')[1];
    const job = await (await fetch(`${url}/api/v1/jobs/${id}`, auth)).json();
    t.diagnostic(`the page showed the job as: ${(await page.evaluate(() => window.badgesSeen)).join(', ')}; ` +
                 `it ran ${job.elapsed_seconds} s, from ${job.created_at} to ${job.finished_at}`);

    // result.zip: fetched with the token, saved by the browser; the same bytes as the service's.
    const [download] = await Promise.all([page.waitForEvent('download'),
                                          page.click('#job-actions a button')]);
    assert.equal(download.suggestedFilename(), `reconduit-${id.slice(0, 8)}.zip`);
    const zip = fs.readFileSync(await download.path());
    assert.equal(zip.length, job.result.bytes);
    assert.equal(zip.toString('latin1', 0, 2), 'PK');
    const direct = Buffer.from(await (await fetch(`${url}${job.links.result}`, auth)).arrayBuffer());
    assert.ok(zip.equals(direct), 'the downloaded result.zip is the service\'s');
    // A file of the list likewise.
    const [report] = await Promise.all([page.waitForEvent('download'),
                                        page.click('#files-list a:text-is("report.json")')]);
    assert.equal(report.suggestedFilename(), 'report.json');
    assert.equal(typeof JSON.parse(fs.readFileSync(await report.path(), 'utf8')), 'object');
    assert.equal(await page.textContent('#download-status'), '');
  } else {
    t.diagnostic(`${images} is absent: the upload and downloads with a token are not tried`);
  }

  // The token went in headers only.
  assert.ok(requested.length > 5);
  assert.deepEqual(requested.filter((u) => u.includes(token)), []);

  // Forgotten: gone from the tab, and the page asks again.
  await page.click('#token-forget');
  await page.waitForSelector('#token-dialog[open]');
  assert.match(await page.textContent('#token-message'), /needs an access token/);
  assert.equal(await page.evaluate(() => sessionStorage.getItem('reconduit.token')), null);
  assert.deepEqual(errors, []);
  await page.close();
  console.log(`the token test took ${((Date.now() - started) / 1000).toFixed(1)} s`);
});

// ---------------------------------------------------------------------------------------------
// What the page makes of a job's stage figures, from jobs the service could not produce on
// demand: the browser's requests for one made-up job are answered here (the rest of the page
// talks to the real server).

const GiB = 1024 * 1024 * 1024;
const MiB = 1024 * 1024;

// A stage entry as the worker writes it (stage_progress.<stage>).
function stageEntry(title, seconds, ownPeak, processPeak, summary = {}, extra = {}) {
  return {title, status: 'success', progress: 1, seconds, peak_memory_bytes: processPeak,
          stage_peak_memory_bytes: ownPeak, stage_peak_memory_own: true, summary, ...extra};
}

function fakeJob(id, state, stages) {
  return {
    id, state, stage: state === 'running' ? 'export' : null, progress: 0.9, stages,
    finished_stages: [], created_at: '2026-12-02T08:00:00.000Z', elapsed_seconds: 120,
    eta_seconds: null, attempts: 1, max_attempts: 3, cancel_requested: false,
    counts: {images: 20, registered: 20, points: 5000}, error: null, options: {},
    result: state === 'succeeded' ? {bytes: 1000, sha256: 'x'} : null,
    links: {result: `/api/v1/jobs/${id}/result.zip`},
  };
}

// The sparse stages, each with its time and memory; features's own peak is unknown (the worker
// could not reset the kernel's mark).
function sparseStages() {
  return {
    ingest: stageEntry('Reading photos', 0.5, 60 * MiB, 60 * MiB, {accepted: 20}),
    features: stageEntry('Finding features', 12, 900 * MiB, 900 * MiB, {features: 80000},
                         {stage_peak_memory_own: false}),
    pairs: stageEntry('Choosing pairs', 2, 120 * MiB, 900 * MiB),
    matching: stageEntry('Matching', 30, 400 * MiB, 900 * MiB),
    sparse: stageEntry('Cameras and points', 25, 300 * MiB, 900 * MiB, {registered: 20}),
  };
}

// Opens the page on job `id`, whose requests `answer(pathname)` serves; counts the job's fetches.
async function openFakeJob(id, answer) {
  const page = await browser.newPage({viewport: {width: 1200, height: 1600}});
  const errors = [];
  page.on('pageerror', (error) => errors.push(error.message));
  const fetches = {job: 0};
  await page.route((url) => url.pathname.startsWith(`/api/v1/jobs/${id}`), (route) => {
    const pathname = new URL(route.request().url()).pathname;
    if (pathname.endsWith('/events')) {
      return route.fulfill({status: 200, contentType: 'application/x-ndjson', body: ''});
    }
    if (pathname.endsWith('/files')) return route.fulfill({json: {files: []}});
    fetches.job += 1;
    return route.fulfill({json: answer(pathname)});
  });
  await page.goto(`${baseUrl}/#${id}`);
  await page.waitForSelector('#health.ok');
  await page.waitForSelector('#stage-rows tr');
  return {page, errors, fetches};
}

const cellTexts = (page, selector) =>
    page.$$eval(selector, (cells) => cells.map((cell) => cell.textContent));

test('shows each stage\'s time, own peak memory and the process\'s, and the per-map figures',
     async () => {
  const id = 'd'.repeat(32);
  const maps = Array.from({length: 20}, (_, i) => ({
    image: `IMG_${String(i).padStart(2, '0')}.jpg`, seconds: 2 + i / 10,
    depth_fraction: 0.5 + i / 100, fused_fraction: 0.25, sources: [1, 2],
  }));
  const stages = {
    ...sparseStages(),
    dense: stageEntry('Dense matching', 61, 1.5 * GiB, 3 * GiB, {points: 1600000, maps}),
    export: {title: 'Writing results', status: 'running', progress: 0.5, seconds: 3,
             memory_bytes: 200 * MiB},
  };
  // Running: the page refreshes every 1.5 s.
  const {page, errors, fetches} = await openFakeJob(id, () => fakeJob(id, 'running', stages));

  // A row per stage of the pipeline, dense among them, with its time and both peaks.
  assert.deepEqual(await cellTexts(page, '#stage-rows tr td:nth-child(1)'),
                   ['Reading photos', 'Finding features', 'Choosing pairs', 'Matching',
                    'Cameras and points', 'Dense matching', 'mesh', 'texture', 'Writing results',
                    'package']);
  const dense = '#stage-rows tr[data-stage="dense"]';
  assert.deepEqual(await cellTexts(page, `${dense} td`),
                   ['Dense matching', 'success', '', '1 min 1 s', '1.50 GiB', '3.00 GiB',
                    'points 1600000']);
  assert.equal(await page.textContent('#stage-rows tr[data-stage="pairs"] td:nth-child(5)'),
               '120.0 MiB');
  assert.equal(await page.textContent('#stage-rows tr[data-stage="pairs"] td:nth-child(6)'),
               '900.0 MiB');
  // features's own peak is unknown: a dash, not the process's figure passed off as its own.
  assert.equal(await page.textContent('#stage-rows tr[data-stage="features"] td:nth-child(5)'),
               '—');
  // The running stage: the memory in use now.
  assert.equal(await page.textContent('#stage-rows tr[data-stage="export"] td:nth-child(5)'),
               '200.0 MiB now');
  // No model yet, and the 3D view says so.
  assert.equal(await page.textContent('#model-status'),
               'The 3D model appears here once the job has succeeded; it is running (Writing results).');
  assert.equal(await page.isVisible('#model-canvas'), false);

  // The per-map table: 20 maps start collapsed, open on a click, and stay open.
  const details = '#maps details[data-stage="dense"]';
  assert.match(await page.textContent(`${details} summary`), /^Dense matching: 20 maps, 59 s in all$/);
  assert.equal(await page.$eval(details, (d) => d.open), false);
  assert.equal(await page.isVisible(`${details} table`), false);
  await page.click(`${details} summary`);
  assert.equal(await page.isVisible(`${details} table`), true);
  assert.equal(await page.$$eval(`${details} tbody tr`, (rows) => rows.length), 20);
  assert.deepEqual(await cellTexts(page, `${details} tbody tr:first-child td`),
                   ['IMG_00.jpg', '2.0 s', '50 %', '25 %']);
  assert.deepEqual(await cellTexts(page, `${details} tbody tr:last-child td`),
                   ['IMG_19.jpg', '3.9 s', '69 %', '25 %']);
  await waitForFetches(fetches, fetches.job + 2);
  assert.equal(await page.$eval(details, (d) => d.open), true, 'a refresh keeps it open');
  await page.screenshot({path: path.join(outDir, 'reconduit-web-test-stages.png'),
                         fullPage: true});
  assert.deepEqual(errors, []);
  await page.close();
});

// Resolves once the page fetched the job `count` times (it refreshes by itself).
async function waitForFetches(fetches, count) {
  const deadline = Date.now() + 10000;
  while (fetches.job < count) {
    if (Date.now() > deadline) throw new Error(`the page fetched the job ${fetches.job} times`);
    await new Promise((resolve) => setTimeout(resolve, 100));
  }
  // The rendering of the last answer.
  await new Promise((resolve) => setTimeout(resolve, 200));
}

test('a short per-map list starts open; a succeeded job without a dense stage lists none',
     async () => {
  const id = 'e'.repeat(32);
  const maps = [{image: 'a.jpg', seconds: 4.2, depth_fraction: 0.71, fused_fraction: 0.55}];
  const withDense = {...sparseStages(), dense: stageEntry('Dense matching', 4.2, GiB, 2 * GiB,
                                                          {maps})};
  let {page, errors} = await openFakeJob(id, () => fakeJob(id, 'succeeded', withDense));
  assert.equal(await page.$eval('#maps details[data-stage="dense"]', (d) => d.open), true);
  assert.deepEqual(await cellTexts(page, '#maps tbody tr td'), ['a.jpg', '4.2 s', '71 %', '55 %']);
  assert.deepEqual(errors, []);
  await page.close();

  // A job from before the dense stage: its stages only, no per-map table.
  ({page, errors} = await openFakeJob(id, () => fakeJob(id, 'succeeded', sparseStages())));
  assert.deepEqual(await cellTexts(page, '#stage-rows tr td:nth-child(1)'),
                   ['Reading photos', 'Finding features', 'Choosing pairs', 'Matching',
                    'Cameras and points']);
  assert.equal(await page.$$eval('#maps *', (nodes) => nodes.length), 0);
  assert.deepEqual(errors, []);
  await page.close();
});

test('a skipped stage shows as skipped with its reason, in its row and the job\'s summary',
     async () => {
  // Either way a stage can say it: a summary's skipped_reason, or the status "skipped".
  const variants = [
    stageEntry('Dense matching', 0.1, 50 * MiB, 900 * MiB,
               {skipped_reason: 'too few registered photos (2; at least 3)'}),
    {...stageEntry('Dense matching', 0.1, 50 * MiB, 900 * MiB), status: 'skipped',
     summary: undefined, message: 'too few registered photos (2; at least 3)'},
  ];
  for (const [i, dense] of variants.entries()) {
    const id = `${i}`.repeat(32);
    const stages = {...sparseStages(), dense, export: stageEntry('Writing results', 1, 0, 0),
                    package: stageEntry('Packing the results', 1, 0, 0)};
    const {page, errors} = await openFakeJob(id, () => fakeJob(id, 'succeeded', stages));
    const row = '#stage-rows tr[data-stage="dense"]';
    assert.deepEqual(await cellTexts(page, `${row} td:nth-child(2)`), ['skipped'], `variant ${i}`);
    assert.equal(await page.textContent(`${row} td:nth-child(7)`),
                 'too few registered photos (2; at least 3)');
    assert.equal(await page.getAttribute(row, 'class'), 'skipped');
    assert.match(await page.textContent('#job-summary'),
                 /^succeeded.*Dense matching skipped: too few registered photos \(2; at least 3\)$/);
    // The other stages succeeded as usual.
    assert.equal((await cellTexts(page, '#stage-rows tr td:nth-child(2)'))
                     .filter((status) => status === 'success').length, 7);
    // The job has no model.glb, and the 3D view says why.
    await page.waitForSelector('#model-status:has-text("no 3D model")');
    assert.equal(await page.textContent('#model-status'),
                 'This job has no 3D model (no model.glb). Dense matching skipped: too few ' +
                 'registered photos (2; at least 3).');
    assert.equal(await page.isVisible('#model-canvas'), false);
    assert.deepEqual(errors, []);
    await page.close();
  }
});
