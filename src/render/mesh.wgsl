// Block meshes: lit colour pass and flat block-ID pass (one pipeline, `mode` chooses).
//
// The block id arrives as the instance index: every block is drawn as one instance whose
// first_instance is its BlockId, so no per-vertex id is stored.

struct Globals {
    // clip_from_world for the local frame (f64 on the CPU, cast once).
    clip_from_world: mat4x4<f32>,
    // xyz: unit direction towards the sun; w: ambient term.
    sun: vec4<f32>,
    // x: 0 = lit colour, 1 = block ids.
    mode: vec4<u32>,
};

@group(0) @binding(0) var<uniform> g: Globals;

// The ground plane is drawn as this instance id (never a block id).
const GROUND: u32 = 0xFFFFFFu;

struct VsOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) normal: vec3<f32>,
    @location(1) @interpolate(flat) block: u32,
};

@vertex
fn vs_main(
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @builtin(instance_index) block: u32,
) -> VsOut {
    var out: VsOut;
    out.clip = g.clip_from_world * vec4<f32>(position, 1.0);
    out.normal = normal;
    out.block = block;
    return out;
}

// A small deterministic tint per block so neighbouring blocks can be told apart.
fn tint(id: u32) -> f32 {
    let h = (id * 2654435761u) >> 24u;
    return 0.9 + 0.2 * f32(h) / 255.0;
}

@fragment
fn fs_main(in: VsOut) -> @location(0) vec4<f32> {
    if g.mode.x == 1u {
        // id + 1 in the low 24 bits (0 is "no block"); exact through Rgba8Unorm.
        let id = in.block + 1u;
        return vec4<f32>(
            f32(id & 255u),
            f32((id >> 8u) & 255u),
            f32((id >> 16u) & 255u),
            255.0,
        ) / 255.0;
    }
    let n = normalize(in.normal);
    let light = g.sun.w + (1.0 - g.sun.w) * max(dot(n, g.sun.xyz), 0.0);
    var base: vec3<f32>;
    if in.block == GROUND {
        base = vec3<f32>(0.55, 0.58, 0.50);
    } else if n.z > 0.5 {
        // Roofs.
        base = vec3<f32>(0.70, 0.36, 0.28) * tint(in.block);
    } else if n.z < -0.5 {
        // Undersides (overhangs).
        base = vec3<f32>(0.35, 0.35, 0.35);
    } else {
        // Facades.
        base = vec3<f32>(0.86, 0.82, 0.72) * tint(in.block);
    }
    return vec4<f32>(min(base * light, vec3<f32>(1.0)), 1.0);
}
