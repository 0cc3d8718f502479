// What Relief's pages share (served at /pages/common.js): the `window.relief` object tests wait
// on, failing with a message a person can read, the server's terrain, and the message for a
// library that is not installed.

/// Creates `window.relief` with a `ready` promise and `error`, plus `extra` fields; returns it
/// with `resolve` (the page is ready) and `fail(message)` (shown on the `status` element, kept in
/// `relief.error`, and rejecting `ready`).
export function pageState(status, extra = {}) {
  let resolve;
  let reject;
  const relief = {
    ready: new Promise((ok, no) => {
      resolve = ok;
      reject = no;
    }),
    error: null,
    ...extra,
  };
  window.relief = relief;
  // A test waits on the promise; a person reads the message.
  relief.ready.catch(() => {});
  const fail = (message) => {
    relief.error = message;
    status.textContent = message;
    status.className = 'error';
    reject(new Error(message));
  };
  return { relief, resolve, fail };
}

/// The server's `/v1/terrain`, which must be georeferenced for `place` (the globe, the map).
export async function georeferencedTerrain(place) {
  const response = await fetch('/v1/terrain');
  if (!response.ok) {
    throw new Error(`/v1/terrain answered ${response.status}: ${await response.text()}`);
  }
  const terrain = await response.json();
  if (!terrain.bounds_lonlat) {
    throw new Error(`this terrain has no georeference, so it has no place on the ${place} ` +
      '(build it from a georeferenced DEM, or with --origin LON,LAT)');
  }
  return terrain;
}

/// What to do when library `name` (npm package `pkg`) did not load from `url`.
export function missingLibrary(name, url, pkg) {
  return `${name} did not load from ${url}. Install the pages' libraries: from the ` +
    'repository, run `npm ci --prefix web` (or start the server with --web-lib pointing at a ' +
    `node_modules folder holding ${pkg}), then reload.`;
}
