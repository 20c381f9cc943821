// Draws triangle meshes for `lancet render`: flat-shaded triangles (each vertex carries its
// triangle's normal), Lambert diffuse plus ambient, lit from both sides (a face seen from
// behind, such as the inside of a cut, is shaded as if it faced the viewer).

struct Uniforms {
    // Clip position of a vertex from its offset from the drawing's origin.
    view_projection: mat4x4<f32>,
    // xyz: unit direction towards the light.
    light: vec4<f32>,
    // xyz: the eye, as an offset from the origin.
    eye: vec4<f32>,
    // x: ambient, y: diffuse weight (their sum is 1, so no colour saturates).
    shading: vec4<f32>,
}

@group(0) @binding(0) var<uniform> u: Uniforms;

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) normal: vec3<f32>,
    @location(1) colour: vec3<f32>,
    @location(2) offset: vec3<f32>,
}

@vertex
fn vs_main(
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) colour: vec3<f32>,
) -> VertexOut {
    var out: VertexOut;
    out.clip = u.view_projection * vec4<f32>(position, 1.0);
    out.normal = normal;
    out.colour = colour;
    out.offset = position;
    return out;
}

@fragment
fn fs_main(in: VertexOut) -> @location(0) vec4<f32> {
    var n = normalize(in.normal);
    if (dot(n, u.eye.xyz - in.offset) < 0.0) {
        n = -n;
    }
    let lambert = max(dot(n, u.light.xyz), 0.0);
    let shade = u.shading.x + u.shading.y * lambert;
    return vec4<f32>(in.colour * shade, 1.0);
}
