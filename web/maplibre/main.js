// Relief's MapLibre page: a map in terrain mode over this server's elevation tiles. The style
// has a background, a `raster-dem` source from the server's TileJSON (/tiles/terrain-rgb.json,
// or /tiles/terrarium.json with ?encoding=terrarium), a hillshade of the same DEM tiles (the
// imagery, made offline from the terrain itself) and `terrain: {source: 'dem', exaggeration:
// 1}`; the camera
// looks at the terrain's box pitched 60 degrees. MapLibre is loaded as an ES module from this
// server (/lib/maplibre-gl/), and nothing is fetched from any other host.
//
// For tests and scripts, `window.relief` holds:
// - `ready`: a promise that resolves once the style, the DEM tiles and the frame have loaded
//   (MapLibre's `idle`), with { ms }; it rejects with the reason if the page cannot load;
// - `map`, `encoding`, `terrain` (the server's /v1/terrain);
// - `jumpTo(options)`: moves the camera and resolves at the next `idle`;
// - `sample(points)`: at [lon, lat] points, MapLibre's `queryTerrainElevation` in metres and
//   the raster-dem tile whose pixels it read ({z, x, y}, or null where it read none).

import { georeferencedTerrain, missingLibrary, pageState } from '/pages/common.js';

const status = document.getElementById('status');
const params = new URLSearchParams(location.search);
const encoding = params.get('encoding') === 'terrarium' ? 'terrarium' : 'terrain-rgb';
const { relief, resolve: resolveReady, fail } = pageState(status, { encoding });

// Web Mercator world coordinates in [0, 1), as MapLibre's tiles count them.
function world(lon, lat) {
  const s = Math.sin((lat * Math.PI) / 180);
  return [(lon + 180) / 360, 0.5 - Math.log((1 + s) / (1 - s)) / (4 * Math.PI)];
}

// The raster-dem tile MapLibre's terrain reads at each point: the deepest rendered terrain
// tile over the point, and the DEM tile it is drawn with (its own or a loaded parent's), as
// MapLibre's own CPU sampler finds them. It reads MapLibre's internals; null if they moved.
function demTiles(map, points) {
  const manager = map.terrain?.tileManager;
  if (!manager?.getRenderableTiles || !manager.getSourceTile) return points.map(() => null);
  const byKey = new Map();
  const zooms = new Set();
  for (const tile of manager.getRenderableTiles()) {
    if (!tile) continue;
    const { canonical, wrap } = tile.tileID;
    const dem = manager.getSourceTile(tile.tileID, true);
    zooms.add(canonical.z);
    byKey.set(`${wrap}/${canonical.z}/${canonical.x}/${canonical.y}`,
      dem?.dem ? { z: dem.tileID.canonical.z, x: dem.tileID.canonical.x, y: dem.tileID.canonical.y } : null);
  }
  const deepest = [...zooms].sort((a, b) => b - a);
  return points.map(([lon, lat]) => {
    const [x, y] = world(lon, lat);
    for (const z of deepest) {
      const key = `0/${z}/${Math.floor(x * 2 ** z)}/${Math.floor(y * 2 ** z)}`;
      if (byKey.has(key)) return byKey.get(key);
    }
    return null;
  });
}

async function start() {
  const started = performance.now();
  let maplibregl;
  try {
    maplibregl = await import('/lib/maplibre-gl/maplibre-gl.mjs');
  } catch (e) {
    throw new Error(missingLibrary('MapLibre GL JS', '/lib/maplibre-gl/', 'maplibre-gl'));
  }
  status.textContent = 'Loading the terrain...';
  const terrain = await georeferencedTerrain('map');
  relief.terrain = terrain;
  const [west, south, east, north] = terrain.bounds_lonlat;

  const map = new maplibregl.Map({
    container: 'map',
    style: {
      version: 8,
      // The same tiles twice: MapLibre draws terrain and hillshade better from separate
      // sources (it says so in the console otherwise).
      sources: {
        dem: { type: 'raster-dem', url: `/tiles/${encoding}.json` },
        shade: { type: 'raster-dem', url: `/tiles/${encoding}.json` },
      },
      layers: [
        { id: 'background', type: 'background', paint: { 'background-color': '#e8e4d8' } },
        {
          id: 'hillshade',
          type: 'hillshade',
          source: 'shade',
          paint: {
            'hillshade-exaggeration': 0.7,
            'hillshade-shadow-color': '#3d3526',
            'hillshade-highlight-color': '#fffdf5',
            'hillshade-accent-color': '#6b5d45',
          },
        },
      ],
      terrain: { source: 'dem', exaggeration: 1 },
    },
    center: [(west + east) / 2, (south + north) / 2],
    zoom: 10,
    maxPitch: 85,
  });
  relief.map = map;
  // Centred on the terrain's box, close enough for it to fill most of the view once pitched
  // 60 degrees, looking north-north-east.
  const fit = map.cameraForBounds([[west, south], [east, north]], { padding: 20 });
  map.jumpTo({ ...fit, zoom: fit.zoom + 0.5, pitch: 60, bearing: -20 });
  // `idle` comes once the style, the tiles in view and the frame are done; MapLibre may fire
  // it in the same frame as `load`, so the listener goes on now, not after `load`.
  const idle = new Promise((resolve) => map.once('idle', resolve));
  map.on('error', (e) => {
    // Tiles outside the terrain are 404s by design; anything else is worth seeing.
    console.warn('maplibre:', e.error?.message ?? e);
  });
  await idle;
  status.textContent = '';
  resolveReady({ ms: Math.round(performance.now() - started) });
}

relief.jumpTo = (options) => new Promise((resolve) => {
  relief.map.once('idle', resolve);
  relief.map.jumpTo(options);
});

relief.sample = (points) => {
  const map = relief.map;
  const dem = demTiles(map, points);
  return points.map(([lon, lat], i) => ({
    elevation: map.queryTerrainElevation([lon, lat]),
    dem: dem[i],
  }));
};

start().catch((e) => fail(`The MapLibre page failed: ${e.message ?? e}`));
