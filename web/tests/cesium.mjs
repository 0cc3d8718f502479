// The CesiumJS page in headless Chromium: loads GET /cesium/ from the server, waits until its
// tiles have loaded, takes a screenshot, samples the terrain with `sampleTerrainMostDetailed`
// at 200 points of the terrain's box, and prints one line of JSON: the points and heights, the
// page's request log, timings, and where the screenshot went.
//
//   node web/tests/cesium.mjs http://127.0.0.1:PORT [--screenshot out.png] [--points 200]

import { args, launch, points, report, within } from './browser.mjs';

const { base, options } = args();
const count = Number(options.points ?? 200);
const started = Date.now();
const browser = await launch({ width: 960, height: 600 });
const { page } = browser;
let result;
try {
  await page.goto(`${base}/cesium/?duration=0`);
  const ready = await within(150000, 'loading the CesiumJS page', page.evaluate(async () => {
    if (!window.relief) throw new Error('the page has no window.relief');
    return window.relief.ready;
  }));
  const loaded = Date.now() - started;
  if (options.screenshot) await page.screenshot({ path: options.screenshot });
  const terrain = await page.evaluate(() => window.relief.terrain);
  const pts = points(terrain.bounds_lonlat, count);
  const heights = await within(60000, 'sampling the terrain', page.evaluate(
    (p) => window.relief.sample(p), pts));
  result = {
    ok: true,
    ready,
    loaded_ms: loaded,
    total_ms: Date.now() - started,
    bounds: terrain.bounds_lonlat,
    points: pts,
    heights,
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
