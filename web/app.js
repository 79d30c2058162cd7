// Reconduit's browser page: upload photos, follow jobs, look at the results. Plain JavaScript
// against the JSON API (README, "Using the API"); no build step, nothing loaded from elsewhere
// (the 3D view, viewer.js, imports three.js from this server's web/vendor/).
'use strict';

const API = '/api/v1';
const STAGES = ['ingest', 'features', 'pairs', 'matching', 'sparse', 'dense', 'mesh', 'texture', 'export', 'package'];
// A per-map table longer than this starts collapsed.
const LONG_MAP_LIST = 12;
const FINAL = new Set(['succeeded', 'failed', 'canceled']);

const $ = (id) => document.getElementById(id);

// An element with attributes and children (strings become text: nothing is parsed as HTML).
function el(tag, attributes = {}, ...children) {
  const node = document.createElement(tag);
  for (const [key, value] of Object.entries(attributes)) {
    if (value === undefined || value === null || value === false) continue;
    if (key.startsWith('on')) node.addEventListener(key.slice(2), value);
    else node.setAttribute(key, value === true ? '' : value);
  }
  for (const child of children.flat()) {
    if (child === undefined || child === null) continue;
    node.append(child instanceof Node ? child : String(child));
  }
  return node;
}

// The service's error text: {"error": {"code", "message"}} or the status line.
async function errorText(response) {
  try {
    const body = await response.json();
    if (body && body.error && body.error.message) return body.error.message;
  } catch (e) { /* not JSON */ }
  return `${response.status} ${response.statusText}`;
}

async function api(path, options = {}) {
  const response = await authFetch(API + path, options);
  if (!response.ok) throw new Error(await errorText(response));
  return response.json();
}

// ---------------------------------------------------------------------------------------------
// The access token: a service started with --token (or RECONDUIT_TOKEN) answers 401 to every
// request without it but /healthz and the page's own files.
//
// The page asks for it when the service first answers 401, keeps it in this tab's
// sessionStorage only (gone when the tab closes; "Forget the token" clears it sooner) and sends
// it as `Authorization: Bearer …` with every request: fetch and XMLHttpRequest here, the 3D
// view's loader in viewer.js. What the browser would fetch by URL on its own (downloads,
// pictures, links opened in a new tab) cannot carry a header, so with a token those are fetched
// here and handed over as blob: URLs. The token never goes in a URL: URLs end up in logs and in
// the history.

const TOKEN_KEY = 'reconduit.token';

function storedToken() {
  try {
    return sessionStorage.getItem(TOKEN_KEY) || '';
  } catch (e) {
    return '';  // Storage disabled: every request then goes without a token.
  }
}

function authHeaders(token = storedToken()) {
  return token ? {Authorization: `Bearer ${token}`} : {};
}

function showTokenState() {
  $('token-state').hidden = !storedToken();
}

// The open dialog's promise (of the token entered): every refused request waits for the same.
let tokenAsked = null;

// `refused`: the message says a token was refused (shown as an error).
function askToken(message, refused = false) {
  if (tokenAsked) return tokenAsked;
  tokenAsked = new Promise((resolve) => {
    const form = $('token-form');
    const input = $('token-input');
    $('token-message').textContent = message;
    $('token-message').className = refused ? 'error' : '';
    input.value = '';
    const submit = (event) => {
      event.preventDefault();
      const token = input.value.trim();
      // What an HTTP header can carry; the service's tokens have no white space either.
      if (!/^[\x21-\x7e]+$/.test(token)) {
        $('token-message').textContent = 'A token is printable ASCII, without spaces.';
        $('token-message').className = 'error';
        return;
      }
      form.removeEventListener('submit', submit);
      try {
        sessionStorage.setItem(TOKEN_KEY, token);
      } catch (e) { /* Storage disabled: the requests waiting now still get the token. */ }
      $('token-dialog').close();
      tokenAsked = null;
      showTokenState();
      resolve(token);
    };
    form.addEventListener('submit', submit);
    $('token-dialog').showModal();
    input.focus();
  });
  return tokenAsked;
}

// After a 401 to a request that carried `used` ('' for none), with the service's `reason`:
// resolves with the token to try next. A token entered meanwhile (for another refused request)
// is simply tried; a refused one is forgotten and asked for again.
function tokenAfterRefusal(used, reason) {
  const current = storedToken();
  if (current && current !== used) return Promise.resolve(current);
  if (!used) {
    return askToken('This service needs an access token (it was started with one). ' +
                    'Enter it to use the page.');
  }
  try {
    sessionStorage.removeItem(TOKEN_KEY);
  } catch (e) { /* nothing kept */ }
  showTokenState();
  return askToken(`The service refused this token (${reason}). Check it and enter it again.`, true);
}

