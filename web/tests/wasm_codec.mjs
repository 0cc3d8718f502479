// The page's WebAssembly (web/page/pkg/) against vectors a Rust test recorded from a real tile
// session: builds the same hello, poses and acks, applies the recorded server messages in a
// TileSession, and prints, per message, what it decoded: kind, digest, tiles removed, added
// and evicted, which added tiles morph in, and each added tile's geometry (counts, the sums of the
// positions' and normals' bit patterns and of the indices), for
// the Rust test to compare with relief-proto's own answers. Runs in Node.js, no browser.
//
//   node web/tests/wasm_codec.mjs VECTORS.json

import { readFileSync } from 'node:fs';
import { dirname, join } from 'node:path';
import { fileURLToPath } from 'node:url';

const pkg = join(dirname(fileURLToPath(import.meta.url)), '../page/pkg');
const wasm = await import(join(pkg, 'relief_wasm.js'));
await wasm.default({ module_or_path: readFileSync(join(pkg, 'relief_wasm_bg.wasm')) });

const v = JSON.parse(readFileSync(process.argv[2], 'utf8'));
const hex = (bytes) => Buffer.from(bytes).toString('hex');
const s = new wasm.TileSession(v.lens[0], v.lens[1], v.lens[2], v.lens[3], v.tau, 'tiles', v.crack, v.cache);
const out = { ok: true, hello: hex(s.hello()), poses: [], acks: [], messages: [] };
for (const p of v.poses) out.poses.push(hex(s.pose(...p)));
for (const frame of v.frames) {
  const entry = {};
  try {
    entry.kind = s.receive(Buffer.from(frame, 'hex'), 0);
  } catch (e) {
    entry.error = String(e.message ?? e);
    out.messages.push(entry);
    continue;
  }
  entry.digest = s.digest;
  entry.removed = Array.from(s.removed());
  entry.added = Array.from(s.added());
  entry.evicted = Array.from(s.evicted());
  entry.split = Array.from(s.split_added());
  // The sum of an array's f32 bit patterns: exact, and any bit off shows.
  const bits = (a) => new Uint32Array(a.buffer, a.byteOffset, a.length).reduce((x, y) => x + y, 0);
  entry.geometry = entry.added.map((i) => {
    const g = s.geometry(i);
    const p = g.positions();
    const n = g.normals();
    const ix = g.indices();
    const r = {
      positions: p.length, normals: n.length, indices: ix.length, mesh: g.mesh_triangles,
      position_bits: bits(p), normal_bits: bits(n),
      index_sum: ix.reduce((a, x) => a + x, 0),
    };
    g.free();
    return r;
  });
  out.acks.push(hex(s.ack()));
  out.messages.push(entry);
}
out.resume_hello = hex(s.hello());
process.stdout.write(`${JSON.stringify(out)}\n`);
