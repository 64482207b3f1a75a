// nsrm studio: the page. Everything it shows is computed by the nsrm server (the same code as the
// CLI) except the WebGPU preview, which runs nsrm's generated WGSL in the page.
'use strict';

const TOKEN = new URLSearchParams(location.search).get('token') || '';
const SVGNS = 'http://www.w3.org/2000/svg';
const $ = (id) => document.getElementById(id);

const S = {
  info: null,
  frame: null, // the frame state from the server
  fit: null, // the last fit response
  compare: null,
  dragCorners: null, // corners being dragged (frame pixels)
  busy: 0,
};

function withToken(url) {
  return url + (url.includes('?') ? '&' : '?') + 'token=' + encodeURIComponent(TOKEN);
}

function status(msg, isError) {
  const el = $('status');
  el.textContent = msg;
  el.classList.toggle('error', !!isError);
  document.body.dataset.status = isError ? 'error' : 'ok';
}

async function api(method, path, body, raw) {
  const opts = { method, headers: { 'X-Nsrm-Token': TOKEN } };
  if (body !== undefined) {
    if (raw) {
      opts.body = body;
      opts.headers['Content-Type'] = 'application/octet-stream';
    } else {
      opts.body = JSON.stringify(body);
      opts.headers['Content-Type'] = 'application/json';
    }
  }
  S.busy++;
  document.body.dataset.busy = String(S.busy);
  try {
    const r = await fetch(path, opts);
    const ct = r.headers.get('Content-Type') || '';
    const data = ct.startsWith('application/json') ? await r.json() : await r.text();
    if (!r.ok) {
      const msg = (data && data.error) || String(data) || r.statusText;
      throw new Error(msg);
    }
    return data;
  } finally {
    S.busy--;
    document.body.dataset.busy = String(S.busy);
  }
}

function fmt(v, d = 2) {
  return typeof v === 'number' && isFinite(v) ? v.toFixed(d) : '–';
}

function option(sel, value, text) {
  const o = document.createElement('option');
  o.value = value;
  o.textContent = text === undefined ? value : text;
  sel.appendChild(o);
  return o;
}

// ---- opening frames -------------------------------------------------------------------------

async function init() {
  try {
    S.info = await api('GET', '/api/info');
  } catch (e) {
    status('cannot reach the studio: ' + e.message, true);
    return;
  }
  const files = $('files');
  files.textContent = '';
  if (S.info.files.length === 0) option(files, '', '(none listed)');
  for (const f of S.info.files) option(files, f.index, f.name);
  for (const f of S.info.files) option($('flat'), 'file:' + f.index, 'flat frame: ' + f.name);
  for (const r of S.info.references) option($('reference'), r);
  for (const f of S.info.formats) option($('format'), f);
  for (const s of S.info.spaces) {
    option($('space'), s);
    option($('export-space'), s);
  }
  $('space').value = 'linear-srgb';
  $('export-space').value = 'xyz';
  status('ready: open a frame');
  document.body.dataset.ready = '1';
}

async function openListed() {
  const i = $('files').value;
  if (i === '') return;
  status('reading ' + $('files').selectedOptions[0].textContent + '…');
  try {
    showFrame(await api('POST', `/api/files/${i}/open`));
  } catch (e) {
    status(e.message, true);
  }
}

async function upload(file) {
  status(`uploading ${file.name} (${(file.size / 1e6).toFixed(1)} MB)…`);
  if (S.info && file.size > S.info.max_upload_bytes) {
    status(`${file.name}: ${file.size} bytes is over the limit of ${S.info.max_upload_bytes}`, true);
    return;
  }
  try {
    showFrame(await api('POST', '/api/frames?name=' + encodeURIComponent(file.name), file, true));
  } catch (e) {
    status(e.message, true);
  }
}

async function uploadFlat(file) {
  if (!S.frame) {
    status('open a frame first, then its flat frame', true);
    return;
  }
  if (S.info && file.size > S.info.max_upload_bytes) {
    status(`${file.name}: ${file.size} bytes is over the limit of ${S.info.max_upload_bytes}`, true);
    return;
  }
  status(`uploading the flat frame ${file.name}…`);
  try {
    const st = await api('POST', `/api/frames/${S.frame.id}/flat?name=` + encodeURIComponent(file.name), file, true);
    showFrame(st);
    if (!st.error) status(`flat field: ${file.name}`);
  } catch (e) {
    status(e.message, true);
  }
}

