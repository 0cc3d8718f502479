// The shading every terrain pass shares (the vertex stream's `terrain.wgsl` and the tile
// stream's `tiles.wgsl` are each appended to this file): the frame's uniform block, the vertex
// output, the height colour ramp, and the fragment shader with sun, haze and wireframe.

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
    // near (m), lowest height, highest height (the colour ramp), wireframe (0 or 1).
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
};

// Height colour ramp: lowland green, upland olive, brown, grey rock, snow.
fn ramp(t: f32) -> vec3<f32> {
    let c0 = vec3<f32>(0.16, 0.30, 0.10);
    let c1 = vec3<f32>(0.42, 0.45, 0.20);
    let c2 = vec3<f32>(0.45, 0.33, 0.20);
    let c3 = vec3<f32>(0.50, 0.48, 0.46);
    let c4 = vec3<f32>(0.95, 0.95, 0.97);
    if (t < 0.25) {
        return mix(c0, c1, t / 0.25);
    } else if (t < 0.5) {
        return mix(c1, c2, (t - 0.25) / 0.25);
    } else if (t < 0.8) {
        return mix(c2, c3, (t - 0.5) / 0.3);
    }
    return mix(c3, c4, (t - 0.8) / 0.2);
}

@fragment
fn fs(in: VOut) -> @location(0) vec4<f32> {
    // Flat normal of the drawn (morphed) triangle.
    var n = normalize(cross(dpdx(in.rel), dpdy(in.rel)));
    if (n.z < 0.0) {
        n = -n;
    }
    let span = max(frame.misc.z - frame.misc.y, 1.0);
    let base = ramp(clamp((in.height - frame.misc.y) / span, 0.0, 1.0));
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
