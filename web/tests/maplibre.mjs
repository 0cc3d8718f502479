// The MapLibre page in headless Chromium: loads GET /maplibre/?encoding=... from the server,
// waits until it is idle with its DEM tiles loaded, takes a screenshot of the pitched terrain
// view, then looks straight down (so that every point is drawn), at the whole terrain box and
// close up, and in each view reads `queryTerrainElevation` at 200 points with the raster-dem
// tile each one was read from. Prints one line of JSON.
//
//   node web/tests/maplibre.mjs http://127.0.0.1:PORT [--encoding terrain-rgb|terrarium]
//        [--screenshot out.png] [--points 200]

import { args, points, runPage, within } from './browser.mjs';

const { base, options } = args();
const encoding = options.encoding ?? 'terrain-rgb';
const count = Number(options.points ?? 200);
const path = `/maplibre/?encoding=${encoding}`;
await runPage(base, path, 120000, 'loading the MapLibre page', async (page) => {
  if (options.screenshot) await page.screenshot({ path: options.screenshot });
  const terrain = await page.evaluate(() => window.relief.terrain);
  const tilejson = await page.evaluate(() => {
    const source = window.relief.map.getSource('dem');
    return { encoding: source.encoding, maxzoom: source.maxzoom, tileSize: source.tileSize };
  });
  // Two views straight down, so that every point is on a drawn tile: the whole box (coarser
  // DEM tiles), and close up over its middle (the deepest DEM tiles), `count` points each,
  // spread over the part of the box in view.
  const views = [];
  for (const close of [false, true]) {
    const view = await within(60000, 'a measuring view', page.evaluate(async ([box, close]) => {
      const [w, s, e, n] = box;
      const map = window.relief.map;
      const camera = close
        // MapLibre's terrain reads DEM tiles about two zooms under the map's zoom.
        ? { center: [(w + e) / 2, (s + n) / 2], zoom: map.getSource('dem').maxzoom + 2.3 }
        : map.cameraForBounds([[w, s], [e, n]], { padding: 20 });
      await window.relief.jumpTo({ ...camera, pitch: 0, bearing: 0 });
      const b = map.getBounds();
      return {
        zoom: map.getZoom(),
        bounds: [Math.max(w, b.getWest()), Math.max(s, b.getSouth()),
          Math.min(e, b.getEast()), Math.min(n, b.getNorth())],
      };
    }, [terrain.bounds_lonlat, close]));
    const pts = points(view.bounds, count);
    const samples = await page.evaluate((p) => window.relief.sample(p), pts);
    views.push({ name: close ? 'close' : 'whole', ...view, points: pts, samples });
  }
  return {
    encoding,
    bounds: terrain.bounds_lonlat,
    source: tilejson,
    views,
    screenshot: options.screenshot ?? null,
  };
});