// fetch with the token; a 401 asks for it (again) and retries. For requests whose body can be
// sent twice (every fetch of this page: the uploads go through XMLHttpRequest).
async function authFetch(url, options = {}) {
  for (;;) {
    const token = storedToken();
    const response = await fetch(url, {...options,
                                       headers: {...(options.headers || {}), ...authHeaders(token)}});
    if (response.status !== 401) return response;
    await tokenAfterRefusal(token, await errorText(response));
  }
}

// The body of `response` as a Blob, reporting progress(loaded, total) as it arrives.
async function readBlob(response, progress) {
  const total = Number(response.headers.get('Content-Length')) || 0;
  const type = response.headers.get('Content-Type') || '';
  if (!response.body) return response.blob();
  const reader = response.body.getReader();
  const parts = [];
  let loaded = 0;
  for (;;) {
    const {done, value} = await reader.read();
    if (done) break;
    parts.push(value);
    loaded += value.length;
    progress(loaded, total);
  }
  return new Blob(parts, {type});
}

// What a click on a link to a service URL does when there is a token: fetches `href` with it,
// then saves the file as `name`, or opens it in a new tab when `name` is null. Progress and
// errors go to `status` (an element).
async function followWithToken(href, name, status) {
  const label = name || href.split('/').pop();
  status.className = 'hint';
  status.textContent = `Downloading ${label}…`;
  let blob;
  try {
    const response = await authFetch(href);
    if (!response.ok) throw new Error(await errorText(response));
    blob = await readBlob(response, (loaded, total) => {
      status.textContent = `Downloading ${label}: ${bytes(loaded)}` +
                           (total > 0 ? ` of ${bytes(total)}` : '');
    });
  } catch (e) {
    status.className = 'error';
    status.textContent = `${label} could not be downloaded: ${e.message}`;
    return;
  }
  const url = URL.createObjectURL(blob);
  // Long enough for the browser to save it, or for the new tab to read it.
  setTimeout(() => URL.revokeObjectURL(url), 60000);
  status.textContent = '';
  if (name) {
    const save = el('a', {href: url, download: name, hidden: true});
    document.body.append(save);
    save.click();
    save.remove();
  } else if (!window.open(url, '_blank')) {
    // A popup blocker (the click's permission can lapse during a long download).
    status.replaceChildren(`${label} is ready: `, el('a', {href: url, target: '_blank'}, 'open it'));
  }
}

// Makes `link` (to a service URL) work with a token: followed as usual without one (the browser
// streams the download to disk), through followWithToken with one; `status`: where its progress
// shows (by default under the job's buttons).
function withToken(link, name, status = null) {
  link.addEventListener('click', (event) => {
    if (!storedToken()) return;
    event.preventDefault();
    followWithToken(link.getAttribute('href'), name, status || $('download-status'));
  });
  return link;
}

function forgetToken() {
  try {
    sessionStorage.removeItem(TOKEN_KEY);
  } catch (e) { /* nothing kept */ }
  // Start over: nothing the token showed stays on screen, and the service will ask again.
  location.reload();
}

function duration(seconds) {
  if (seconds === null || seconds === undefined) return '';
  if (seconds < 60) return `${seconds.toFixed(seconds < 10 ? 1 : 0)} s`;
  const m = Math.floor(seconds / 60), s = Math.round(seconds % 60);
  if (m < 60) return `${m} min ${s} s`;
  return `${Math.floor(m / 60)} h ${m % 60} min`;
}

function bytes(n) {
  if (n < 1024) return `${n} B`;
  if (n < 1024 * 1024) return `${(n / 1024).toFixed(1)} KiB`;
  if (n < 1024 * 1024 * 1024) return `${(n / 1024 / 1024).toFixed(1)} MiB`;
  return `${(n / 1024 / 1024 / 1024).toFixed(2)} GiB`;
}

function when(iso) {
  return iso ? new Date(iso).toLocaleString() : '';
}

function badge(job) {
  const text = job.cancel_requested && !FINAL.has(job.state) ? 'canceling' : job.state;
  return el('span', {class: `badge ${job.state}`}, text);
}

// ---------------------------------------------------------------------------------------------
// Health

async function checkHealth() {
  const status = $('health');
  try {
    const response = await fetch('/healthz');
    const body = await response.json();
    const up = response.ok && body.status === 'ok';
    status.textContent = up ? 'The service is up.' : `The service answered: ${JSON.stringify(body)}`;
    status.className = `status ${up ? 'ok' : 'bad'}`;
  } catch (e) {
    status.textContent = `The service did not answer: ${e.message}`;
    status.className = 'status bad';
  }
}

// ---------------------------------------------------------------------------------------------
// Upload