async function uploadReference(file) {
  if (!S.frame) {
    status('open a frame first, then the reference file of its chart', true);
    return;
  }
  status(`uploading the reference ${file.name}…`);
  try {
    const st = await api('POST', `/api/frames/${S.frame.id}/reference?name=` + encodeURIComponent(file.name), file, true);
    showFrame(st);
    if (!st.error) status(`reference: ${file.name}`);
  } catch (e) {
    status(e.message, true);
  }
}

function showFrame(st) {
  const first = !S.frame || S.frame.id !== st.id;
  S.frame = st;
  if (first) {
    S.fit = null;
    S.compare = null;
    $('fit-result').textContent = '';
    $('compare').textContent = '';
    $('swatches').textContent = '';
    $('histogram').textContent = '';
    $('corrected').hidden = true;
    $('corrected-canvas').hidden = true;
    $('corrected-device').textContent = '';
    const img = $('preview');
    img.src = withToken(st.preview.url);
  }
  $('viewer').classList.add('loaded');
  $('frame-name').textContent = `${st.name} (${st.width}×${st.height})`;
  $('chart').value = st.settings.chart;
  const refSel = $('reference');
  let refUp = refSel.querySelector('option[value="upload"]');
  if (st.reference_upload) {
    if (!refUp) refUp = option(refSel, 'upload', '');
    refUp.textContent = st.reference_upload + ' (uploaded)';
  } else if (refUp) {
    refUp.remove();
  }
  refSel.value = st.settings.reference || '';
  const flatSel = $('flat');
  let up = flatSel.querySelector('option[value="upload"]');
  if (st.flat_upload) {
    if (!up) up = option(flatSel, 'upload', '');
    up.textContent = 'flat frame: ' + st.flat_upload + ' (uploaded)';
  } else if (up) {
    up.remove();
  }
  flatSel.value = st.settings.flat || 'none';
  S.dragCorners = null;
  if (!st.fitted) {
    S.fit = null;
  }
  drawOverlay();
  showReadingInfo();
  updateLinks();
  $('command').textContent = st.command;
  if (st.error) status(st.error, true);
  else status('chart read');
  document.body.dataset.readings = String(Number(document.body.dataset.readings || 0) + 1);
}

// ---- the overlay: patches, flags, corners ---------------------------------------------------

function currentCorners() {
  const st = S.frame;
  if (S.dragCorners) return S.dragCorners;
  if (st.reading) return st.reading.corners;
  if (st.settings.corners) return st.settings.corners;
  // No reading: a starting guess in the middle of the frame, to drag onto the chart.
  const w = st.width, h = st.height;
  return [[w * 0.3, h * 0.3], [w * 0.7, h * 0.3], [w * 0.7, h * 0.7], [w * 0.3, h * 0.7]];
}

function el(name, attrs, parent) {
  const e = document.createElementNS(SVGNS, name);
  for (const [k, v] of Object.entries(attrs)) e.setAttribute(k, v);
  if (parent) parent.appendChild(e);
  return e;
}

// Smallest label drawn, in screen pixels.
const MIN_LABEL_PX = 7;

