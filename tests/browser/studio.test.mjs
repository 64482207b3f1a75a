// The studio in a real browser: headless Debian chromium driven by puppeteer-core (no browser
// download). Starts `nsrm studio --no-browser`, loads the page, drops a `render-scene` frame,
// waits for the overlay, drags a corner and sees the reading change, fits, compares, shows the
// corrected preview (WebGPU where the browser has it), downloads a CLF and checks it equals what
// the page's own command lines make with `nsrm export`, byte for byte; no console errors.
// Screenshots go to $STUDIO_OUT. Run by tests/all/studio.rs (the_page_in_a_real_browser).
import puppeteer from 'puppeteer-core';
import { spawn, execFileSync } from 'node:child_process';
import fs from 'node:fs';
import path from 'node:path';
import os from 'node:os';

const BIN = process.env.NSRM_BIN || 'nsrm';
const CHROMIUM = process.env.NSRM_CHROMIUM || '/usr/bin/chromium';
const OUT = process.env.STUDIO_OUT || fs.mkdtempSync(path.join(os.tmpdir(), 'studio-out-'));
const WORK = process.env.STUDIO_WORK || fs.mkdtempSync(path.join(os.tmpdir(), 'studio-work-'));
fs.mkdirSync(OUT, { recursive: true });

const log = (...a) => console.log('[studio test]', ...a);
// With every panel filled (reading, fit, comparison, corrected preview): no horizontal scroll at
// common window widths, and the corrected preview right under its button (no blank gap).
async function checkLayout(page) {
  // The server's preview too (a browser without WebGPU): the page's canvas is then hidden.
  await page.select('#where', 'server');
  await page.click('#show-corrected');
  await page.waitForFunction(() => document.getElementById('corrected-device').dataset.device === 'server', { timeout: 120000 });
  for (const width of [1280, 1400, 1920]) {
    await page.setViewport({ width, height: 1000 });
    await sleep(200);
    const m = await page.evaluate(() => {
      const shown = [...document.querySelectorAll('#corrected, #corrected-canvas')].find((e) => !e.hidden);
      const button = document.getElementById('show-corrected').getBoundingClientRect();
      return {
        scrollWidth: document.documentElement.scrollWidth,
        innerWidth: window.innerWidth,
        gap: shown ? shown.getBoundingClientRect().top - button.bottom : null,
      };
    });
    log(`layout at ${width} px:`, JSON.stringify(m));
    if (m.scrollWidth > m.innerWidth) fail(`horizontal scroll at ${width} px: the page is ${m.scrollWidth} px wide`);
    if (m.gap === null || m.gap > 120) fail(`the corrected preview starts ${m.gap} px below its button at ${width} px`);
    await page.screenshot({ path: path.join(OUT, `06-layout-${width}.png`), fullPage: true });
  }
  await page.setViewport({ width: 1500, height: 1100 });
}

function fail(msg) {
  throw new Error(msg);
}
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

async function until(what, fn, ms = 60000) {
  const t0 = Date.now();
  for (;;) {
    const v = await fn();
    if (v) return v;
    if (Date.now() - t0 > ms) fail(`timed out after ${ms} ms waiting for ${what}`);
    await sleep(100);
  }
}

// A synthetic capture.
const scene = path.join(WORK, 'scene.exr');
execFileSync(BIN, ['render-scene', '--chart', 'cc24', '--width', '960', '--height', '640', '--seed', '7',
  '--min-area', '0.2', '-o', scene], { stdio: 'inherit' });

// The server, in an empty directory (it must write nothing there).
const serveDir = path.join(WORK, 'serve');
fs.rmSync(serveDir, { recursive: true, force: true });
fs.mkdirSync(serveDir);
// A listed frame with a long name, as a real shoot's are: its name fills the file and flat-field
// menus, which must not push the page sideways.
const listed = path.join(WORK, 'a_chart_shot_under_the_tungsten_lamps_of_stage_b_take_0001_after_the_lens_change.exr');
fs.copyFileSync(scene, listed);
const server = spawn(BIN, ['studio', '--no-browser', listed], { cwd: serveDir, stdio: ['ignore', 'pipe', 'inherit'] });
let serverOut = '';
server.stdout.on('data', (d) => { serverOut += d; });
let browser;
let errors = [];