let chosenFiles = [];

function choose(files) {
  chosenFiles = Array.from(files);
  const total = chosenFiles.reduce((sum, f) => sum + f.size, 0);
  $('drop-text').textContent = chosenFiles.length === 0
      ? 'Drop photos (JPEG, PNG, TIFF) or one zip of photos here, or click to choose.'
      : `${chosenFiles.length} file${chosenFiles.length === 1 ? '' : 's'}, ${bytes(total)}: ` +
        chosenFiles.slice(0, 6).map((f) => f.name).join(', ') +
        (chosenFiles.length > 6 ? ', …' : '');
  $('submit').disabled = chosenFiles.length === 0;
  $('upload-status').textContent = '';
  $('upload-status').className = '';
}

function isZip(file) {
  return file.type === 'application/zip' || file.type === 'application/x-zip-compressed' ||
         file.name.toLowerCase().endsWith('.zip');
}

function upload(event) {
  event.preventDefault();
  if (chosenFiles.length === 0) return;
  const statusLine = $('upload-status');
  const optionsText = $('options').value.trim();
  if (optionsText) {
    try {
      const parsed = JSON.parse(optionsText);
      if (typeof parsed !== 'object' || parsed === null || Array.isArray(parsed)) {
        throw new Error('the options must be one JSON object');
      }
    } catch (e) {
      statusLine.textContent = `Options: ${e.message}`;
      statusLine.className = 'error';
      return;
    }
  }
  const zips = chosenFiles.filter(isZip);
  if (zips.length > 0 && chosenFiles.length > 1) {
    statusLine.textContent = 'Send either photos or one zip, not both.';
    statusLine.className = 'error';
    return;
  }
  let body;
  let target = `${API}/jobs`;
  if (zips.length === 1) {
    // A zip goes as the body; options then travel in the query string.
    if (optionsText) target += `?options=${encodeURIComponent(optionsText)}`;
    body = zips[0];
  } else {
    body = new FormData();
    if (optionsText) body.append('options', optionsText);
    for (const file of chosenFiles) body.append('images', file, file.name);
  }
  sendUpload(target, zips.length === 1 ? 'application/zip' : null, body);
}

// Sends an upload (XMLHttpRequest, for its upload progress) with the token; after a 401 asks
// for the token and sends it again.
function sendUpload(target, type, body) {
  const statusLine = $('upload-status');
  const request = new XMLHttpRequest();
  request.open('POST', target);
  if (type) request.setRequestHeader('Content-Type', type);
  const token = storedToken();
  for (const [name, value] of Object.entries(authHeaders(token))) {
    request.setRequestHeader(name, value);
  }
  const bar = $('upload-progress');
  bar.hidden = false;
  bar.value = 0;
  $('submit').disabled = true;
  statusLine.className = '';
  statusLine.textContent = 'Uploading…';
  request.upload.addEventListener('progress', (e) => {
    if (!e.lengthComputable) return;
    bar.value = e.loaded / e.total;
    statusLine.textContent = `Uploading: ${bytes(e.loaded)} of ${bytes(e.total)}`;
  });
  request.addEventListener('load', () => {
    bar.hidden = true;
    let answer = null;
    try { answer = JSON.parse(request.responseText); } catch (e) { /* not JSON */ }
    const message = answer && answer.error ? answer.error.message
                                           : `${request.status} ${request.statusText}`;
    if (request.status === 401) {
      statusLine.textContent = 'Waiting for the access token…';
      tokenAfterRefusal(token, message).then(() => sendUpload(target, type, body));
      return;
    }
    if (request.status === 201 && answer) {
      choose([]);  // Clears the status line too: the message comes after.
      $('files').value = '';
      statusLine.textContent = `Job created with ${answer.counts.images} photos.`;
      refreshJobs();
      select(answer.id);
      pollSoon();
    } else {
      statusLine.textContent = `Not accepted: ${message}`;
      statusLine.className = 'error';
      $('submit').disabled = false;
    }
  });
  request.addEventListener('error', () => {
    bar.hidden = true;
    statusLine.textContent = 'The upload failed: the connection was lost.';
    statusLine.className = 'error';
    $('submit').disabled = false;
  });
  request.send(body);
}

// ---------------------------------------------------------------------------------------------
// Job list

let selectedId = null;

