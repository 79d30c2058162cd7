// The web page (web/) in a real browser: Debian's chromium driven by playwright-core, against
// a real reconduit-server and reconduit-worker on a temporary data folder. A person's path:
// open the page, see that the service is up, pick photos (../shared/datasets/kermit; that part
// is skipped without them), upload them, watch the job run to
// the end, look at the cameras, pictures, files and log, then delete the job; and the errors
// a person can make: a zip together with photos, a file that is not a photo.
//
// Run by ctest (tests/CMakeLists.txt), which passes the binaries' paths:
//   RECONDUIT_SERVER_BINARY, RECONDUIT_WORKER_BINARY, RECONDUIT_WEB_DIR, RECONDUIT_SOURCE_DIR;
//   RECONDUIT_CHROMIUM overrides /usr/bin/chromium. `npm ci` in this folder installs
//   playwright-core (scripts/test.sh does it).
import {after, before, test} from 'node:test';
import assert from 'node:assert/strict';
import {spawn} from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import readline from 'node:readline';

import {chromium} from 'playwright-core';

const env = (name) => {
  const value = process.env[name];
  if (!value) throw new Error(`${name} is not set (run this test through ctest)`);
  return value;
};

const dataDir = fs.mkdtempSync(path.join(os.tmpdir(), 'reconduit-web-test-'));
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
    args: ['--no-sandbox'],
  });
});

after(async () => {
  if (browser) await browser.close();
  for (const child of children) child.kill('SIGTERM');
  await Promise.all(children.map((c) => new Promise((resolve) => {
    if (c.exitCode !== null || c.signalCode !== null) resolve();
    else c.on('exit', resolve);
  })));
  fs.rmSync(dataDir, {recursive: true, force: true});
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
  await page.setInputFiles('#files', photos);
  assert.match(await page.textContent('#drop-text'), /^11 files/);
  await page.click('#submit');

  // The new job opens by itself and runs to the end.
  await page.waitForSelector('#job:not([hidden])');
  await page.waitForSelector('#job-summary .badge.succeeded, #job-summary .badge.failed',
                             {timeout: 180000});
  const summary = await page.textContent('#job-summary');
  assert.match(summary, /^succeeded/, summary);
  assert.match(summary, /11 photos, 11 cameras recovered, \d+ points/);
  assert.match(page.url(), /#[0-9a-f]{32}$/);

  // Every stage finished, the camera table shows a focal length, the pictures load.
  const statuses = await page.$$eval('#stage-rows tr td:nth-child(2)', (cells) =>
      cells.map((cell) => cell.textContent));
  assert.deepEqual(statuses, Array(7).fill('success'));
  // The focal length with its precision (one standard deviation).
  assert.match(await page.textContent('#cameras'), /\d+\.\d\d ± \d+\.\d\d/);
  await page.waitForFunction(() => {
    const pictures = [...document.querySelectorAll('#pictures img')];
    return pictures.length === 2 && pictures.every((img) => img.complete && img.naturalWidth > 0);
  });
  const files = await page.$$eval('#files-list a', (links) => links.map((a) => a.textContent));
  for (const name of ['cameras.json', 'sparse.ply', 'report.json']) assert.ok(files.includes(name));
  const download = await page.getAttribute('#job-actions a', 'href');
  const zip = await fetch(baseUrl + download);
  assert.equal(zip.status, 200);
  assert.equal(zip.headers.get('content-type'), 'application/zip');
  assert.match(await page.textContent('#log'), /queued with 11 photos/);
  await page.screenshot({path: path.join(os.tmpdir(), 'reconduit-web-test.png'), fullPage: true});

  // Delete: the job leaves the list and the service.
  const id = page.url().split('#')[1];
  await page.click('#job-actions button:has-text("Delete")');
  await page.waitForSelector('#job', {state: 'hidden'});
  assert.equal((await fetch(`${baseUrl}/api/v1/jobs/${id}`)).status, 404);
  await page.waitForFunction(() => document.querySelectorAll('#job-rows tr').length === 0);
  assert.deepEqual(errors, []);
  await page.close();
});
