#!/usr/bin/env node
// Loads a 3D Tiles tileset in CesiumJS (npm `cesium`) inside headless Chromium (driven by
// `puppeteer-core`), from a static HTTP server on 127.0.0.1 that this script runs: no network,
// no Ion token, no imagery or terrain (ellipsoid only). For each view it moves the camera, waits
// until every tile the view needs has loaded, records which tiles loaded, which were drawn and
// which failed, and saves a screenshot.
//
// Usage: node cesium_tileset.mjs SPEC.json
// SPEC: { "chromium": "/usr/bin/chromium", "tileset_dir": DIR, "out_dir": DIR,
//         "tileset_url": URL (optional: the tileset.json of another server, e.g. `blockwalk
//         serve` on a .3tz, loaded instead of the one in tileset_dir), "prefix": "" (optional:
//         the screenshots' name prefix),
//         "width": 480, "height": 270, "maximum_screen_space_error": 16,
//         "sky": [r, g, b], "ground": [r, g, b], "sun_local": [x, y, z],
//         "views": [{ "name": "far", "eye": [x, y, z], "target": [x, y, z], "fov_y_deg": 60 }] }
// Eye and target are in the tileset's local frame (x east, y north, z up, metres), placed on the
// globe through the root tile's transform (or, for a tileset whose root groups the buildings'
// tree and an external terrain tileset, `extras.kind` "group", through its first child's).
// Tiles are named `kind:node_key` from their `extras` (explicit tiles) or their tile metadata
// (implicit tiles: properties `kind` and `node_key`), `?` when they carry neither (the implicit
// root as tileset.json writes it). Every response under the tileset's folder URL is recorded
// (`requests.tileset_files`, relative paths; `requests.missing`, those answered 404 or worse).
// Prints one JSON report on stdout; exit status 0 when the script ran (the caller judges the
// report), 2 when it could not run.
import fs from 'node:fs';
import http from 'node:http';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import puppeteer from 'puppeteer-core';

const here = path.dirname(fileURLToPath(import.meta.url));
const cesiumDir = path.join(here, 'node_modules', 'cesium', 'Build', 'Cesium');

function fail(msg) {
  console.error(msg);
  process.exit(2);
}

const specPath = process.argv[2];
if (!specPath) fail('usage: cesium_tileset.mjs SPEC.json');
const spec = JSON.parse(fs.readFileSync(specPath, 'utf8'));
if (!fs.existsSync(path.join(cesiumDir, 'Cesium.js'))) fail(`CesiumJS not found in ${cesiumDir}`);

const page = `<!doctype html>
<html><head><meta charset="utf-8">
<script>window.CESIUM_BASE_URL = '/cesium/';</script>
<script src="/cesium/Cesium.js"></script>
<link href="/cesium/Widgets/widgets.css" rel="stylesheet">
<style>html, body, #c { margin: 0; width: 100%; height: 100%; overflow: hidden; }</style>
</head><body><div id="c"></div></body></html>`;

const types = {
  '.js': 'text/javascript', '.mjs': 'text/javascript', '.json': 'application/json',
  '.css': 'text/css', '.glb': 'model/gltf-binary', '.wasm': 'application/wasm',
  '.png': 'image/png', '.jpg': 'image/jpeg', '.svg': 'image/svg+xml', '.html': 'text/html',
};
const requests = { served: 0, missing: [], tileset_files: [] };
function serveFile(res, root, rel) {
  const file = path.normalize(path.join(root, rel));
  if (!file.startsWith(root)) {
    res.writeHead(403).end();
    return;
  }
  fs.readFile(file, (err, data) => {
    if (err) {
      requests.missing.push(rel);
      res.writeHead(404).end();
      return;
    }
    requests.served += 1;
    res.writeHead(200, { 'Content-Type': types[path.extname(file)] || 'application/octet-stream' });
    res.end(data);
  });
}
const tilesetRoot = path.resolve(spec.tileset_dir);
const server = http.createServer((req, res) => {
  const url = decodeURIComponent(new URL(req.url, 'http://x').pathname);
  if (url === '/' || url === '/index.html') {
    res.writeHead(200, { 'Content-Type': 'text/html' }).end(page);
  } else if (url.startsWith('/cesium/')) {
    serveFile(res, cesiumDir, url.slice('/cesium/'.length));
  } else if (url.startsWith('/tileset/')) {
    requests.tileset_files.push(url.slice('/tileset/'.length));
    serveFile(res, tilesetRoot, url.slice('/tileset/'.length));
  } else {
    requests.missing.push(url);
    res.writeHead(404).end();
  }
});
await new Promise((ok) => server.listen(0, '127.0.0.1', ok));
const port = server.address().port;