function drawOverlay() {
  const st = S.frame;
  const svg = $('overlay');
  svg.textContent = '';
  svg.setAttribute('viewBox', `0 0 ${st.width} ${st.height}`);
  svg.setAttribute('preserveAspectRatio', 'none');
  const excluded = new Set(st.settings.exclude);
  const patches = st.reading ? st.reading.patches : [];
  const pitch = patches.length > 1
    ? Math.hypot(patches[0].outline[1][0] - patches[0].outline[0][0], patches[0].outline[1][1] - patches[0].outline[0][1])
    : st.width / 20;
  // Screen pixels per frame pixel (the overlay is scaled with the preview).
  const shown = svg.getBoundingClientRect().width;
  const scale = shown > 0 ? shown / st.width : 1;
  let hidden = 0;
  for (const p of patches) {
    const flagged = p.flags.length > 0;
    const cls = 'patch' + (flagged ? ' flagged' : '') + (excluded.has(p.label) ? ' excluded' : '');
    const poly = el('polygon', { class: cls, points: p.outline.map((q) => q.join(',')).join(' ') }, svg);
    poly.dataset.label = p.label;
    const t = el('title', {}, poly);
    t.textContent = `${p.label}: RGB ${p.rgb.map((v) => v.toPrecision(4)).join(', ')}` +
      (flagged ? ` — ${p.flags.join(', ')}` : '') + (excluded.has(p.label) ? ' — excluded by hand' : '');
    poly.addEventListener('click', () => toggleExclude(p));
    // A label fits inside its patch (about 0.6 em per character), and is left out when it would
    // be too small to read on screen: then the patch's tooltip names it.
    // The patch's number or grid name (`01`, `A1`); the full name is in the tooltip.
    const short = p.label.split(' ')[0];
    const text = flagged ? `${short} ${p.flags.map((f) => f[0].toUpperCase()).join('')}` : short;
    const size = Math.min(pitch * 0.45, (pitch * 0.9) / (0.6 * text.length));
    if (size * scale < MIN_LABEL_PX) {
      hidden++;
      continue;
    }
    const lab = el('text', { class: 'plabel' + (flagged ? ' flagged' : ''), x: p.centre[0], y: p.centre[1], 'font-size': size }, svg);
    lab.textContent = text;
  }
  svg.dataset.labelsHidden = String(hidden);
  const c = currentCorners();
  el('polygon', { class: 'grid', points: c.map((q) => q.join(',')).join(' ') }, svg);
  const r = Math.max(st.width, st.height) / 90;
  c.forEach((q, i) => {
    const g = el('g', { class: 'corner-handle', 'data-index': i }, svg);
    el('circle', { class: 'corner', cx: q[0], cy: q[1], r }, g);
    const n = el('text', { class: 'cnum', x: q[0], y: q[1], 'font-size': r * 1.2 }, g);
    n.textContent = String(i + 1);
    g.addEventListener('pointerdown', (ev) => startDrag(ev, i));
  });
}

function framePoint(ev) {
  const svg = $('overlay');
  const pt = svg.createSVGPoint();
  pt.x = ev.clientX;
  pt.y = ev.clientY;
  const m = svg.getScreenCTM();
  const p = pt.matrixTransform(m.inverse());
  return [p.x, p.y];
}

function startDrag(ev, i) {
  ev.preventDefault();
  const svg = $('overlay');
  S.dragCorners = currentCorners().map((q) => q.slice());
  svg.setPointerCapture(ev.pointerId);
  const move = (e) => {
    const p = framePoint(e);
    S.dragCorners[i] = [Math.max(0, Math.min(S.frame.width, p[0])), Math.max(0, Math.min(S.frame.height, p[1]))];
    drawOverlay();
  };
  const up = async (e) => {
    svg.removeEventListener('pointermove', move);
    svg.removeEventListener('pointerup', up);
    svg.releasePointerCapture(e.pointerId);
    const corners = S.dragCorners.map((q) => [Math.round(q[0] * 100) / 100, Math.round(q[1] * 100) / 100]);
    await setReading({ corners });
  };
  svg.addEventListener('pointermove', move);
  svg.addEventListener('pointerup', up);
}

async function setReading(changes) {
  const st = S.frame;
  if (!st) return;
  const settings = Object.assign({}, st.settings, changes);
  status('reading the chart…');
  try {
    showFrame(await api('POST', `/api/frames/${st.id}/reading`, settings));
  } catch (e) {
    S.dragCorners = null;
    drawOverlay();
    status(e.message, true);
  }
}

function toggleExclude(p) {
  const ex = new Set(S.frame.settings.exclude);
  if (p.flags.length > 0 && !ex.has(p.label)) {
    status(`${p.label} is already left out: ${p.flags.join(', ')}`);
    return;
  }
  if (ex.has(p.label)) ex.delete(p.label);
  else ex.add(p.label);
  setReading({ exclude: [...ex] });
}

function showReadingInfo() {
  const st = S.frame;
  const info = $('reading-info');
  if (!st.reading) {
    info.textContent = 'No chart reading: ' + (st.error || '') + ' Drag the four corners onto the chart.';
    return;
  }
  const r = st.reading;
  const pv = r.provenance;
  const usable = r.patches.filter((p) => p.flags.length === 0).length;
  const flagged = r.patches.filter((p) => p.flags.length > 0).map((p) => `${p.label} (${p.flags.join(', ')})`);
  const ex = st.settings.exclude.length;
  info.textContent = `${pv.chart} ${pv.located === 'detected' ? 'found automatically' : 'read at the given corners'}; ` +
    `${r.patches.length} patches, ${usable} usable${ex ? `, ${ex} excluded by hand` : ''}; ` +
    `reference ${pv.reference}: median ΔE00 ${fmt(pv.reference_match_de00)} after a 3×3 map; ` +
    `white level ${r.white_level === null ? 'none' : fmt(r.white_level, 4)}${r.white_level_inferred ? ' (inferred)' : ''}; ` +
    `flat field ${pv.flat}${pv.flat !== 'none' ? ` (non-uniformity ${fmt(pv.light_nonuniformity, 3)})` : ''}` +
    (flagged.length ? `; flagged: ${flagged.join(', ')}` : '');
}

