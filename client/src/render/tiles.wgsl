// Relief's tile-stream shader (appended to `shade.wgsl`, which has the frame block, the vertex
// output and the fragment shader): each tile's triangles pulled from its own position and index
// buffers, three indices a triangle, so that the wireframe knows each corner. A tile that
// arrived as the child of a split morphs from its parent's mesh to its own over the growth
// duration (`tile_scene.rs`); its boundary, patches and skirts never move. Under the
// wireframe, patches and skirts are tinted red.

// Arrival time of each active tile (seconds on the frame's clock), by instance index.
@group(0) @binding(1) var<storage, read> arrivals: array<f32>;
// The tile's vertices, world metres: x, y, z, and z on the parent's mesh (the morph target).
@group(1) @binding(0) var<storage, read> positions: array<vec4<f32>>;
// The mesh's triangle count, then the tile's triangles' vertex indices: mesh, dropped
// patches, raised patches, skirts.
@group(1) @binding(1) var<storage, read> indices: array<u32>;
// The tile's smooth normals (`TileMesh::normals`): x, y of its own mesh's, then of the morph
// target's; z follows, as they point up.
@group(1) @binding(2) var<storage, read> normals: array<vec4<f32>>;

@vertex
fn vs_tile(@builtin(vertex_index) vi: u32, @builtin(instance_index) tile: u32) -> VOut {
    var o: VOut;
    let corner = vi % 3u;
    o.bary = vec3<f32>(f32(corner == 0u), f32(corner == 1u), f32(corner == 2u));
    o.crack = f32(vi / 3u >= indices[0]);
    let v = indices[vi + 1u];
    let q = positions[v];
    // alpha: 0 on arrival, 1 after the growth duration (1 at once without one).
    var alpha = 1.0;
    if (frame.morph.z > 0.0) {
        alpha = clamp((frame.eye.w - arrivals[tile]) / frame.morph.z, 0.0, 1.0);
    }
    let p = vec3<f32>(q.xy, mix(q.w, q.z, alpha));
    let rel = p - frame.eye.xyz;
    o.clip = frame.view_proj * vec4<f32>(rel, 1.0);
    o.rel = rel;
    o.height = p.z;
    // Morphed like the heights; patches and skirts shade flat (a zero normal).
    let nv = normals[v];
    let nxy = mix(nv.zw, nv.xy, alpha);
    o.normal = vec3<f32>(nxy, sqrt(max(1.0 - dot(nxy, nxy), 0.0))) * (1.0 - o.crack);
    return o;
}