try {
  const url = await until('the studio URL', () => {
    const m = serverOut.match(/nsrm studio: (http:\/\/127\.0\.0\.1:\d+\/\?token=[0-9a-f]+)/);
    return m && m[1];
  }, 30000);
  log('server at', url.replace(/token=.*/, 'token=…'));

  browser = await puppeteer.launch({
    executablePath: CHROMIUM,
    headless: true,
    args: ['--no-sandbox', '--enable-unsafe-webgpu', '--window-size=1500,1100'],
    defaultViewport: { width: 1500, height: 1100 },
    // Chromium's profile, dconf and caches in the work directory, never the caller's.
    userDataDir: path.join(WORK, 'chromium-profile'),
    env: { ...process.env, HOME: WORK, XDG_CONFIG_HOME: path.join(WORK, 'config'), XDG_CACHE_HOME: path.join(WORK, 'cache') },
  });
  const page = await browser.newPage();
  page.on('console', (m) => {
    if (m.type() === 'error') errors.push(`console: ${m.text()}`);
  });
  page.on('pageerror', (e) => errors.push(`page error: ${e.message}`));
  page.on('requestfailed', (r) => errors.push(`request failed: ${r.url().replace(/token=[0-9a-f]+/, 'token=…')}`));
  page.on('response', (r) => {
    if (r.status() >= 400) errors.push(`HTTP ${r.status()}: ${r.url().replace(/token=[0-9a-f]+/, 'token=…')}`);
  });

  await page.goto(url, { waitUntil: 'load' });
  await page.waitForSelector('body[data-ready="1"]', { timeout: 30000 });
  await page.screenshot({ path: path.join(OUT, '01-loaded.png') });
  // The drop zone's text is one centred paragraph, not flex columns.
  const hint = await page.evaluate(() => {
    const p = document.querySelector('#drop-hint > p');
    const v = document.getElementById('viewer').getBoundingClientRect();
    return p ? { width: p.getBoundingClientRect().width, viewer: v.width, kids: document.getElementById('drop-hint').children.length } : null;
  });
  if (!hint || hint.kids !== 1 || hint.width < 0.4 * hint.viewer) fail(`the drop zone's text is laid out in pieces: ${JSON.stringify(hint)}`);

  // Drop the frame on the page, as a person drags it from a file manager.
  const b64 = fs.readFileSync(scene).toString('base64');
  await page.evaluate(async (b64) => {
    const bin = atob(b64);
    const bytes = new Uint8Array(bin.length);
    for (let i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
    const dt = new DataTransfer();
    dt.items.add(new File([bytes], 'scene.exr', { type: 'image/x-exr' }));
    const viewer = document.getElementById('viewer');
    viewer.dispatchEvent(new DragEvent('dragover', { dataTransfer: dt, bubbles: true, cancelable: true }));
    viewer.dispatchEvent(new DragEvent('drop', { dataTransfer: dt, bubbles: true, cancelable: true }));
  }, b64);
  await page.waitForSelector('#overlay polygon.patch', { timeout: 60000 });
  await page.waitForFunction(() => document.getElementById('preview').complete && document.getElementById('preview').naturalWidth > 0);
  const first = await page.evaluate(() => ({
    patches: document.querySelectorAll('#overlay polygon.patch').length,
    located: S.frame.reading.provenance.located,
    rgb: S.frame.reading.patches.map((p) => p.rgb),
    readings: Number(document.body.dataset.readings),
  }));
  log(`overlay: ${first.patches} patches, ${first.located}`);
  if (first.patches !== 24) fail(`expected 24 patches in the overlay, got ${first.patches}`);
  await page.screenshot({ path: path.join(OUT, '02-overlay.png') });

  // Drag corner 3 a few pixels: a new reading at the given corners.
  const handle = await page.$('g.corner-handle[data-index="2"] circle');
  const box = await handle.boundingBox();
  const cx = box.x + box.width / 2, cy = box.y + box.height / 2;
  await page.mouse.move(cx, cy);
  await page.mouse.down();
  for (let i = 1; i <= 5; i++) await page.mouse.move(cx + 2 * i, cy - 1.5 * i);
  await page.mouse.up();
  await page.waitForFunction((n) => Number(document.body.dataset.readings) > n && document.body.dataset.busy === '0', { timeout: 60000 }, first.readings);
  const second = await page.evaluate(() => ({
    located: S.frame.reading && S.frame.reading.provenance.located,
    rgb: S.frame.reading && S.frame.reading.patches.map((p) => p.rgb),
    corners: S.frame.settings.corners,
    status: document.getElementById('status').textContent,
  }));
  if (second.located !== 'corners') fail(`after the drag the reading is not at the given corners: ${second.status}`);
  const changed = second.rgb.filter((c, i) => c.some((v, k) => v !== first.rgb[i][k])).length;
  log(`drag: corners ${JSON.stringify(second.corners)}; ${changed} patch readings changed`);
  if (changed === 0) fail('dragging a corner did not change the reading');
  await page.screenshot({ path: path.join(OUT, '03-dragged.png') });

  // Exclude a patch by clicking it, then take it back.
  await page.click('#overlay polygon.patch:not(.flagged)');
  await page.waitForFunction(() => S.frame.settings.exclude.length === 1 && document.body.dataset.busy === '0', { timeout: 60000 });
  await page.click('#include-all');
  await page.waitForFunction(() => S.frame.settings.exclude.length === 0 && document.body.dataset.busy === '0', { timeout: 60000 });

  // Fit NSRM 3 and compare every model.
  await page.select('#kind', 'nsrm');
  await page.select('#order', '3');
  await page.click('#fit');
  await page.waitForFunction(() => document.body.dataset.fits === '1' && document.body.dataset.busy === '0', { timeout: 120000 });
  await page.click('#compare-all');
  await page.waitForSelector('#compare table tr.best', { timeout: 300000 });
  const fitText = await page.$eval('#fit-result', (e) => e.textContent);
  const best = await page.$eval('#compare h2', (e) => e.textContent);
  log('fit:', fitText);
  log('compare:', best);
  await page.screenshot({ path: path.join(OUT, '04-fit.png'), fullPage: true });

  // The corrected preview: WebGPU in the page where the browser has it, else the server.
  await page.select('#space', 'linear-srgb');
  await page.click('#show-corrected');
  await page.waitForFunction(() => document.getElementById('corrected-device').dataset.device, { timeout: 120000 });
  await page.waitForFunction(() => {
    const e = document.getElementById('corrected-device');
    return e.dataset.device === 'server' || e.dataset.maxDiff !== undefined;
  }, { timeout: 60000 });
  const device = await page.$eval('#corrected-device', (e) => ({ text: e.textContent, device: e.dataset.device, maxDiff: e.dataset.maxDiff }));
  log('corrected preview:', device.text);
  if (device.device === 'webgpu' && Number(device.maxDiff) > 1) fail(`the WebGPU preview differs from the server's by ${device.maxDiff}/255`);
  await page.screenshot({ path: path.join(OUT, '05-corrected.png'), fullPage: true });
  await checkLayout(page);

  // Download the CLF (output space ACEScg) through the page's link.
  const dl = path.join(WORK, 'downloads');
  fs.rmSync(dl, { recursive: true, force: true });
  fs.mkdirSync(dl);
  const cdp = await page.createCDPSession();
  await cdp.send('Browser.setDownloadBehavior', { behavior: 'allow', downloadPath: dl });
  await page.select('#format', 'clf');
  await page.select('#export-space', 'acescg');
  await page.waitForFunction(() => document.getElementById('command').textContent.includes('--output-space acescg'), { timeout: 30000 });
  await page.click('#download-export');
  const clfPath = path.join(dl, 'model.clf');
  await until('the CLF download', () => fs.existsSync(clfPath) && !fs.readdirSync(dl).some((f) => f.endsWith('.crdownload')), 120000);
  const downloaded = fs.readFileSync(clfPath);

  // The page's command lines, run in a fresh directory holding the frame under its name.
  const command = await page.$eval('#command', (e) => e.textContent);
  log('command lines:\n' + command);
  const rerun = path.join(WORK, 'rerun');
  fs.rmSync(rerun, { recursive: true, force: true });
  fs.mkdirSync(rerun);
  fs.copyFileSync(scene, path.join(rerun, 'scene.exr'));
  for (const line of command.split('\n')) {
    if (!line.startsWith('nsrm ')) fail(`not an nsrm command: ${line}`);
    execFileSync('sh', ['-c', `"$NSRM_BIN" ${line.slice(5)}`], { cwd: rerun, env: { ...process.env, NSRM_BIN: BIN }, stdio: ['ignore', 'ignore', 'inherit'] });
  }
  const cliClf = fs.readFileSync(path.join(rerun, 'model.clf'));
  if (!cliClf.equals(downloaded)) {
    // Both kept as artefacts, with the command lines, to see where they part.
    fs.writeFileSync(path.join(OUT, 'mismatch-downloaded.clf'), downloaded);
    fs.writeFileSync(path.join(OUT, 'mismatch-cli.clf'), cliClf);
    fs.writeFileSync(path.join(OUT, 'mismatch-commands.txt'), command);
  }
  if (!cliClf.equals(downloaded)) fail(`the downloaded CLF (${downloaded.length} bytes) differs from nsrm export's (${cliClf.length} bytes)`);
  log(`CLF download equals nsrm export's, byte for byte (${downloaded.length} bytes)`);
  fs.copyFileSync(clfPath, path.join(OUT, 'model.clf'));

  if (fs.readdirSync(serveDir).length !== 0) fail(`the server wrote into its working directory: ${fs.readdirSync(serveDir)}`);
  if (errors.length) fail('errors in the page:\n' + errors.join('\n'));
  log(`ok; screenshots in ${OUT}`);
} catch (e) {
  console.error('[studio test] FAILED:', e.message);
  if (errors.length) console.error(errors.join('\n'));
  try {
    const pages = browser ? await browser.pages() : [];
    if (pages[1]) await pages[1].screenshot({ path: path.join(OUT, 'failure.png'), fullPage: true });
  } catch (_) { /* the screenshot is a courtesy */ }
  process.exitCode = 1;
} finally {
  if (browser) await browser.close();
  server.kill('SIGTERM');
  await new Promise((r) => {
    const t = setTimeout(() => { server.kill('SIGKILL'); r(); }, 10000);
    server.on('exit', () => { clearTimeout(t); r(); });
    if (server.exitCode !== null) { clearTimeout(t); r(); }
  });
}