// ---- fitting and comparing ------------------------------------------------------------------

function fitRequest() {
  return {
    kind: $('kind').value,
    order: Number($('order').value),
    objective: $('objective').value,
    preserve_white: $('preserve-white').checked,
    white_patch: $('white-patch').value.trim() || null,
    ridge: $('ridge').value || null,
    normalise: $('normalise').value,
  };
}

async function fit() {
  if (!S.frame) return;
  status('fitting…');
  try {
    const r = await api('POST', `/api/frames/${S.frame.id}/fit`, fitRequest());
    S.fit = r;
    S.frame.fitted = { kind: r.kind, order: r.order };
    showFit();
    updateLinks();
    $('command').textContent = r.command;
    await refreshCommand();
    status(`fitted ${r.kind.toUpperCase()} order ${r.order}`);
    document.body.dataset.fits = String(Number(document.body.dataset.fits || 0) + 1);
  } catch (e) {
    status(e.message, true);
  }
}

function showFit() {
  const r = S.fit;
  const s = r.in_sample;
  const rep = r.report;
  $('fit-result').textContent = `${r.kind.toUpperCase()} order ${r.order} (${r.terms} terms) on ${r.n_patches} patches: ` +
    `in-sample ΔE00 mean ${fmt(s.mean, 3)}, median ${fmt(s.median, 3)}, p95 ${fmt(s.p95, 3)}, max ${fmt(s.max, 3)}; ` +
    `objective ${rep.objective}, ridge λ ${rep.ridge_lambda}, condition number ${rep.condition_number === null ? 'inf' : rep.condition_number.toExponential(3)}`;
  const grid = $('swatches');
  grid.textContent = '';
  for (const p of r.patches) {
    const d = document.createElement('div');
    d.className = 'swatch' + (p.dE00 > 3 ? ' bad' : '');
    d.title = `${p.label}: reference | corrected, ΔE00 ${fmt(p.dE00, 3)}`;
    const pair = document.createElement('div');
    pair.className = 'pair';
    for (const c of [p.reference_srgb8, p.corrected_srgb8]) {
      const sp = document.createElement('span');
      sp.style.background = `rgb(${c[0]},${c[1]},${c[2]})`;
      pair.appendChild(sp);
    }
    d.appendChild(pair);
    const t = document.createElement('div');
    t.textContent = `${p.label} ${fmt(p.dE00)}`;
    d.appendChild(t);
    grid.appendChild(d);
  }
  histogram(r.patches.map((p) => p.dE00));
}

function histogram(values) {
  const svg = $('histogram');
  svg.textContent = '';
  const W = 400, H = 130, pad = 18;
  svg.setAttribute('viewBox', `0 0 ${W} ${H}`);
  const max = Math.max(...values, 0.5);
  const step = max > 8 ? 1 : max > 3 ? 0.5 : 0.25;
  const nb = Math.ceil(max / step + 1e-9);
  const bins = new Array(nb).fill(0);
  for (const v of values) bins[Math.min(nb - 1, Math.floor(v / step))]++;
  const top = Math.max(...bins, 1);
  const bw = (W - 2 * pad) / nb;
  bins.forEach((n, i) => {
    const h = (H - 2 * pad) * n / top;
    el('rect', { class: 'bar-rect', x: pad + i * bw + 1, y: H - pad - h, width: Math.max(1, bw - 2), height: h }, svg);
    if (n) {
      const t = el('text', { x: pad + (i + 0.5) * bw, y: H - pad - h - 3, 'text-anchor': 'middle' }, svg);
      t.textContent = String(n);
    }
  });
  for (let i = 0; i <= nb; i += Math.max(1, Math.round(nb / 8))) {
    const t = el('text', { x: pad + i * bw, y: H - 4, 'text-anchor': 'middle' }, svg);
    t.textContent = (i * step).toString();
  }
  const t = el('text', { x: W - pad, y: 12, 'text-anchor': 'end' }, svg);
  t.textContent = 'ΔE00 histogram (in-sample), patches per bin';
}

