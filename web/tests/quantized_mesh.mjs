// An independent decoder of the server's quantized-mesh tiles: @loaders.gl/terrain's
// QuantizedMeshLoader (through @loaders.gl/core's `parse`) decodes /cesium/{z}/{x}/{y}.terrain
// tiles at several levels; its lower-level `decode` adds the edge index lists and the
// extensions it knows (vertex normals); the `metadata` extension, which loaders.gl skips, is
// read here. Prints one line of JSON with every tile's vertices, triangles and edges.
//
//   node web/tests/quantized_mesh.mjs http://127.0.0.1:PORT

import { existsSync } from 'node:fs';
import { dirname, join } from 'node:path';
import { fileURLToPath, pathToFileURL } from 'node:url';
import { args, missing, report } from './browser.mjs';

const { base } = args();
const modules = join(dirname(fileURLToPath(import.meta.url)), '..', 'node_modules');
let parse;
let QuantizedMeshLoader;
let decode;
try {
  ({ parse } = await import('@loaders.gl/core'));
  ({ QuantizedMeshLoader } = await import('@loaders.gl/terrain'));
  // Not in the package's exports: imported by path, for the edge lists and extensions.
  const lower = join(modules, '@loaders.gl/terrain/dist/lib/decode-quantized-mesh.js');
  if (!existsSync(lower)) throw new Error(`${lower} is missing`);
  ({ default: decode } = await import(pathToFileURL(lower).href));
} catch (e) {
  missing(`@loaders.gl/core and @loaders.gl/terrain are not installed (${e.message}).`);
}

/** What CesiumJS sends for tiles with both extensions. */
const WITH_EXTENSIONS = 'application/vnd.quantized-mesh;extensions=octvertexnormals-metadata,' +
  'application/octet-stream;q=0.9,*/*;q=0.01';
const PLAIN = 'application/vnd.quantized-mesh,application/octet-stream;q=0.9,*/*;q=0.01';

/** The extensions after the edge lists, by id: 1 normals, 2 water mask, 4 metadata. */
function extensions(buffer, start) {
  const view = new DataView(buffer);
  const out = {};
  let at = start;
  while (at < view.byteLength) {
    const id = view.getUint8(at);
    const length = view.getUint32(at + 1, true);
    at += 5;
    if (id === 4) {
      const n = view.getUint32(at, true);
      out.metadata = JSON.parse(new TextDecoder().decode(new Uint8Array(buffer, at + 4, n)));
    } else {
      out[`id${id}`] = length;
    }
    at += length;
  }
  return out;
}

/** The byte after the edge index lists (where the extensions start). */
function edgesEnd(buffer, vertexCount, triangleCount) {
  const bytes = vertexCount > 65536 ? 4 : 2;
  let at = 88 + 4 + vertexCount * 6;
  if (at % bytes) at += bytes - (at % bytes);
  at += 4 + triangleCount * 3 * bytes;
  const view = new DataView(buffer);
  for (let edge = 0; edge < 4; edge++) {
    at += 4 + view.getUint32(at, true) * bytes;
  }
  return at;
}

function tileBounds(z, x, y) {
  const size = 180 / 2 ** z;
  return [-180 + x * size, -90 + y * size, -180 + (x + 1) * size, -90 + (y + 1) * size];
}

async function tile(z, x, y, accept) {
  const url = `${base}/cesium/${z}/${x}/${y}.terrain`;
  const response = await fetch(url, { headers: { accept, 'accept-encoding': 'gzip' } });
  if (!response.ok) throw new Error(`${url} answered ${response.status}: ${await response.text()}`);
  const buffer = await response.arrayBuffer();
  // Both decoders undo the index coding in place: each gets its own copy.
  const pristine = buffer.slice(0);
  const bounds = tileBounds(z, x, y);
  const mesh = await parse(buffer.slice(0), QuantizedMeshLoader, {
    worker: false,
    'quantized-mesh': { bounds },
  });
  const position = mesh.attributes.POSITION.value;
  const texcoord = mesh.attributes.TEXCOORD_0.value;
  const n = position.length / 3;
  const full = decode(pristine.slice(0));
  const triangles = Array.from(mesh.indices.value);
  return {
    z,
    x,
    y,
    accept,
    content_type: response.headers.get('content-type'),
    content_encoding: response.headers.get('content-encoding'),
    etag: response.headers.get('etag'),
    cors: response.headers.get('access-control-allow-origin'),
    bytes: buffer.byteLength,
    bounds,
    header: full.header,
    vertex_count: n,
    triangle_count: triangles.length / 3,
    // Quantized u and v back from the loader's texture coordinates (u / 32767 in float32).
    u: Array.from(texcoord.filter((_, i) => i % 2 === 0), (t) => Math.round(t * 32767)),
    v: Array.from(texcoord.filter((_, i) => i % 2 === 1), (t) => Math.round(t * 32767)),
    lon: Array.from(position.filter((_, i) => i % 3 === 0)),
    lat: Array.from(position.filter((_, i) => i % 3 === 1)),
    height: Array.from(position.filter((_, i) => i % 3 === 2)),
    triangles,
    edges: {
      west: Array.from(full.westIndices),
      south: Array.from(full.southIndices),
      east: Array.from(full.eastIndices),
      north: Array.from(full.northIndices),
    },
    normals_bytes: full.extensions?.vertexNormals?.length ?? 0,
    extensions: extensions(pristine, edgesEnd(pristine, n, triangles.length / 3)),
  };
}

let result;
try {
  const layer = await (await fetch(`${base}/cesium/layer.json`)).json();
  const [w, s, e, n] = layer.bounds;
  const [lon, lat] = [(w + e) / 2, (s + n) / 2];
  const max = layer.maxzoom;
  const levels = [...new Set([0, 3, 6, 9, max - 1, max])].filter((z) => z >= 0 && z <= max);
  const tiles = [];
  for (const z of levels) {
    const x = Math.floor(((lon + 180) / 360) * 2 ** (z + 1));
    const y = Math.floor(((lat + 90) / 180) * 2 ** z);
    tiles.push(await tile(z, x, y, z === max ? WITH_EXTENSIONS : PLAIN));
  }
  // The corner of the deepest level's range: a tile partly outside the terrain.
  const corner = layer.available[max][0];
  tiles.push(await tile(max, corner.startX, corner.startY, WITH_EXTENSIONS));
  result = { ok: true, max_level: max, tiles };
} catch (e) {
  result = { ok: false, error: e.stack ?? String(e) };
}
report(result);