async function refreshJobs() {
  let list;
  try {
    list = await api('/jobs?limit=50');
  } catch (e) {
    $('jobs-empty').hidden = false;
    $('jobs-empty').textContent = `The job list could not be read: ${e.message}`;
    return false;
  }
  const rows = list.jobs.map((job) => el('tr', {class: job.id === selectedId ? 'selected' : null},
      el('td', {}, when(job.created_at)),
      el('td', {}, job.counts ? job.counts.images : ''),
      el('td', {}, badge(job)),
      el('td', {},
         el('progress', {max: 1, value: job.progress || 0}), ' ',
         FINAL.has(job.state) ? '' : (job.stage || '')),
      el('td', {}, el('button', {type: 'button', onclick: () => select(job.id)}, 'Open'))));
  $('job-rows').replaceChildren(...rows);
  $('jobs-empty').hidden = list.jobs.length > 0;
  $('jobs-empty').textContent = 'No jobs yet: upload photos above.';
  return list.jobs.some((job) => !FINAL.has(job.state));
}

// ---------------------------------------------------------------------------------------------
// One job

let lastEventId = 0;
let shownFilesFor = null;

function select(id) {
  if (selectedId !== id) {
    selectedId = id;
    lastEventId = 0;
    shownFilesFor = null;
    $('log').textContent = '';
    for (const part of ['maps', 'cameras', 'rejected', 'files-list', 'download-status']) {
      $(part).replaceChildren();
    }
    setPictures();
    closeModel();
    modelMessage('');
  }
  if (location.hash !== `#${id}`) history.replaceState(null, '', `#${id}`);
  $('job').hidden = false;
  refreshJob();
  refreshJobs();
}

async function act(path, method, confirmText) {
  if (confirmText && !window.confirm(confirmText)) return;
  try {
    await api(`/jobs/${selectedId}${path}`, {method});
  } catch (e) {
    window.alert(e.message);
    refreshJob();
    return;
  }
  if (method === 'DELETE') {
    selectedId = null;
    closeModel();
    $('job').hidden = true;
    history.replaceState(null, '', location.pathname);
  } else {
    refreshJob();
  }
  refreshJobs();
}

function summaryText(summary) {
  if (!summary) return '';
  const parts = [];
  for (const [key, value] of Object.entries(summary)) {
    if (key === 'skipped_reason') continue;  // Shown as the stage's status.
    if (typeof value === 'number') {
      parts.push(`${key.replaceAll('_', ' ')} ${Number.isInteger(value) ? value : value.toFixed(3)}`);
    } else if (typeof value === 'string' && key !== 'archive_sha256') {
      parts.push(`${key.replaceAll('_', ' ')} ${value}`);
    }
  }
  return parts.join(', ');
}

// Why a stage was skipped (its status "skipped", or a summary's skipped_reason: the stage could
// not work on these photos and the job went on without it), or null when it was not.
function skippedReason(s) {
  const reason = s.summary && s.summary.skipped_reason;
  if (s.status !== 'skipped' && !reason) return null;
  return reason || s.message || 'no reason given';
}

// The stage's own peak memory (the high-water mark since it began), or while it runs the
// memory in use now; a dash where only the process's peak is known (the worker could not
// reset the kernel's mark, or the stage ran before stages kept their own).
function stagePeakCell(s) {
  if (s.stage_peak_memory_own && s.stage_peak_memory_bytes) {
    return el('td', {class: 'memory'}, bytes(s.stage_peak_memory_bytes));
  }
  if (s.status === 'running' && s.memory_bytes) {
    return el('td', {class: 'memory', title: 'In use now'}, `${bytes(s.memory_bytes)} now`);
  }
  if (s.peak_memory_bytes) {
    return el('td', {class: 'memory', title: 'Not measured: only the process\'s peak is known'},
              '—');
  }
  return el('td', {class: 'memory'});
}

function stageRow(job, name) {
  const s = (job.stages || {})[name] || {};
  const skipped = skippedReason(s);
  const status = skipped ? 'skipped' : s.status || (job.stage === name ? 'running' : '');
  let found = s.message && !s.status ? s.message : summaryText(s.summary);
  if (skipped) found = skipped;
  return el('tr', {'data-stage': name, class: skipped ? 'skipped' : null},
      el('td', {}, s.title || name),
      el('td', {}, status),
      el('td', {class: 'progress'}, el('progress', {max: 1, value: s.progress || 0}),
         s.total ? ` ${s.done} / ${s.total}` : ''),
      el('td', {}, duration(s.seconds)),
      stagePeakCell(s),
      el('td', {class: 'memory'}, s.peak_memory_bytes ? bytes(s.peak_memory_bytes) : ''),
      el('td', {}, found));
}

// The stages to list: every stage of the pipeline; but a succeeded job has an entry for each
// stage it ran, so a stage it has none for was not part of its pipeline (a job from before
// that stage existed) and is left out.
function shownStages(job) {
  const stages = job.stages || {};
  return STAGES.filter((name) => job.state !== 'succeeded' || name in stages);
}

function percent(fraction) {
  return typeof fraction === 'number' ? `${Math.round(fraction * 100)} %` : '';
}

