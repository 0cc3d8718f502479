// The shading every terrain pass shares (the vertex stream's `terrain.wgsl` and the tile
// stream's `tiles.wgsl` are each appended to this file): the frame's uniform block, the vertex
// output, the hypsometric colour ramp, and the fragment shader with sun, haze and wireframe.

struct Frame {
    // Projection times view, for positions relative to the eye.
    view_proj: mat4x4<f32>,
    // xyz: eye, world metres; w: now, seconds on the renderer's clock.
    eye: vec4<f32>,
    // xyz: unit view direction; w: focal length, pixels.
    forward: vec4<f32>,
    // Inward normals of the four side planes and the near plane; w: the plane's offset.
    planes: array<vec4<f32>, 5>,
    // tau (px), lambda, growth duration (s, 0: none), off-axis bound.
    morph: vec4<f32>,
    // near (m), lowest height, highest height (of the terrain), wireframe (0 or 1).
    misc: vec4<f32>,
    // xyz: unit direction towards the sun; w: 1 to encode sRGB in the shader.
    light: vec4<f32>,
    // rgb: haze colour (linear); w: fog distance, metres.
    haze: vec4<f32>,
};

@group(0) @binding(0) var<uniform> frame: Frame;

struct VOut {
    @builtin(position) clip: vec4<f32>,
    // Position relative to the eye, metres.
    @location(0) rel: vec3<f32>,
    // Barycentric corner, for the wireframe.
    @location(1) bary: vec3<f32>,
    // Height, metres, for the colour ramp.
    @location(2) height: f32,
    // 1 on a tile's crack patch or skirt (tinted under the wireframe), else 0.
    @location(3) crack: f32,
    // Smooth normal (any length), or zero where a pass has none: then the triangle's flat one.
    @location(4) normal: vec3<f32>,
};

// Hypsometric colour ramp in metres above sea level (linear RGB), so that a colour means the
// same height on every terrain: green lowlands, olive and tan uplands, browns, grey rock above
// the tree line, snow only on the highest summits (from about 3,300 m, white by 3,700 m).
// Below sea level stays the lowland green.
fn ramp(h: f32) -> vec3<f32> {
    var stops = array<vec4<f32>, 9>(
        vec4<f32>(0.0, 0.13, 0.27, 0.10),
        vec4<f32>(300.0, 0.24, 0.38, 0.14),
        vec4<f32>(800.0, 0.42, 0.45, 0.22),
        vec4<f32>(1400.0, 0.50, 0.42, 0.26),
        vec4<f32>(2000.0, 0.42, 0.32, 0.21),
        vec4<f32>(2600.0, 0.40, 0.36, 0.33),
        vec4<f32>(3100.0, 0.55, 0.54, 0.53),
        vec4<f32>(3400.0, 0.82, 0.82, 0.84),
        vec4<f32>(3700.0, 0.95, 0.95, 0.97),
    );
    if (h <= stops[0].x) {
        return stops[0].yzw;
    }
    for (var i = 1u; i < 9u; i++) {
        if (h < stops[i].x) {
            let a = stops[i - 1u];
            let b = stops[i];
            return mix(a.yzw, b.yzw, (h - a.x) / (b.x - a.x));
        }
    }
    return stops[8].yzw;
}

@fragment
fn fs(in: VOut) -> @location(0) vec4<f32> {
    // The smooth normal where the pass gives one, else the drawn (morphed) triangle's flat one.
    var n = normalize(cross(dpdx(in.rel), dpdy(in.rel)));
    if (n.z < 0.0) {
        n = -n;
    }
    if (dot(in.normal, in.normal) > 1.0e-12) {
        n = normalize(in.normal);
    }
    let base = ramp(in.height);
    let lambert = max(dot(n, frame.light.xyz), 0.0);
    var c = base * (0.30 + 0.95 * lambert);
    let fog = 1.0 - exp(-length(in.rel) / frame.haze.w);
    c = mix(c, frame.haze.rgb, 0.45 * fog);
    if (frame.misc.w > 0.5) {
        let d = in.bary / max(fwidth(in.bary), vec3<f32>(1.0e-6));
        let edge = min(min(d.x, d.y), d.z);
        c = mix(vec3<f32>(0.05, 0.05, 0.07), c, smoothstep(0.0, 1.0, edge));
        // Tinted after the edges: a patch is often thinner than its edge lines.
        c = mix(c, vec3<f32>(0.95, 0.08, 0.06), 0.85 * in.crack);
    }
    if (frame.light.w > 0.5) {
        c = pow(c, vec3<f32>(1.0 / 2.2));
    }
    return vec4<f32>(c, 1.0);
}
