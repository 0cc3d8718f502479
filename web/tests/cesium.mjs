// The CesiumJS page in headless Chromium: loads GET /cesium/ from the server, waits until its
// tiles have loaded, takes a screenshot, samples the terrain with `sampleTerrainMostDetailed`
// at 200 points of the terrain's box, and prints one line of JSON: the points and heights, the
// page's request log, timings, and where the screenshot went.
//
//   node web/tests/cesium.mjs http://127.0.0.1:PORT [--screenshot out.png] [--points 200]

import { args, points, runPage, within } from './browser.mjs';

const { base, options } = args();
const count = Number(options.points ?? 200);
await runPage(base, '/cesium/?duration=0', 150000, 'loading the CesiumJS page', async (page) => {
  if (options.screenshot) await page.screenshot({ path: options.screenshot });
  const terrain = await page.evaluate(() => window.relief.terrain);
  const pts = points(terrain.bounds_lonlat, count);
  const heights = await within(60000, 'sampling the terrain', page.evaluate(
    (p) => window.relief.sample(p), pts));
  return {
    bounds: terrain.bounds_lonlat,
    points: pts,
    heights,
    screenshot: options.screenshot ?? null,
  };
});
