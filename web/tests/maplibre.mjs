// The MapLibre page in headless Chromium: loads GET /maplibre/?encoding=... from the server,
// waits until it is idle with its DEM tiles loaded, takes a screenshot of the pitched terrain
// view, then looks straight down at the whole terrain box (so that every point is drawn) and
// reads `queryTerrainElevation` at 200 points with the raster-dem tile each one was read from.
// Prints one line of JSON.
//
//   node web/tests/maplibre.mjs http://127.0.0.1:PORT [--encoding terrain-rgb|terrarium]
//        [--screenshot out.png] [--points 200]

import { args, launch, points, report, within } from './browser.mjs';

const { base, options } = args();
const encoding = options.encoding ?? 'terrain-rgb';
const count = Number(options.points ?? 200);
const started = Date.now();
const browser = await launch({ width: 960, height: 600 });
const { page } = browser;
let result;
try {
  await page.goto(`${base}/maplibre/?encoding=${encoding}`);
  const ready = await within(120000, 'loading the MapLibre page', page.evaluate(async () => {
    if (!window.relief) throw new Error('the page has no window.relief');
    return window.relief.ready;
  }));
  const loaded = Date.now() - started;
  if (options.screenshot) await page.screenshot({ path: options.screenshot });
  const terrain = await page.evaluate(() => window.relief.terrain);
  const tilejson = await page.evaluate(() => {
    const source = window.relief.map.getSource('dem');
    return { encoding: source.encoding, maxzoom: source.maxzoom, tileSize: source.tileSize };
  });
  // Straight down over the whole box: every point is on a drawn tile.
  await within(60000, 'the measuring view', page.evaluate(([w, s, e, n]) => {
    const map = window.relief.map;
    const camera = map.cameraForBounds([[w, s], [e, n]], { padding: 20 });
    return window.relief.jumpTo({ ...camera, pitch: 0, bearing: 0 });
  }, terrain.bounds_lonlat));
  const pts = points(terrain.bounds_lonlat, count);
  const samples = await page.evaluate((p) => window.relief.sample(p), pts);
  const zoom = await page.evaluate(() => window.relief.map.getZoom());
  result = {
    ok: true,
    encoding,
    ready,
    loaded_ms: loaded,
    total_ms: Date.now() - started,
    bounds: terrain.bounds_lonlat,
    source: tilejson,
    zoom,
    points: pts,
    samples,
    requests: browser.requests,
    console: browser.console,
    screenshot: options.screenshot ?? null,
  };
} catch (e) {
  const error = await page.evaluate(() => window.relief?.error).catch(() => null);
  result = {
    ok: false,
    error: `${e.message}${error ? ` (the page says: ${error})` : ''}`,
    requests: browser.requests,
    console: browser.console,
  };
} finally {
  await browser.close();
}
report(result);
