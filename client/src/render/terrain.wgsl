// Relief's vertex-stream shaders: vertex pulling with the geomorph (vertex) and the same
// geomorph written out for tests (compute); `shade.wgsl` (prepended) has the frame block and the
// shading. The records are written by `scene.rs`; the morph is the formula of
// `relief_proto::mesh::morph`, which is its reference (paper 000, section 3.6).

const NONE: u32 = 0xffffffffu;

struct Node {
    // Position at rest, world metres.
    pos: vec3<f32>,
    // The parent's slot; NONE for the root.
    parent: u32,
    // The box of the node's screen error.
    box_min: vec3<f32>,
    // Static error, metres (0 until the node has split).
    err: f32,
    box_max: vec3<f32>,
    // When the client applied the node's split, seconds.
    t_split: f32,
};

@group(0) @binding(1) var<storage, read> nodes: array<Node>;
@group(1) @binding(0) var<storage, read_write> drawn_out: array<vec4<f32>>;
@group(2) @binding(0) var<storage, read> cells: array<u32>;
@group(2) @binding(1) var<storage, read> drawn: array<vec4<f32>>;
// Smooth normals, 4 words per node slot: the sum of the unit normals of the drawn triangles
// around the node, in units of 1/NORMAL_SCALE (written by `normals`, read by `vs_pre`).
@group(1) @binding(1) var<storage, read_write> normal_sums: array<atomic<i32>>;
@group(2) @binding(2) var<storage, read> normals: array<i32>;

const NORMAL_SCALE: f32 = 1024.0;

// Screen error of a box (relief_proto::view::ViewState::error_of).
fn screen_error(b0: vec3<f32>, b1: vec3<f32>, err: f32) -> f32 {
    if (err <= 0.0) {
        return 0.0;
    }
    let rel_min = b0 - frame.eye.xyz;
    let rel_max = b1 - frame.eye.xyz;
    var margin = 3.0e38;
    for (var i = 0u; i < 5u; i++) {
        let n = frame.planes[i].xyz;
        let p = select(rel_min, rel_max, n >= vec3<f32>(0.0));
        margin = min(margin, dot(n, p) - frame.planes[i].w);
    }
    if (margin < 0.0) {
        return 0.0;
    }
    let f = frame.forward.xyz;
    let near_corner = select(rel_max, rel_min, f >= vec3<f32>(0.0));
    let far = max(abs(rel_min), abs(rel_max));
    let depth = max(dot(f, near_corner), frame.misc.x);
    let r_max = sqrt(far.x * far.x + far.y * far.y);
    return frame.forward.w * err * min(r_max / depth, frame.morph.w) / depth;
}

// Alpha of the children of `p` (MorphRule::alpha).
fn alpha(p: Node) -> f32 {
    let tau = frame.morph.x;
    let e = screen_error(p.box_min, p.box_max, p.err);
    var a = clamp((e - tau) / ((frame.morph.y - 1.0) * tau), 0.0, 1.0);
    if (frame.morph.z > 0.0) {
        a = min(a, clamp((frame.eye.w - p.t_split) / frame.morph.z, 0.0, 1.0));
    }
    return a;
}

// Where node `i` is drawn this frame: D(n) = D(p) + alpha(p) (P(n) - D(p)), walked upwards
// from the node, stopping at the first ancestor whose alpha is 1.
fn drawn_position(i: u32) -> vec3<f32> {
    var cur = i;
    var out = vec3<f32>(0.0);
    var w = 1.0;
    for (var k = 0u; k < 64u; k++) {
        let n = nodes[cur];
        if (n.parent == NONE) {
            out += w * n.pos;
            break;
        }
        let a = alpha(nodes[n.parent]);
        out += (w * a) * n.pos;
        w *= 1.0 - a;
        if (w <= 0.0) {
            break;
        }
        cur = n.parent;
    }
    return out;
}

// The same positions for every node slot, written out once per frame: `vs_pre` reads them
// (each node is shared by about six triangle corners), and tests read them back.
@compute @workgroup_size(64)
fn morph(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = id.x + id.y * groups.x * 64u;
    if (i >= arrayLength(&nodes)) {
        return;
    }
    drawn_out[i] = vec4<f32>(drawn_position(i), 1.0);
}

// Smooth per-vertex normals of the drawn (geomorphed) mesh: each triangle adds its upward unit
// normal to its three corners' sums (fixed point, for integer atomics). Runs after `morph`,
// over every triangle slot; the buffer is cleared before.
@compute @workgroup_size(64)
fn normals_pass(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let t = id.x + id.y * groups.x * 64u;
    if (3u * t + 2u >= arrayLength(&cells)) {
        return;
    }
    let s = vec3<u32>(cells[3u * t], cells[3u * t + 1u], cells[3u * t + 2u]);
    if (s.x == NONE || s.y == NONE || s.z == NONE) {
        return;
    }
    let a = drawn[s.x].xyz;
    let c = cross(drawn[s.y].xyz - a, drawn[s.z].xyz - a);
    let len = length(c);
    if (len <= 0.0) {
        return;
    }
    var n = c / len;
    if (n.z < 0.0) {
        n = -n;
    }
    let q = vec3<i32>(round(n * NORMAL_SCALE));
    for (var k = 0u; k < 3u; k++) {
        atomicAdd(&normal_sums[4u * s[k]], q.x);
        atomicAdd(&normal_sums[4u * s[k] + 1u], q.y);
        atomicAdd(&normal_sums[4u * s[k] + 2u], q.z);
    }
}

// Vertex pulling: the vertex index walks the cell records, three slots a triangle.
fn pulled(vi: u32, morph_here: bool) -> VOut {
    var o: VOut;
    o.crack = 0.0;
    let corner = vi % 3u;
    o.bary = vec3<f32>(f32(corner == 0u), f32(corner == 1u), f32(corner == 2u));
    let slot = cells[vi];
    if (slot == NONE) {
        // A missing triangle: all three corners land outside the clip volume.
        o.clip = vec4<f32>(2.0, 2.0, 2.0, 1.0);
        o.rel = vec3<f32>(0.0);
        o.height = 0.0;
        o.normal = vec3<f32>(0.0);
        return o;
    }
    var p: vec3<f32>;
    if (morph_here) {
        p = drawn_position(slot);
        // No normals pass for this path: the fragment shader uses the flat normal.
        o.normal = vec3<f32>(0.0);
    } else {
        p = drawn[slot].xyz;
        o.normal = vec3<f32>(
            f32(normals[4u * slot]),
            f32(normals[4u * slot + 1u]),
            f32(normals[4u * slot + 2u]),
        );
    }
    let rel = p - frame.eye.xyz;
    o.clip = frame.view_proj * vec4<f32>(rel, 1.0);
    o.rel = rel;
    o.height = p.z;
    return o;
}

// Each vertex geomorphed here, from its ancestors' screen errors for this frame's camera.
@vertex
fn vs(@builtin(vertex_index) vi: u32) -> VOut {
    return pulled(vi, true);
}

// Each vertex at the position the `morph` pass computed for its node this frame.
@vertex
fn vs_pre(@builtin(vertex_index) vi: u32) -> VOut {
    return pulled(vi, false);
}
