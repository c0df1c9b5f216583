// Block meshes: lit colour pass and flat block-ID pass (one shader, `mode` chooses).
//
// The unit id (block, page or building: scene::units) is stored per vertex, so that one draw
// call may span many units (render/mesh.rs merges neighbouring units into one call).
//
// The colours are `city::appearance`, mirrored here operation for operation (see that module's
// docs for the formulas and why they reproduce bit for bit). Its constants (SILL, LINTEL,
// GROUND_SILL, GROUND_LINTEL, GROUND_FLOOR_SHADE, UNDERSIDE, TERRAIN, TERRAIN_ID) are not written here: `render/mesh.rs`
// prepends them, printed from the Rust values, so there is one definition.

struct Globals {
    // clip_from_world for the local frame (f64 on the CPU, cast once).
    clip_from_world: mat4x4<f32>,
    // xyz: unit direction towards the sun; w: ambient term.
    sun: vec4<f32>,
    // x: 0 = lit colour, 1 = block ids.
    mode: vec4<u32>,
};

// `appearance::BuildingStyle` as uploaded (`GpuStyle` in render/mesh.rs).
struct Style {
    // rgb: facade; w: window_half.
    facade: vec4<f32>,
    // rgb: window glass; w: inv_storey_m.
    window: vec4<f32>,
    // rgb: roof (or ground surface); w: inv_bay_m.
    roof: vec4<f32>,
    // x: levels; y: the bits of ground_z (the building's ground, local z).
    levels: vec4<u32>,
};

@group(0) @binding(0) var<uniform> g: Globals;
@group(0) @binding(1) var<storage, read> styles: array<Style>;

struct VsOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) normal: vec3<f32>,
    @location(1) @interpolate(flat) block: u32,
    // x: along-wall u (m); y: height above the ground z (m).
    @location(2) uz: vec2<f32>,
    @location(3) @interpolate(flat) style: u32,
    // The first vertex's normal: terrain is shaded flat with it (as visibility::oracle does).
    @location(4) @interpolate(flat) flat_normal: vec3<f32>,
};

@vertex
fn vs_main(
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) u_m: f32,
    @location(3) style: u32,
    @location(4) block: u32,
) -> VsOut {
    var out: VsOut;
    out.clip = g.clip_from_world * vec4<f32>(position, 1.0);
    out.normal = normal;
    out.block = block;
    out.uz = vec2<f32>(u_m, position.z);
    out.style = style;
    out.flat_normal = normal;
    return out;
}

// appearance::facade_color.
fn facade_color(s: Style, u_m: f32, z_m: f32) -> vec3<f32> {
    let t = (z_m - bitcast<f32>(s.levels.y)) * s.window.w;
    let st = floor(t);
    let v = t - st;
    if s.levels.x == 0u || st < 0.0 || st >= f32(s.levels.x) {
        return s.facade.rgb;
    }
    let ground = st < 1.0;
    var v0 = SILL;
    var v1 = LINTEL;
    if ground {
        v0 = GROUND_SILL;
        v1 = GROUND_LINTEL;
    }
    let b = u_m * s.roof.w;
    let f = b - floor(b);
    if v >= v0 && v < v1 && abs(f - 0.5) < s.facade.w {
        return s.window.rgb;
    }
    if ground {
        return s.facade.rgb * GROUND_FLOOR_SHADE;
    }
    return s.facade.rgb;
}

// appearance::roof_color.
fn roof_color(s: Style) -> vec3<f32> {
    return s.roof.rgb;
}

// appearance::surface_color.
fn surface_color(s: Style, n: vec3<f32>, u_m: f32, z_m: f32) -> vec3<f32> {
    if n.z > 0.5 {
        return roof_color(s);
    } else if n.z < -0.5 {
        return UNDERSIDE;
    }
    return facade_color(s, u_m, z_m);
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
    if in.block == TERRAIN_ID {
        // Terrain: appearance::TERRAIN, lit with the first vertex's normal.
        let n = normalize(in.flat_normal);
        let light = g.sun.w + (1.0 - g.sun.w) * max(dot(n, g.sun.xyz), 0.0);
        return vec4<f32>(min(TERRAIN * light, vec3<f32>(1.0)), 1.0);
    }
    let n = normalize(in.normal);
    // appearance::shade.
    let light = g.sun.w + (1.0 - g.sun.w) * max(dot(n, g.sun.xyz), 0.0);
    let base = surface_color(styles[in.style], n, in.uz.x, in.uz.y);
    return vec4<f32>(min(base * light, vec3<f32>(1.0)), 1.0);
}