// Whether the person opened or closed a stage's per-map table, kept across the refreshes.
const mapsOpen = new Map();

// Per stage whose summary lists "maps" (the dense stage: one depth map per photo): the time of
// each map and the share of its pixels with a depth and with a fused point. Long lists start
// collapsed.
function renderMaps(job) {
  const sections = [];
  for (const name of shownStages(job)) {
    const s = (job.stages || {})[name];
    const maps = s && s.summary && s.summary.maps;
    if (!Array.isArray(maps) || maps.length === 0) continue;
    const key = `${job.id}/${name}`;
    const open = mapsOpen.has(key) ? mapsOpen.get(key) : maps.length <= LONG_MAP_LIST;
    const total = maps.reduce((sum, m) => sum + (typeof m.seconds === 'number' ? m.seconds : 0), 0);
    const rows = maps.map((m) => el('tr', {},
        el('td', {}, m.image || ''),
        el('td', {}, duration(m.seconds)),
        el('td', {}, percent(m.depth_fraction)),
        el('td', {}, percent(m.fused_fraction))));
    const details = el('details', {class: 'maps', 'data-stage': name, open},
        el('summary', {}, `${s.title || name}: ${maps.length} map${maps.length === 1 ? '' : 's'}, ` +
                          `${duration(total)} in all`),
        el('table', {},
           el('thead', {}, el('tr', {}, el('th', {}, 'Photo'), el('th', {}, 'Time'),
                              el('th', {}, 'With depth'), el('th', {}, 'Fused'))),
           el('tbody', {}, rows)));
    details.addEventListener('toggle', () => mapsOpen.set(key, details.open));
    sections.push(details);
  }
  $('maps').replaceChildren(...(sections.length > 0 ? [el('h3', {}, 'Per map'), ...sections] : []));
}

function renderCameras(job) {
  const sparse = job.stages && job.stages.sparse;
  const cameras = sparse && sparse.summary && sparse.summary.cameras;
  if (!cameras || cameras.length === 0) return;
  const rows = cameras.map((c) => {
    const sd = c.stddev || {};
    const focal = c.final_focal !== undefined ? c.final_focal : c.initial_focal;
    return el('tr', {},
        el('td', {}, c.camera_id),
        el('td', {}, `${c.width} × ${c.height}`),
        el('td', {}, c.photos),
        el('td', {}, focal !== undefined ? focal.toFixed(2) : '',
           sd.focal ? ` ± ${sd.focal.toFixed(2)}` : ''),
        el('td', {}, (c.initial_focal_source || '').replaceAll('_', ' ')),
        el('td', {}, c.warning || c.self_calibration || ''));
  });
  $('cameras').replaceChildren(
      el('h3', {}, 'Cameras'),
      el('table', {},
         el('thead', {}, el('tr', {}, el('th', {}, 'Camera'), el('th', {}, 'Size'),
                            el('th', {}, 'Photos'), el('th', {}, 'Focal length (px, ± 1σ)'),
                            el('th', {}, 'Started from'), el('th', {}, 'Note'))),
         el('tbody', {}, rows)));
}

function renderRejected(job) {
  const items = (job.images && job.images.items) || [];
  const rejected = items.filter((image) => image.status !== 'accepted');
  if (rejected.length === 0) {
    $('rejected').replaceChildren();
    return;
  }
  $('rejected').replaceChildren(
      el('h3', {}, 'Photos not used'),
      el('ul', {}, rejected.map((image) => el('li', {}, `${image.name}: ${image.reason || image.status}`))));
}

