// The calibration report of `nsrm calibrate` (report.html) in headless Chromium: it renders
// (title, the overlay image decoded, the plots drawn), logs no console error, and no request
// leaves the page (every request other than the page itself and data: URLs fails the test).
// A screenshot goes to $REPORT_OUT/report.png. Run by tests/all/calibrate.rs.
import puppeteer from 'puppeteer-core';
import fs from 'node:fs';
import path from 'node:path';

const CHROMIUM = process.env.NSRM_CHROMIUM || '/usr/bin/chromium';
const PAGE = process.env.REPORT_HTML;
const OUT = process.env.REPORT_OUT;
if (!PAGE || !OUT) throw new Error('REPORT_HTML and REPORT_OUT must be set');
fs.mkdirSync(OUT, { recursive: true });

const pageUrl = 'file://' + path.resolve(PAGE);
const browser = await puppeteer.launch({
  executablePath: CHROMIUM,
  headless: true,
  args: ['--no-sandbox', '--window-size=1280,1000'],
});
const errors = [];
const requests = [];
try {
  const page = await browser.newPage();
  await page.setViewport({ width: 1280, height: 1000 });
  page.on('console', (m) => { if (m.type() === 'error') errors.push(m.text()); });
  page.on('pageerror', (e) => errors.push(String(e)));
  await page.setRequestInterception(true);
  page.on('request', (r) => {
    const u = r.url();
    if (u === pageUrl || u.startsWith('data:')) {
      r.continue();
    } else {
      requests.push(u);
      r.abort();
    }
  });
  await page.goto(pageUrl, { waitUntil: 'load' });
  const facts = await page.evaluate(() => {
    const img = document.querySelector('img.overlay');
    return {
      title: document.title,
      h1: document.querySelector('h1')?.textContent || '',
      overlayWidth: img ? img.naturalWidth : 0,
      svgs: document.querySelectorAll('svg').length,
      circles: document.querySelectorAll('#ramp + svg circle').length,
      rows: document.querySelectorAll('table.patches tr').length,
      diagnosis: document.querySelectorAll('ul.diagnosis li').length,
      scrollWidth: document.documentElement.scrollWidth,
      innerWidth: window.innerWidth,
    };
  });
  console.log('[report test]', JSON.stringify(facts));
  await page.screenshot({ path: path.join(OUT, 'report.png'), fullPage: true });
  if (!facts.h1.startsWith('Calibration of')) throw new Error(`no heading: ${facts.h1}`);
  if (!(facts.overlayWidth > 0)) throw new Error('the overlay image did not decode');
  if (facts.svgs < 3) throw new Error(`${facts.svgs} SVG plots, expected swatches, histogram, ramp`);
  if (facts.circles < 9) throw new Error(`the neutral ramp has ${facts.circles} points`);
  if (facts.rows < 2) throw new Error('no patch table');
  if (facts.diagnosis < 1) throw new Error('no diagnosis');
  if (facts.scrollWidth > facts.innerWidth) throw new Error(`horizontal scroll: ${facts.scrollWidth} > ${facts.innerWidth}`);
  if (requests.length) throw new Error(`requests left the page: ${requests.join(', ')}`);
  if (errors.length) throw new Error(`console errors: ${errors.join(' | ')}`);
  console.log('[report test] ok');
} finally {
  await browser.close();
}
