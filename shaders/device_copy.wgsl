// The device's memory-bandwidth floor: each invocation copies one vec4 (STREAM's copy kernel),
// the way the steps read and write their arrays, in the steps' workgroups of 64 and their grid
// (`engine::gpu::dispatch_size`: 256 MiB is 16M vec4s, more workgroups than one dimension
// holds).

@group(0) @binding(0) var<uniform> n: vec4<u32>;
@group(0) @binding(1) var<storage, read> src: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> dst: array<vec4<f32>>;

@compute @workgroup_size(64)
fn main(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let i = (wid.y * groups.x + wid.x) * 64u + lid;
    if i < n.x {
        dst[i] = src[i];
    }
}