const browser = await puppeteer.launch({
  executablePath: spec.chromium,
  headless: true,
  args: [
    '--no-sandbox',
    '--use-angle=swiftshader',
    '--enable-unsafe-swiftshader',
    '--ignore-gpu-blocklist',
    '--disable-dev-shm-usage',
    `--window-size=${spec.width},${spec.height}`,
  ],
});
const report = { port, console: [], page_errors: [], views: [] };
try {
  const tab = await browser.newPage();
  await tab.setViewport({ width: spec.width, height: spec.height });
  tab.on('console', (m) => report.console.push(`${m.type()}: ${m.text()}`));
  tab.on('pageerror', (e) => report.page_errors.push(String(e)));
  // Responses of another server (the tileset_url's): recorded as the local server records its own.
  const remoteBase = spec.tileset_url ? new URL('.', spec.tileset_url).href : null;
  if (remoteBase) {
    // Requests issued and not finished (their URLs), for a report of a view that never loads.
    requests.pending = {};
    tab.on('request', (r) => {
      if (r.url().startsWith(remoteBase)) {
        requests.issued = (requests.issued || 0) + 1;
        requests.pending[r.url()] = true;
      }
    });
    tab.on('requestfinished', (r) => delete requests.pending[r.url()]);
    tab.on('requestfailed', (r) => {
      if (r.url().startsWith(remoteBase)) {
        (requests.failed = requests.failed || []).push(`${r.url()}: ${r.failure() && r.failure().errorText}`);
      }
    });
    tab.on('response', (r) => {
      if (!r.url().startsWith(remoteBase)) return;
      const rel = decodeURIComponent(r.url().slice(remoteBase.length).split(/[?#]/)[0]);
      requests.tileset_files.push(rel);
      if (r.status() >= 400) requests.missing.push(rel);
      else requests.served += 1;
    });
  }
  tab.on('request', (r) => {
    const u = new URL(r.url());
    if (u.hostname !== '127.0.0.1' && u.protocol !== 'data:' && u.protocol !== 'blob:') {
      report.page_errors.push(`request outside the test server: ${r.url()}`);
    }
  });
  await tab.goto(`http://127.0.0.1:${port}/index.html`, { waitUntil: 'load' });
  report.setup = await tab.evaluate(async (spec) => {
    const C = window.Cesium;
    const viewer = new C.Viewer('c', {
      baseLayer: false,
      terrainProvider: new C.EllipsoidTerrainProvider(),
      animation: false, timeline: false, baseLayerPicker: false, geocoder: false,
      homeButton: false, sceneModePicker: false, navigationHelpButton: false,
      fullscreenButton: false, infoBox: false, selectionIndicator: false,
      skyBox: false, skyAtmosphere: false, shouldAnimate: false,
      contextOptions: { webgl: { preserveDrawingBuffer: true } },
    });
    viewer.cesiumWidget.creditContainer.style.display = 'none';
    const scene = viewer.scene;
    const rgb = (c) => C.Color.fromBytes(c[0], c[1], c[2], 255);
    scene.backgroundColor = rgb(spec.sky);
    scene.globe.baseColor = rgb(spec.ground);
    scene.globe.showGroundAtmosphere = false;
    scene.globe.enableLighting = false;
    scene.fog.enabled = false;
    if (scene.sun) scene.sun.show = false;
    if (scene.moon) scene.moon.show = false;
    const tileset = await C.Cesium3DTileset.fromUrl(spec.tileset_url || '/tileset/tileset.json', {
      maximumScreenSpaceError: spec.maximum_screen_space_error,
    });
    scene.primitives.add(tileset);
    const group = tileset.root.extras && tileset.root.extras.kind === 'group';
    // The local frame: the spec's transform when the root has none of its own (a root over
    // external tilesets, each placed by its own), else the root's (or the group's first child's).
    const t = spec.local_to_ecef
      ? C.Matrix4.fromArray(spec.local_to_ecef)
      : (group ? tileset.root.children[0] : tileset.root).computedTransform;
    const toWorld = (p) => C.Matrix4.multiplyByPoint(t, new C.Cartesian3(p[0], p[1], p[2]), new C.Cartesian3());
    const dirToWorld = (d) => C.Cartesian3.normalize(
      C.Matrix4.multiplyByPointAsVector(t, new C.Cartesian3(d[0], d[1], d[2]), new C.Cartesian3()),
      new C.Cartesian3());
    // The sun of our own renderer: the light travels against the direction to the sun.
    const s = spec.sun_local;
    scene.light = new C.DirectionalLight({ direction: dirToWorld([-s[0], -s[1], -s[2]]), intensity: 2.0 });
    window.bw = { C, viewer, tileset, toWorld, dirToWorld, failed: [], loaded: [], visible: [] };
    tileset.tileFailed.addEventListener((e) => window.bw.failed.push(`${e.url}: ${e.message}`));
    const label = (tile) => {
      if (tile.extras && tile.extras.kind) return tile.extras.kind + ':' + tile.extras.node_key;
      const m = tile.metadata;
      if (m && typeof m.hasProperty === 'function' && m.hasProperty('kind')) {
        return m.getProperty('kind') + ':' + String(m.getProperty('node_key'));
      }
      return '?';
    };
    tileset.tileLoad.addEventListener((tile) => window.bw.loaded.push(label(tile)));
    tileset.tileVisible.addEventListener((tile) => window.bw.visible.push(label(tile)));
    const cart = C.Cartographic.fromCartesian(toWorld([0, 0, 0]));
    return {
      cesium: C.VERSION,
      webgl2: scene.context.webgl2,
      origin_lon_deg: C.Math.toDegrees(cart.longitude),
      origin_lat_deg: C.Math.toDegrees(cart.latitude),
      origin_height_m: cart.height,
    };
  }, spec);

  for (const view of spec.views) {
    const result = await tab.evaluate(async (view, spec) => {
      const { C, viewer, tileset, toWorld } = window.bw;
      const camera = viewer.camera;
      const eye = toWorld(view.eye);
      const target = toWorld(view.target);
      const direction = C.Cartesian3.normalize(C.Cartesian3.subtract(target, eye, new C.Cartesian3()), new C.Cartesian3());
      // Up: the local z made orthogonal to the direction.
      const zUp = window.bw.dirToWorld([0, 0, 1]);
      const right = C.Cartesian3.normalize(C.Cartesian3.cross(direction, zUp, new C.Cartesian3()), new C.Cartesian3());
      const up = C.Cartesian3.cross(right, direction, new C.Cartesian3());
      camera.setView({ destination: eye, orientation: { direction, up } });
      // Cesium's fov is the horizontal one on a landscape canvas.
      const aspect = spec.width / spec.height;
      const fovY = C.Math.toRadians(view.fov_y_deg);
      camera.frustum.fov = aspect >= 1 ? 2 * Math.atan(Math.tan(fovY / 2) * aspect) : fovY;
      camera.frustum.near = 1.0;
      window.bw.loaded.length = 0;
      window.bw.failed.length = 0;
      const t0 = performance.now();
      // Render until every tile this view needs is loaded and a few frames have passed.
      let settled = 0;
      while (performance.now() - t0 < view.timeout_ms) {
        viewer.scene.render();
        await new Promise((r) => setTimeout(r, 50));
        settled = tileset.tilesLoaded ? settled + 1 : 0;
        if (settled >= 5) break;
      }
      window.bw.visible.length = 0;
      viewer.scene.render();
      const visible = window.bw.visible.slice();
      const stats = tileset.statistics;
      return {
        name: view.name,
        tiles_loaded: tileset.tilesLoaded,
        seconds: (performance.now() - t0) / 1000,
        loaded: window.bw.loaded.slice(),
        visible,
        failed: window.bw.failed.slice(),
        selected: stats.selected,
        triangles: stats.numberOfTrianglesSelected,
        pending_requests: stats.numberOfPendingRequests,
        processing: stats.numberOfTilesProcessing,
        attempted: stats.numberOfAttemptedRequests,
      };
    }, { ...view, timeout_ms: view.timeout_ms || 60000 }, spec);
    const shot = path.join(spec.out_dir, `${spec.prefix || ''}cesium_${view.name}.png`);
    await tab.screenshot({ path: shot });
    result.screenshot = shot;
    report.views.push(result);
  }
} catch (e) {
  report.page_errors.push(`script: ${e && e.stack ? e.stack : e}`);
} finally {
  await browser.close();
  server.close();
}
report.requests = requests;
process.stdout.write(JSON.stringify(report, null, 2) + '\n');
