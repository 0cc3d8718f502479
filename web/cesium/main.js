// Relief's CesiumJS page: the viewer over this server's terrain (/cesium/layer.json and its
// quantized-mesh tiles), Cesium's bundled NaturalEarthII imagery, and nothing that calls
// Cesium ion or any other host: no ion token, no ion imagery, no geocoder, no base layer picker.
//
// Query parameters: `duration` (seconds of the camera's flight to the terrain, default 2).
//
// For tests and scripts, `window.relief` holds:
// - `ready`: a promise that resolves once the camera has arrived and every tile in view
//   (terrain and imagery) has loaded, with { frames, ms }; it rejects with the reason if the
//   page cannot load (the error is also shown on the page);
// - `viewer`, `terrainProvider`, `terrain` (the server's /v1/terrain);
// - `sample(points)`: heights of CesiumJS's most detailed terrain at [lon, lat] points
//   (degrees), through `sampleTerrainMostDetailed`, in metres (null where it has none).
import { georeferencedTerrain, missingLibrary, pageState } from '/pages/common.js';

const status = document.getElementById('status');
const params = new URLSearchParams(location.search);
const duration = Number(params.get('duration') ?? 2);
const { relief, resolve: resolveReady, fail } = pageState(status);
const Cesium = window.Cesium;

async function start() {
  const started = performance.now();
  status.textContent = 'Loading the terrain...';
  const terrain = await georeferencedTerrain('globe');
  relief.terrain = terrain;
  const [west, south, east, north] = terrain.bounds_lonlat;

  // No ion: an empty token, so that nothing could authenticate to it even by mistake.
  Cesium.Ion.defaultAccessToken = '';
  const terrainProvider = await Cesium.CesiumTerrainProvider.fromUrl('/cesium/', {
    requestVertexNormals: true,
    requestMetadata: true,
  });
  relief.terrainProvider = terrainProvider;
  const imagery = Cesium.TileMapServiceImageryProvider.fromUrl(
    Cesium.buildModuleUrl('Assets/Textures/NaturalEarthII'));
  const viewer = new Cesium.Viewer('viewer', {
    terrainProvider,
    baseLayer: Cesium.ImageryLayer.fromProviderAsync(imagery),
    baseLayerPicker: false,
    geocoder: false,
    animation: false,
    timeline: false,
    homeButton: false,
    sceneModePicker: false,
    navigationHelpButton: false,
    fullscreenButton: false,
    infoBox: false,
    selectionIndicator: false,
  });
  relief.viewer = viewer;
  const scene = viewer.scene;
  // A fixed time, so that the sun (terrain lighting from the vertex normals) is the same on
  // every load: early morning over Japan, a low sun from the east that shades the slopes.
  viewer.clock.currentTime = Cesium.JulianDate.fromIso8601('2025-05-01T21:30:00Z');
  viewer.clock.shouldAnimate = false;
  scene.globe.enableLighting = true;
  scene.globe.depthTestAgainstTerrain = true;

  // Fly to the terrain's box: from the south-south-west, looking down 18 degrees, far enough
  // back for most of the box.
  const [hmin, hmax] = terrain.height_range_m ?? [0, 0];
  const rectangle = Cesium.Rectangle.fromDegrees(west, south, east, north);
  const sphere = Cesium.BoundingSphere.fromRectangle3D(
    rectangle, Cesium.Ellipsoid.WGS84, (hmin + hmax) / 2);
  await new Promise((resolve) => {
    viewer.camera.flyToBoundingSphere(sphere, {
      offset: new Cesium.HeadingPitchRange(
        Cesium.Math.toRadians(-30), Cesium.Math.toRadians(-18), sphere.radius * 1.5),
      duration,
      complete: resolve,
      cancel: resolve,
    });
  });

  // Tiles: done once the globe reports its load queue empty for a few frames in a row.
  status.textContent = 'Loading tiles...';
  const frames = await new Promise((resolve, reject) => {
    let quiet = 0;
    let count = 0;
    const deadline = performance.now() + 120000;
    const remove = scene.postRender.addEventListener(() => {
      count += 1;
      quiet = scene.globe.tilesLoaded ? quiet + 1 : 0;
      if (quiet >= 5) {
        remove();
        resolve(count);
      } else if (performance.now() > deadline) {
        remove();
        reject(new Error('the tiles did not finish loading within 120 s'));
      }
    });
  });
  status.textContent = '';
  resolveReady({ frames, ms: Math.round(performance.now() - started) });
}

relief.sample = async (points) => {
  const positions = points.map(([lon, lat]) => Cesium.Cartographic.fromDegrees(lon, lat));
  await Cesium.sampleTerrainMostDetailed(relief.terrainProvider, positions, true);
  return positions.map((p) => (Number.isFinite(p.height) ? p.height : null));
};

if (typeof Cesium === 'undefined') {
  fail(missingLibrary('CesiumJS', '/lib/cesium/', 'cesium'));
} else {
  start().catch((e) => fail(`The CesiumJS page failed: ${e.message ?? e}`));
}
