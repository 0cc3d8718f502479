// Relief's tile-stream shader (appended to `shade.wgsl`, which has the frame block, the vertex
// output and the fragment shader): each tile's triangles pulled from its own position and index
// buffers, three indices a triangle, so that the wireframe knows each corner. The tiles are
// drawn as they are: no geomorph. Under the wireframe, patches and skirts are tinted red.

// The tile's vertex positions, world metres, x y z after one another.
@group(1) @binding(0) var<storage, read> positions: array<f32>;
// The mesh's triangle count, then the tile's triangles' vertex indices: mesh, dropped
// patches, raised patches, skirts.
@group(1) @binding(1) var<storage, read> indices: array<u32>;

@vertex
fn vs_tile(@builtin(vertex_index) vi: u32) -> VOut {
    var o: VOut;
    let corner = vi % 3u;
    o.bary = vec3<f32>(f32(corner == 0u), f32(corner == 1u), f32(corner == 2u));
    o.crack = f32(vi / 3u >= indices[0]);
    let v = indices[vi + 1u] * 3u;
    let p = vec3<f32>(positions[v], positions[v + 1u], positions[v + 2u]);
    let rel = p - frame.eye.xyz;
    o.clip = frame.view_proj * vec4<f32>(rel, 1.0);
    o.rel = rel;
    o.height = p.z;
    return o;
}
