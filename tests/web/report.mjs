// report.html as a person opens it: result.zip extracted to a folder, the page opened from
// file:// in chromium, no server and no network. Used by page.test.mjs on the result.zip of
// its real kermit job.
import assert from 'node:assert/strict';
import {execFileSync} from 'node:child_process';
import fs from 'node:fs';
import path from 'node:path';
import {pathToFileURL} from 'node:url';

// Extracts `zipBytes` into `folder` (Debian's unzip), opens report.html and checks that every
// picture loaded, that no request failed or left the folder, and that every link points to an
// extracted file. Returns the page's text and the extracted folder's file names.
export async function checkExtractedReport(browser, zipBytes, folder) {
  fs.mkdirSync(folder, {recursive: true});
  const zipPath = path.join(folder, 'result.zip');
  fs.writeFileSync(zipPath, zipBytes);
  const extracted = path.join(folder, 'extracted');
  try {
    execFileSync('unzip', ['-q', '-o', zipPath, '-d', extracted]);
  } catch (error) {
    throw new Error(`cannot extract result.zip (is unzip installed? apt-get install unzip): ${error}`);
  }
  const files = fs.readdirSync(extracted, {recursive: true})
                    .filter((f) => fs.statSync(path.join(extracted, f)).isFile())
                    .map((f) => f.split(path.sep).join('/'));

  const page = await browser.newPage({viewport: {width: 1200, height: 900}});
  const failed = [];
  const outside = [];
  const errors = [];
  page.on('requestfailed', (request) =>
      failed.push(`${request.url()}: ${request.failure()?.errorText}`));
  page.on('request', (request) => {
    if (!request.url().startsWith(pathToFileURL(extracted).href + '/')) outside.push(request.url());
  });
  page.on('pageerror', (error) => errors.push(error.message));
  page.on('console', (message) => {
    if (message.type() === 'error') errors.push(message.text());
  });
  await page.goto(pathToFileURL(path.join(extracted, 'report.html')).href, {waitUntil: 'load'});

  const images = await page.$$eval('img', (all) => all.map((img) => ({
    src: img.getAttribute('src'), complete: img.complete, width: img.naturalWidth})));
  assert.ok(images.length > 0, 'report.html shows pictures');
  const broken = images.filter((img) => !img.complete || img.width === 0);
  assert.deepEqual(broken, [], 'every picture loads');
  assert.deepEqual(failed, [], 'no request fails');
  assert.deepEqual(outside, [], 'nothing is fetched from outside the extracted folder');
  assert.deepEqual(errors, [], 'no error in the console');
  const links = await page.$$eval('a[href]', (all) => all.map((a) => a.getAttribute('href')));
  for (const link of links) {
    const target = decodeURIComponent(link);
    assert.ok(fs.existsSync(path.join(extracted, target)), `${link}: the link's file is there`);
  }
  const text = await page.textContent('body');
  await page.close();
  return {text, files, images};
}