async function renderFiles(job) {
  if (job.state !== 'succeeded') {
    // A restarted job will have new files: list them again when it succeeds.
    shownFilesFor = null;
    setPictures();
    $('files-list').replaceChildren();
    modelNotYet(job);
    return;
  }
  if (shownFilesFor === job.id) return;
  shownFilesFor = job.id;
  let listing;
  try {
    listing = await api(`/jobs/${job.id}/files`);
  } catch (e) {
    if (job.id === selectedId) {
      $('files-list').replaceChildren(el('p', {class: 'error'}, `Files: ${e.message}`));
    }
    shownFilesFor = null;
    return;
  }
  if (job.id !== selectedId) return;  // Another job was opened meanwhile.
  // The report's pictures (the deliverables' own images, e.g. 16-bit depth maps, are files).
  const pictures = listing.files.filter((f) => f.name.startsWith('report/') &&
                                               /^image\/(png|jpeg)$/.test(f.type));
  const captions = {
    'report/similarity.png': 'Which photos resemble which (brighter: more alike).',
    'report/match_graph.png': 'Which pairs matched (green: epipolar geometry; orange: planar or rotation only).',
  };
  const caption = (name) => {
    if (captions[name]) return captions[name];
    const photo = /^report\/photos\/(.*)\.jpg$/.exec(name);
    if (photo) return `${photo[1]}: the photo`;
    const render = /^report\/texture\/(.*)_(render|photo)\.jpg$/.exec(name);
    if (render) {
      return render[2] === 'render' ? `${render[1]}: the model seen through this photo's camera`
                                    : `${render[1]}: the photo the model is compared with`;
    }
    const dense = /^report\/dense\/(.*)_(depth|quality)\.(jpg|png)$/.exec(name);
    if (!dense) return name;
    return dense[2] === 'depth' ? `${dense[1]}: depth (red near, blue far, black: none)`
                                : `${dense[1]}: how many photos agree (red: this one only; ` +
                                      'orange to green: 2 and more)';
  };
  setPictures(
      el('h3', {}, 'Pictures'),
      el('div', {class: 'pictures'}, pictures.map((f) => el('figure', {},
          picture(f), el('figcaption', {class: 'hint'}, caption(f.name))))));
  $('files-list').replaceChildren(
      el('h3', {}, 'Files'),
      el('ul', {}, listing.files.map((f) => {
        const name = f.name.split('/').pop();
        return el('li', {}, withToken(el('a', {href: f.url, download: name}, f.name), name),
                  ` (${bytes(f.bytes)})`);
      })));
  showModel(job, listing.files);  // Not awaited: the rest of the page does not wait for it.
}

// The pictures' blob: URLs (with a token), released when the pictures are replaced.
let pictureUrls = [];

function setPictures(...children) {
  for (const url of pictureUrls) URL.revokeObjectURL(url);
  pictureUrls = [];
  $('pictures').replaceChildren(...children);
}

// With a token a picture is fetched (with it) once scrolled to, as loading="lazy" would.
const pictureObserver = 'IntersectionObserver' in window
    ? new IntersectionObserver((entries) => {
      for (const entry of entries) {
        if (!entry.isIntersecting) continue;
        pictureObserver.unobserve(entry.target);
        loadPicture(entry.target);
      }
    }, {rootMargin: '200px'})
    : null;

async function loadPicture(img) {
  let blob;
  try {
    const response = await authFetch(img.dataset.src);
    if (!response.ok) throw new Error(await errorText(response));
    blob = await response.blob();
  } catch (e) {
    img.alt = `${img.alt} (${e.message})`;
    return;
  }
  if (!img.isConnected) return;  // Replaced meanwhile.
  const url = URL.createObjectURL(blob);
  pictureUrls.push(url);
  img.src = url;
  img.parentElement.href = url;
}

// A report picture, linked to itself (opens in a new tab).
function picture(f) {
  if (!storedToken()) {
    return el('a', {href: f.url, target: '_blank'}, el('img', {src: f.url, alt: f.name, loading: 'lazy'}));
  }
  const img = el('img', {alt: f.name, 'data-src': f.url});
  if (pictureObserver) pictureObserver.observe(img);
  else loadPicture(img);
  return el('a', {target: '_blank'}, img);
}

// ---------------------------------------------------------------------------------------------
// The 3D view of model.glb (viewer.js, three.js): imported only when a job has a model.

let viewerModule = null;
let modelFor = null;  // The job whose model is shown or loading.

function loadViewer() {
  if (!viewerModule) viewerModule = import('./viewer.js');
  return viewerModule;
}

// Says why there is no model (or what is happening), without a view.
function modelMessage(text, className = 'hint') {
  $('model-status').textContent = text;
  $('model-status').className = className;
  $('model-progress').hidden = true;
  $('model-box').hidden = true;
  $('model-photo').textContent = '';
}

async function closeModel() {
  modelFor = null;
  if (!viewerModule) return;
  try {
    (await viewerModule).close();
  } catch (e) { /* never loaded: nothing to close */ }
}

// A job that has not succeeded: what the view will hold, or why it will not.
function modelNotYet(job) {
  if (modelFor !== null) closeModel();
  const stage = job.stage && job.stages && job.stages[job.stage];
  const texts = {
    queued: 'The 3D model appears here once the job has succeeded; it is waiting for a worker.',
    running: 'The 3D model appears here once the job has succeeded; it is running' +
             (job.stage ? ` (${(stage && stage.title) || job.stage})` : '') + '.',
    failed: 'The job failed, so there is no 3D model.',
    canceled: 'The job was canceled, so there is no 3D model.',
  };
  modelMessage(texts[job.state] || `The job is ${job.state}: no 3D model yet.`);
}