function modelName(m, o) {
  return m === 'lrm' ? 'LRM' : m.toUpperCase() + o;
}

async function compareAll() {
  if (!S.frame) return;
  status('leave-one-out and in-sample ΔE00 of every model…');
  try {
    const r = await api('POST', `/api/frames/${S.frame.id}/compare`, fitRequest());
    S.compare = r;
    showCompare();
    status('compared ' + r.leave_one_out.length + ' models');
  } catch (e) {
    status(e.message, true);
  }
}

function showCompare() {
  const r = S.compare;
  const box = $('compare');
  box.textContent = '';
  const h = document.createElement('h2');
  h.textContent = `ΔE00 of every model on ${r.n_patches} patches` +
    (r.best ? ` — suggested: ${modelName(r.best.model, r.best.order)} (lowest leave-one-out mean)` : '');
  box.appendChild(h);
  const table = document.createElement('table');
  const head = table.createTHead().insertRow();
  for (const t of ['model', 'LOO mean', 'median', 'p95', 'max', 'in-sample mean', 'max']) {
    const th = document.createElement('th');
    th.textContent = t;
    head.appendChild(th);
  }
  const body = table.createTBody();
  r.leave_one_out.forEach((l, i) => {
    const ins = r.in_sample[i] || {};
    const tr = body.insertRow();
    tr.className = 'row-model';
    if (r.best && l.model === r.best.model && l.order === r.best.order) tr.classList.add('best');
    tr.title = 'fit this model';
    if (l.error) {
      tr.insertCell().textContent = modelName(l.model, l.order);
      const td = tr.insertCell();
      td.colSpan = 6;
      td.className = 'error-cell';
      td.textContent = l.error;
    } else {
      const cells = [modelName(l.model, l.order), fmt(l.mean, 3), fmt(l.median, 3), fmt(l.p95, 3), fmt(l.max, 3), fmt(ins.mean, 3), fmt(ins.max, 3)];
      for (const c of cells) tr.insertCell().textContent = c;
    }
    if (!l.error) tr.addEventListener('click', () => {
      $('kind').value = l.model;
      $('order').value = String(l.order);
      fit();
    });
  });
  box.appendChild(table);
  const p = document.createElement('pre');
  p.className = 'hint';
  p.textContent = 'The same with the CLI (add --in-sample for the in-sample columns):\n' + r.command;
  box.appendChild(p);
}

// ---- corrected preview ----------------------------------------------------------------------

async function showCorrected() {
  if (!S.frame || !S.fit) {
    status('fit a model first', true);
    return;
  }
  const space = $('space').value;
  const useGpu = $('where').value === 'auto' && navigator.gpu;
  if (useGpu) {
    try {
      const adapterName = await correctedWebGpu(space);
      $('corrected-device').textContent = `Computed in this page with WebGPU (${adapterName}), running the WGSL nsrm generates (nsrm export-shader --lang wgsl --layout rgb --output-space ${space}).`;
      $('corrected-device').dataset.device = 'webgpu';
      await compareWithServer(space);
      return;
    } catch (e) {
      $('corrected-device').textContent = 'WebGPU failed (' + e.message + '); computed by the server instead.';
    }
  }
  const img = $('corrected');
  let ran = null;
  try {
    const r = await fetch(`/api/frames/${S.frame.id}/corrected.png?space=${encodeURIComponent(space)}`, {
      headers: { 'X-Nsrm-Token': TOKEN },
    });
    if (!r.ok) {
      const ct = r.headers.get('Content-Type') || '';
      const data = ct.startsWith('application/json') ? await r.json() : { error: await r.text() };
      throw new Error((data && data.error) || r.statusText);
    }
    ran = { device: r.headers.get('X-Nsrm-Device') || 'cpu', detail: r.headers.get('X-Nsrm-Device-Detail') || '' };
    const blob = await r.blob();
    if (img.dataset.objectUrl) URL.revokeObjectURL(img.dataset.objectUrl);
    const objectUrl = URL.createObjectURL(blob);
    img.dataset.objectUrl = objectUrl;
    await new Promise((ok, bad) => {
      img.onload = ok;
      img.onerror = () => bad(new Error('the corrected preview failed'));
      img.src = objectUrl;
    });
  } catch (e) {
    status('corrected preview: ' + e.message, true);
    return;
  }
  img.hidden = false;
  $('corrected-canvas').hidden = true;
  const why = navigator.gpu ? '' : ' (this browser has no WebGPU)';
  const where = ran.device === 'gpu'
    ? `on its GPU (${ran.detail})`
    : `on the CPU${ran.detail && !ran.detail.includes('was asked for') ? ' (' + ran.detail + ')' : ''}`;
  if (!useGpu || !$('corrected-device').textContent.startsWith('WebGPU failed')) {
    $('corrected-device').textContent = `Computed by the nsrm server ${where}${why}, as nsrm apply --output-space ${space} does.`;
  } else {
    $('corrected-device').textContent += ` The server computed it ${where}.`;
  }
  $('corrected-device').dataset.device = 'server';
  $('corrected-device').dataset.serverDevice = ran.device;
}

