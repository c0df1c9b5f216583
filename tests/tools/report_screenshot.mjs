#!/usr/bin/env node
// Opens a walk's report.html from a file:// URL in headless Chromium (driven by
// `puppeteer-core`), with the network cut off, and reports what a reader's browser would meet:
// console messages, page errors, failed requests, every <img> and whether it decoded, every
// inline <svg>, and a full-page screenshot.
//
// Usage: node report_screenshot.mjs SPEC.json
// SPEC: { "chromium": "/usr/bin/chromium", "html": FILE, "screenshot": FILE.png, "width": 1280 }
// Prints one JSON report on stdout; exit status 0 when the script ran (the caller judges the
// report), 2 when it could not run.
import fs from 'node:fs';
import path from 'node:path';
import { pathToFileURL } from 'node:url';
import puppeteer from 'puppeteer-core';

function fail(msg) {
  console.error(msg);
  process.exit(2);
}

const specPath = process.argv[2];
if (!specPath) fail('usage: report_screenshot.mjs SPEC.json');
const spec = JSON.parse(fs.readFileSync(specPath, 'utf8'));
if (!fs.existsSync(spec.html)) fail(`${spec.html}: no such file`);
const width = spec.width || 1280;

const browser = await puppeteer.launch({
  executablePath: spec.chromium,
  headless: true,
  args: ['--no-sandbox', '--disable-dev-shm-usage', `--window-size=${width},900`],
});
const report = { console: [], page_errors: [], requests: [], failed_requests: [] };
try {
  const tab = await browser.newPage();
  await tab.setViewport({ width, height: 900 });
  tab.on('console', (m) => report.console.push({ type: m.type(), text: m.text() }));
  tab.on('pageerror', (e) => report.page_errors.push(String(e)));
  tab.on('request', (r) => report.requests.push(r.url().slice(0, 64)));
  tab.on('requestfailed', (r) =>
    report.failed_requests.push(`${r.url().slice(0, 120)}: ${r.failure()?.errorText}`));
  // Nothing outside the page may be needed: refuse every request but the page itself and data:.
  await tab.setRequestInterception(true);
  const pageUrl = pathToFileURL(path.resolve(spec.html)).href;
  tab.on('request', (r) => {
    const u = r.url();
    if (u === pageUrl || u.startsWith('data:')) r.continue();
    else r.abort('blockedbyclient');
  });
  await tab.goto(pageUrl, { waitUntil: 'load', timeout: 20000 });
  report.title = await tab.title();
  report.images = await tab.$$eval('img', (imgs) =>
    imgs.map((i) => ({
      alt: i.alt,
      complete: i.complete,
      natural_width: i.naturalWidth,
      natural_height: i.naturalHeight,
      data_url: i.src.startsWith('data:'),
    })));
  report.svgs = await tab.$$eval('svg', (s) =>
    s.map((e) => ({ width: e.getBoundingClientRect().width, paths: e.querySelectorAll('path').length })));
  report.captions = await tab.$$eval('figcaption', (c) => c.map((e) => e.innerText.split('\n')[0]));
  report.body_height = await tab.evaluate(() => document.body.scrollHeight);
  if (spec.screenshot) {
    fs.mkdirSync(path.dirname(spec.screenshot), { recursive: true });
    await tab.screenshot({ path: spec.screenshot, fullPage: true });
    report.screenshot = spec.screenshot;
  }
} catch (e) {
  report.page_errors.push(`script: ${e}`);
} finally {
  await browser.close();
}
console.log(JSON.stringify(report));