function photoFacts(name, camera) {
  if (!name) return '';
  const x = camera.userData;
  const size = x.width && x.height ? `, ${x.width} × ${x.height} px` : '';
  const focal = typeof x.focal === 'number' ? `, focal length ${x.focal.toFixed(1)} px` : '';
  return `Seen from ${name}${size}${focal} (${camera.fov.toFixed(1)}° high).`;
}

// A succeeded job: its model.glb in the view, the photos' cameras as a list beside it.
async function showModel(job, files) {
  const model = files.find((f) => f.name === 'model.glb');
  if (!model) {
    await closeModel();
    const stages = job.stages || {};
    const reasons = ['dense', 'mesh', 'texture']
        .map((name) => [(stages[name] || {}).title || name, skippedReason(stages[name] || {})])
        .filter(([, reason]) => reason !== null)
        .map(([title, reason]) => ` ${title} skipped: ${reason}.`);
    modelMessage('This job has no 3D model (no model.glb).' +
                 (reasons.length > 0 ? reasons.join('') : ' Its pipeline did not build one.'));
    return;
  }
  if (modelFor === job.id) return;
  modelFor = job.id;
  modelMessage(`Loading the model (${bytes(model.bytes)})…`);
  const bar = $('model-progress');
  bar.hidden = false;
  bar.value = 0;
  $('model-box').hidden = false;
  $('model-cameras').replaceChildren();
  let viewer;
  try {
    viewer = await loadViewer();
  } catch (e) {
    viewerModule = null;
    if (modelFor === job.id) {
      modelMessage(`The 3D view could not start: ${e.message} (its three.js files are missing ` +
                   'from the server\'s web/vendor/: bash scripts/web_deps.sh installs them).', 'error');
      modelFor = null;
    }
    return;
  }
  if (modelFor !== job.id) return;
  const callbacks = {
    onProgress: (loaded, total) => {
      if (modelFor !== job.id) return;
      bar.value = total > 0 ? Math.min(loaded / total, 1) : 0;
      $('model-status').textContent = total > 0 && loaded >= total
          ? 'Preparing the model…'
          : `Loading the model: ${bytes(loaded)}${total > 0 ? ` of ${bytes(total)}` : ''}`;
    },
    onSelect: (name, camera) => {
      if (modelFor !== job.id) return;
      $('model-photo').textContent = photoFacts(name, camera);
      for (const button of $('model-cameras').querySelectorAll('button')) {
        button.setAttribute('aria-pressed', String(button.dataset.photo === name));
      }
    },
  };
  let shown;
  try {
    shown = await viewer.open($('model-canvas'), model.url, model.bytes, callbacks, authHeaders());
  } catch (e) {
    if (modelFor === job.id) {
      modelMessage(`The model could not be shown: ${e.message}`, 'error');
      modelFor = null;
      viewer.close();
    }
    return;
  }
  if (modelFor !== job.id) return;
  bar.hidden = true;
  $('model-status').className = 'hint';
  $('model-status').textContent =
      `${shown.faces.toLocaleString('en')} triangles; ${shown.cameras.length} photo ` +
      `camera${shown.cameras.length === 1 ? '' : 's'}. Drag to turn, scroll to zoom, ` +
      'right-drag to move; click a camera (or a photo below) to look through it.';
  $('model-cameras').replaceChildren(...shown.cameras.map((name) => el('li', {},
      el('button', {type: 'button', 'data-photo': name, 'aria-pressed': 'false',
                    onclick: () => viewer.lookThrough(name)}, name))));
}

let logBusy = false;

async function refreshLog() {
  if (logBusy) return;
  logBusy = true;
  try {
    await readEvents();
  } finally {
    logBusy = false;
  }
}

async function readEvents() {
  const path = `/jobs/${selectedId}/events?after=${lastEventId}&limit=200`;
  const id = selectedId;
  const response = await authFetch(API + path);
  if (!response.ok || id !== selectedId) return;
  const text = await response.text();
  if (id !== selectedId) return;
  const log = $('log');
  for (const line of text.split('\n')) {
    if (!line.trim()) continue;
    let event;
    try { event = JSON.parse(line); } catch (e) { continue; }
    lastEventId = Math.max(lastEventId, event.id);
    const time = new Date(event.time).toLocaleTimeString();
    log.append(`${time}  ${event.level.padEnd(7)} ${event.message}\n`);
  }
  log.scrollTop = log.scrollHeight;
}