function srgb8(v) {
  if (!(v > 0)) return 0;
  if (v >= 1) return 255;
  const e = v <= 0.0031308 ? 12.92 * v : 1.055 * Math.pow(v, 1 / 2.4) - 0.055;
  return Math.round(e * 255);
}

async function correctedWebGpu(space) {
  const id = S.frame.id;
  const sh = await api('GET', `/api/frames/${id}/shader?space=${encodeURIComponent(space)}`);
  const r = await fetch(`/api/frames/${id}/pixels.f32`, { headers: { 'X-Nsrm-Token': TOKEN } });
  if (!r.ok) throw new Error('pixels: ' + r.status);
  const bytes = new Uint8Array(await r.arrayBuffer());
  const adapter = await navigator.gpu.requestAdapter();
  if (!adapter) throw new Error('no WebGPU adapter');
  const device = await adapter.requestDevice();
  const info = adapter.info || {};
  const module = device.createShaderModule({ code: sh.wgsl });
  const ci = await module.getCompilationInfo();
  const errs = ci.messages.filter((m) => m.type === 'error');
  if (errs.length) throw new Error('WGSL: ' + errs.map((m) => m.message).join('; '));
  const pipeline = device.createComputePipeline({ layout: 'auto', compute: { module, entryPoint: 'main' } });
  const buf = device.createBuffer({ size: bytes.byteLength, usage: GPUBufferUsage.STORAGE | GPUBufferUsage.COPY_SRC | GPUBufferUsage.COPY_DST });
  device.queue.writeBuffer(buf, 0, bytes);
  const read = device.createBuffer({ size: bytes.byteLength, usage: GPUBufferUsage.MAP_READ | GPUBufferUsage.COPY_DST });
  const bg = device.createBindGroup({ layout: pipeline.getBindGroupLayout(0), entries: [{ binding: 1, resource: { buffer: buf } }] });
  const enc = device.createCommandEncoder();
  const pass = enc.beginComputePass();
  pass.setPipeline(pipeline);
  pass.setBindGroup(0, bg);
  const px = sh.width * sh.height;
  const groups = Math.ceil(px / sh.workgroup_size);
  if (groups <= 256) pass.dispatchWorkgroups(groups, 1, 1);
  else pass.dispatchWorkgroups(256, Math.ceil(groups / 256), 1);
  pass.end();
  enc.copyBufferToBuffer(buf, 0, read, 0, bytes.byteLength);
  device.queue.submit([enc.finish()]);
  await read.mapAsync(GPUMapMode.READ);
  const out = new Float32Array(read.getMappedRange().slice(0));
  read.unmap();
  device.destroy();
  const m = sh.to_linear_srgb;
  const canvas = $('corrected-canvas');
  canvas.width = sh.width;
  canvas.height = sh.height;
  const ctx = canvas.getContext('2d');
  const img = ctx.createImageData(sh.width, sh.height);
  for (let i = 0; i < px; i++) {
    const a = out[3 * i], b = out[3 * i + 1], c = out[3 * i + 2];
    for (let k = 0; k < 3; k++) img.data[4 * i + k] = srgb8(m[k][0] * a + m[k][1] * b + m[k][2] * c);
    img.data[4 * i + 3] = 255;
  }
  ctx.putImageData(img, 0, 0);
  canvas.hidden = false;
  $('corrected').hidden = true;
  return [info.vendor, info.architecture].filter(Boolean).join(' ') || 'adapter';
}

