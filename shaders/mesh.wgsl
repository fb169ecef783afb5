// facesynth viewport: shaded meshes, wireframe edges and feature-point markers, rendered into an
// offscreen colour + depth target (egui's own pass has no depth buffer) and then blitted.

struct Camera {
    view_proj: mat4x4<f32>,
    // Eye position in world space (mm); w unused.
    eye: vec4<f32>,
    // Viewport size in physical pixels (x, y); z = marker radius in pixels; w unused.
    viewport: vec4<f32>,
    // Cut-away plane: fragments with dot(clip.xyz, p) > clip.w are discarded (xyz = 0: off).
    clip: vec4<f32>,
};

fn clipped(p: vec3<f32>) -> bool {
    return dot(camera.clip.xyz, camera.clip.xyz) > 0.0 && dot(camera.clip.xyz, p) > camera.clip.w;
}

struct Draw {
    // Used when the mesh has no per-vertex colours (colour.a < 0 means "use vertex colour").
    colour: vec4<f32>,
    // x: 1 = flat shading, y: opacity, z: depth pull towards the camera (clip units), w unused.
    params: vec4<f32>,
};

@group(0) @binding(0) var<uniform> camera: Camera;
@group(1) @binding(0) var<uniform> draw: Draw;

struct MeshIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) colour: vec4<f32>,
};

struct MeshOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) colour: vec4<f32>,
};

@vertex
fn vs_mesh(v: MeshIn) -> MeshOut {
    var out: MeshOut;
    out.clip = camera.view_proj * vec4<f32>(v.position, 1.0);
    out.clip.z = out.clip.z - draw.params.z * out.clip.w;
    out.world = v.position;
    out.normal = v.normal;
    out.colour = select(draw.colour, v.colour, draw.colour.a < 0.0);
    return out;
}

@fragment
fn fs_mesh(f: MeshOut) -> @location(0) vec4<f32> {
    if (clipped(f.world)) {
        discard;
    }
    var n = normalize(f.normal);
    if (draw.params.x > 0.5 || dot(f.normal, f.normal) < 1e-12) {
        // Flat shading: the face normal from screen-space derivatives of the position.
        n = normalize(cross(dpdx(f.world), dpdy(f.world)));
    }
    let to_eye = normalize(camera.eye.xyz - f.world);
    // Headlight, two-sided: scans are open surfaces seen from both sides.
    let ndl = abs(dot(n, to_eye));
    let diffuse = 0.25 + 0.75 * ndl;
    let specular = 0.18 * pow(ndl, 24.0);
    let rgb = f.colour.rgb * diffuse + vec3<f32>(specular);
    return vec4<f32>(rgb, f.colour.a * draw.params.y);
}

// Edges as a line list; pulled slightly towards the camera so they win the depth test
// against the faces they lie on. Uniform colour, or per-vertex (muscle arrows) when the
// uniform colour's alpha is negative.
struct LineOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) colour: vec4<f32>,
};

@vertex
fn vs_line(v: MeshIn) -> LineOut {
    var out: LineOut;
    var clip = camera.view_proj * vec4<f32>(v.position, 1.0);
    clip.z = clip.z - draw.params.z * clip.w;
    out.clip = clip;
    out.world = v.position;
    out.colour = select(draw.colour, v.colour, draw.colour.a < 0.0);
    return out;
}

@fragment
fn fs_line(f: LineOut) -> @location(0) vec4<f32> {
    if (clipped(f.world)) {
        discard;
    }
    return vec4<f32>(f.colour.rgb, abs(f.colour.a) * draw.params.y);
}

// Markers: one screen-aligned disc per instance (6 vertices, two triangles).
struct MarkerIn {
    @location(0) centre: vec3<f32>,
    @location(1) colour: vec4<f32>,
};

struct MarkerOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) offset: vec2<f32>,
    @location(1) colour: vec4<f32>,
    @location(2) centre: vec3<f32>,
};

@vertex
fn vs_marker(@builtin(vertex_index) i: u32, m: MarkerIn) -> MarkerOut {
    var corners = array<vec2<f32>, 6>(
        vec2<f32>(-1.0, -1.0), vec2<f32>(1.0, -1.0), vec2<f32>(1.0, 1.0),
        vec2<f32>(-1.0, -1.0), vec2<f32>(1.0, 1.0), vec2<f32>(-1.0, 1.0),
    );
    let c = corners[i];
    var clip = camera.view_proj * vec4<f32>(m.centre, 1.0);
    let pixels = camera.viewport.z;
    clip.x = clip.x + c.x * pixels * 2.0 / camera.viewport.x * clip.w;
    clip.y = clip.y + c.y * pixels * 2.0 / camera.viewport.y * clip.w;
    clip.z = clip.z - draw.params.z * clip.w;
    var out: MarkerOut;
    out.clip = clip;
    out.offset = c;
    out.colour = m.colour;
    out.centre = m.centre;
    return out;
}

@fragment
fn fs_marker(f: MarkerOut) -> @location(0) vec4<f32> {
    let r2 = dot(f.offset, f.offset);
    if (r2 > 1.0 || clipped(f.centre)) {
        discard;
    }
    // Dark rim so markers read on any colour map.
    let rim = select(1.0, 0.15, r2 > 0.6);
    return vec4<f32>(f.colour.rgb * rim, 1.0);
}