async function refreshJob() {
  if (!selectedId) return false;
  const id = selectedId;
  let job;
  try {
    job = await api(`/jobs/${id}`);
  } catch (e) {
    $('job-summary').replaceChildren(el('p', {class: 'error'}, e.message));
    $('job-actions').replaceChildren();
    return false;
  }
  if (id !== selectedId) return false;
  const facts = [
    badge(job), ' ',
    `${job.counts.images} photos`,
    job.counts.registered !== undefined ? `, ${job.counts.registered} cameras recovered` : '',
    job.counts.points !== undefined ? `, ${job.counts.points} points` : '',
    job.elapsed_seconds ? `; ran ${duration(job.elapsed_seconds)}` : '',
    job.eta_seconds ? `; about ${duration(job.eta_seconds)} left` : '',
  ];
  $('job-title').textContent = `Job ${job.id.slice(0, 8)}`;
  const error = job.error ? el('p', {class: 'error'}, job.error.message || JSON.stringify(job.error))
                          : '';
  const skipped = Object.entries(job.stages || {})
      .map(([name, s]) => [s.title || name, skippedReason(s)])
      .filter(([, reason]) => reason !== null)
      .map(([title, reason]) => `${title} skipped: ${reason}`);
  const skippedNote = skipped.length > 0 ? el('p', {class: 'skipped'}, skipped.join('; ')) : '';
  // Photos the model left out, and why (the sparse stage's plain sentence).
  const sparse = (job.stages || {}).sparse;
  const leftOut = sparse && sparse.summary && sparse.summary.left_out;
  const leftOutNote = leftOut && leftOut.note ? el('p', {class: 'skipped', id: 'left-out'}, leftOut.note) : '';
  $('job-summary').replaceChildren(el('p', {}, facts), leftOutNote, skippedNote, error);
  const actions = [];
  if (job.state === 'succeeded') {
    const name = `reconduit-${job.id.slice(0, 8)}.zip`;
    actions.push(withToken(el('a', {href: job.links.result, download: name},
                              el('button', {type: 'button', class: 'primary'},
                                 `Download result.zip${job.result ? ` (${bytes(job.result.bytes)})` : ''}`)),
                           name));
  }
  if (!FINAL.has(job.state) && !job.cancel_requested) {
    actions.push(el('button', {type: 'button', onclick: () => act('/cancel', 'POST')}, 'Cancel'));
  }
  if (job.state === 'failed' || job.state === 'canceled') {
    actions.push(el('button', {type: 'button', onclick: () => act('/restart', 'POST')}, 'Restart'));
  }
  if (job.state !== 'running') {
    actions.push(el('button', {type: 'button',
                               onclick: () => act('', 'DELETE', 'Delete this job and its files?')},
                    'Delete'));
  }
  $('job-actions').replaceChildren(...actions);
  $('stage-rows').replaceChildren(...shownStages(job).map((name) => stageRow(job, name)));
  renderMaps(job);
  renderCameras(job);
  renderRejected(job);
  await renderFiles(job);
  await refreshLog();
  return !FINAL.has(job.state);
}

// ---------------------------------------------------------------------------------------------
// Start

function setUp() {
  const drop = $('drop');
  $('files').addEventListener('change', (e) => choose(e.target.files));
  for (const type of ['dragenter', 'dragover']) {
    drop.addEventListener(type, (e) => { e.preventDefault(); drop.classList.add('over'); });
  }
  for (const type of ['dragleave', 'drop']) {
    drop.addEventListener(type, () => drop.classList.remove('over'));
  }
  drop.addEventListener('drop', (e) => { e.preventDefault(); choose(e.dataTransfer.files); });
  $('upload-form').addEventListener('submit', upload);
  // The service's option list opens in a new tab, with the token when there is one.
  withToken($('options-link'), null, $('upload-status'));
  $('token-forget').addEventListener('click', forgetToken);
  // The page cannot do anything without the token: Escape does not close the dialog.
  $('token-dialog').addEventListener('cancel', (e) => e.preventDefault());
  showTokenState();
  $('model-overview').addEventListener('click', async () => {
    if (viewerModule) (await viewerModule).overview();
  });
  checkHealth();
  if (location.hash.length > 1) select(location.hash.slice(1));

  tick();
}

// Poll quickly while something runs, slowly otherwise; pollSoon() (a new job) goes back to the
// quick pace at once instead of after the slow pause.
let tickTimer = null;
let ticking = false;
let activeSoon = false;

async function tick() {
  clearTimeout(tickTimer);
  ticking = true;
  activeSoon = false;
  let active = true;
  try {
    const [jobsActive, jobActive] = await Promise.all([refreshJobs(), refreshJob()]);
    active = jobsActive || jobActive;
  } catch (e) {
    // A lost connection (a server restart): try again at the slow pace.
    active = false;
  } finally {
    ticking = false;
    tickTimer = setTimeout(tick, active || activeSoon ? 1500 : 8000);
  }
}

function pollSoon() {
  if (ticking) {
    activeSoon = true;
    return;
  }
  clearTimeout(tickTimer);
  tickTimer = setTimeout(tick, 1500);
}

setUp();