// The page's WebGPU result against the server's preview, in 8-bit codes.
async function compareWithServer(space) {
  const url = withToken(`/api/frames/${S.frame.id}/corrected.png?space=${encodeURIComponent(space)}`);
  const img = new Image();
  await new Promise((ok, bad) => {
    img.onload = ok;
    img.onerror = bad;
    img.src = url;
  });
  const c = document.createElement('canvas');
  c.width = img.width;
  c.height = img.height;
  const ctx = c.getContext('2d');
  ctx.drawImage(img, 0, 0);
  const a = ctx.getImageData(0, 0, c.width, c.height).data;
  const b = $('corrected-canvas').getContext('2d').getImageData(0, 0, c.width, c.height).data;
  let max = 0;
  for (let i = 0; i < a.length; i++) if ((i & 3) !== 3) max = Math.max(max, Math.abs(a[i] - b[i]));
  const el2 = $('corrected-device');
  el2.textContent += ` Largest difference from the server's preview: ${max}/255.`;
  el2.dataset.maxDiff = String(max);
}

// ---- downloads and the command line ---------------------------------------------------------

function updateLinks() {
  const st = S.frame;
  const fitted = st && st.fitted;
  const base = st ? `/api/frames/${st.id}` : '';
  const fmtSel = $('format').value;
  const space = $('export-space').value;
  const set = (id, ok, href, name) => {
    const a = $(id);
    a.classList.toggle('disabled', !ok);
    if (ok) a.href = withToken(href);
    else a.removeAttribute('href');
    if (name) a.setAttribute('download', name);
  };
  set('download-export', fitted, `${base}/export?format=${encodeURIComponent(fmtSel)}&space=${encodeURIComponent(space)}`, `model.${fmtSel}`);
  $('download-export').textContent = `model.${fmtSel}`;
  set('download-model', fitted, `${base}/model.json`);
  set('download-csv', st && st.reading, `${base}/patches.csv`);
  set('download-overlay', st && st.reading, `${base}/overlay.png`);
}

async function refreshCommand() {
  if (!S.frame) return;
  try {
    const q = `format=${encodeURIComponent($('format').value)}&space=${encodeURIComponent($('export-space').value)}`;
    $('command').textContent = await api('GET', `/api/frames/${S.frame.id}/command?${q}`);
  } catch (e) {
    status(e.message, true);
  }
}

// ---- wiring ---------------------------------------------------------------------------------

function wire() {
  window.addEventListener('resize', () => {
    if (S.frame) drawOverlay();
  });
  $('open-file').addEventListener('click', openListed);
  $('file-input').addEventListener('change', (e) => {
    if (e.target.files[0]) upload(e.target.files[0]);
  });
  const viewer = $('viewer');
  document.addEventListener('dragover', (e) => {
    e.preventDefault();
    viewer.classList.add('dragging');
  });
  document.addEventListener('dragleave', () => viewer.classList.remove('dragging'));
  document.addEventListener('drop', (e) => {
    e.preventDefault();
    viewer.classList.remove('dragging');
    const f = e.dataTransfer && e.dataTransfer.files[0];
    if (!f) return;
    // Dropped on the flat-field control: the flat frame of the open frame.
    const onFlat = e.target instanceof Element && e.target.closest('#flat-drop, #flat-input');
    if (onFlat) uploadFlat(f);
    else upload(f);
  });
  $('reference-input').addEventListener('change', (e) => {
    if (e.target.files[0]) uploadReference(e.target.files[0]);
    e.target.value = '';
  });
  $('flat-input').addEventListener('change', (e) => {
    if (e.target.files[0]) uploadFlat(e.target.files[0]);
    e.target.value = '';
  });
  $('chart').addEventListener('change', () => setReading({ chart: $('chart').value, corners: null, exclude: [] }));
  $('reference').addEventListener('change', () => setReading({ reference: $('reference').value || null }));
  $('flat').addEventListener('change', () => setReading({ flat: $('flat').value }));
  $('detect').addEventListener('click', () => setReading({ corners: null }));
  $('include-all').addEventListener('click', () => setReading({ exclude: [] }));
  $('fit').addEventListener('click', fit);
  $('compare-all').addEventListener('click', compareAll);
  $('show-corrected').addEventListener('click', showCorrected);
  for (const id of ['format', 'export-space']) {
    $(id).addEventListener('change', () => {
      updateLinks();
      refreshCommand();
    });
  }
}

wire();
init();
