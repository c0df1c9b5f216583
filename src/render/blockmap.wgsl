// Ray-cast BlockMaps (Cignoni et al., §3.2, Di Benedetto, §4.2.2): one instance per selected map; each
// rasterises its box's back faces, and every fragment walks the map's height field with the grid
// walk of `blockmap::cast` (Amanatides–Woo in 2D), operation for operation as `cast_f32` does it,
// shades the hit as `blockmap::cast::surface` + `blockmap::colors::lit`, and writes its depth.
// A non-empty cell with a footprint edge (image column 2K + 256 + i, A = 255) is the part of the
// cell inside the edge's half-plane: the ray's segment in the cell is cut with it and with the
// height slab, and a hit on the half-plane's side is an EDGE wall with the edge's normal. A second
// edge (image column 3K + 256 + i, A = 255, read only with a first) cuts the segment too, and a hit
// on its side is an EDGE2 wall.
//
// The rays and the depth are those of `blockmap::image` (see its module doc): the view direction
// of the pixel centre `(px·sx + cx, py·sy + cy, −1)`, mapped to texture space per map with
// `d = ax·vx + ay·vy + af`, `o = b + d·near` (the ray starts on the near plane), and the depth
// `max((rn − r·D)/D, 0)` of the view depth `D = near + t`.
//
// `AMBIENT` and `SUN` are prepended by `render/blockmap.rs` from the Rust values.

struct Frame {
    // The box proxies' clip_from_world (local frame).
    clip_from_world: mat4x4<f32>,
    // x: sx, y: cx, z: sy, w: cy.
    pix: vec4<f32>,
    // x: near, y: r, z: rn.
    depth: vec4<f32>,
};

struct Inst {
    // xyz: the camera's right, up and forward vectors in texture units; the eye in texture space.
    ax: vec4<f32>,
    ay: vec4<f32>,
    af: vec4<f32>,
    b: vec4<f32>,
    // The proxy box (local frame, slightly enlarged: the walk tests the exact box).
    box_min: vec4<f32>,
    box_max: vec4<f32>,
    // x: array layer, y: K, z: slices, w: the map's index (written to the map-id target).
    info: vec4<u32>,
};

@group(0) @binding(0) var<uniform> f: Frame;
@group(0) @binding(1) var<storage, read> instances: array<Inst>;
@group(1) @binding(0) var maps: texture_2d_array<u32>;

// Back faces of the unit cube (corner bits: x = 1, y = 2, z = 4), outward counter-clockwise.
const CUBE: array<u32, 36> = array<u32, 36>(
    0u, 4u, 6u, 0u, 6u, 2u, 1u, 3u, 7u, 1u, 7u, 5u, 0u, 1u, 5u, 0u, 5u, 4u,
    2u, 6u, 7u, 2u, 7u, 3u, 0u, 2u, 3u, 0u, 3u, 1u, 4u, 5u, 7u, 4u, 7u, 6u,
);

struct VsOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) @interpolate(flat) inst: u32,
};

@vertex
fn vs_main(@builtin(vertex_index) vi: u32, @builtin(instance_index) ii: u32) -> VsOut {
    let m = instances[ii];
    let c = CUBE[vi];
    let p = vec3<f32>(
        select(m.box_min.x, m.box_max.x, (c & 1u) != 0u),
        select(m.box_min.y, m.box_max.y, (c & 2u) != 0u),
        select(m.box_min.z, m.box_max.z, (c & 4u) != 0u),
    );
    var out: VsOut;
    var clip = f.clip_from_world * vec4<f32>(p, 1.0);
    // Clip at the near plane only (z' = w − near is affine in the vertex, 0 ≤ z' ≤ w ⇔ view
    // depth ≥ near): a box reaching past the far plane still gets its fragments; the depth that
    // counts is the hit's, written below.
    clip.z = clip.w - f.depth.x;
    out.clip = clip;
    out.inst = ii;
    return out;
}

const BIG: f32 = 3.0e38;
const MISS: u32 = 0u;
const ROOF: u32 = 1u;
const WALL: u32 = 2u;
// Faces (blockmap::cast::Face).
const WEST: u32 = 0u;
const EAST: u32 = 1u;
const SOUTH: u32 = 2u;
const NORTH: u32 = 3u;
const INSIDE: u32 = 4u;
const EDGE: u32 = 5u;
const EDGE2: u32 = 6u;
// blockmap::layout::EDGE_OFFSET_RANGE.
const EDGE_RANGE: f32 = 0.75;

struct Hit {
    kind: u32,
    i: i32,
    j: i32,
    face: u32,
    t: f32,
};

fn texel(layer: i32, u: i32, v: i32) -> vec4<u32> {
    return textureLoad(maps, vec2<i32>(u, v), layer, 0);
}

fn sgn(v: f32) -> i32 {
    if v > 0.0 {
        return 1;
    } else if v < 0.0 {
        return -1;
    }
    return 0;
}

// blockmap::cast start_cell's `next`.
fn next_line(c: i32, s: i32, o: f32, d: f32) -> f32 {
    if s > 0 {
        return (f32(c + 1) - o) / d;
    } else if s < 0 {
        return (f32(c) - o) / d;
    }
    return BIG;
}

// blockmap::cast::cast_generic without the tie margins and the distance-map leap.
fn walk_map(o: vec3<f32>, d: vec3<f32>, k: i32, layer: i32) -> Hit {
    var h: Hit;
    h.kind = MISS;
    let kt = f32(k);
    let hi = vec3<f32>(kt, kt, 1.0);
    var t_near = -BIG;
    var t_far = BIG;
    var entry_axis = 3u;
    for (var a = 0u; a < 3u; a++) {
        let oa = o[a];
        let da = d[a];
        if da == 0.0 {
            if oa < 0.0 || oa > hi[a] {
                return h;
            }
            continue;
        }
        let ta = (0.0 - oa) / da;
        let tb = (hi[a] - oa) / da;
        var lo = tb;
        var up = ta;
        if ta < tb {
            lo = ta;
            up = tb;
        }
        if lo > t_near {
            t_near = lo;
            entry_axis = a;
        }
        t_far = min(t_far, up);
    }
    let t0 = max(t_near, 0.0);
    let t1 = t_far;
    if t0 >= t1 {
        return h;
    }
    let eye_inside = t_near <= 0.0;
    let sx = sgn(d.x);
    let sy = sgn(d.y);
    var tdx = BIG;
    if sx != 0 {
        tdx = 1.0 / abs(d.x);
    }
    var tdy = BIG;
    if sy != 0 {
        tdy = 1.0 / abs(d.y);
    }
    let px = o.x + t0 * d.x;
    let py = o.y + t0 * d.y;
    var i = clamp(i32(floor(px)), 0, k - 1);
    var j = clamp(i32(floor(py)), 0, k - 1);
    var tmx = next_line(i, sx, o.x, d.x);
    var tmy = next_line(j, sy, o.y, d.y);
    var face = INSIDE;
    if !eye_inside {
        if entry_axis == 0u {
            face = select(EAST, WEST, sx > 0);
        } else if entry_axis == 1u {
            face = select(NORTH, SOUTH, sy > 0);
        }
    }
    let entered_top = !eye_inside && entry_axis == 2u && d.z < 0.0;
    var t_in = t0;
    for (var it = 0; it < 2 * k; it++) {
        let t_out = min(min(tmx, tmy), t1);
        let za = o.z + t_in * d.z;
        let zb = o.z + t_out * d.z;
        let code = texel(layer, i, j).x;
        let hh = f32(code) / 255.0;
        // A segment wholly above the column cannot hit it, whatever its half-planes: their
        // texel is read only when the segment reaches down to the column's height (the hit is
        // the same; most cells a steep ray crosses above the roofs cost one read instead of two).
        var e = vec4<u32>(0u);
        if code > 0u && min(za, zb) <= hh {
            e = texel(layer, 2 * k + 256 + i, j);
        }
        if code > 0u && e.w == 255u {
            // blockmap::cast: (half-plane(s) ∩ square) × [0, h].
            let e2 = texel(layer, 3 * k + 256 + i, j);
            let cx = f32(i) + 0.5;
            let cy = f32(j) + 0.5;
            var z_ok = true;
            var z_roof = false;
            var z_lo = t_in;
            var z_hi = t_out;
            if za <= hh {
                if zb > hh {
                    z_hi = t_in + (hh - za) / d.z;
                }
            } else if zb <= hh {
                z_lo = t_in + (za - hh) / (-d.z);
                z_roof = true;
            } else {
                z_ok = false;
            }
            let g1 = plane_interval(o, d, e, cx, cy, t_in, t_out);
            var g2 = Interval(true, false, t_in, t_out);
            if e2.w == 255u {
                g2 = plane_interval(o, d, e2, cx, cy, t_in, t_out);
            }
            if z_ok && g1.ok && g2.ok {
                let lo = max(max(z_lo, g1.lo), g2.lo);
                let hi = min(min(z_hi, g1.hi), g2.hi);
                if lo <= hi {
                    h.i = i;
                    h.j = j;
                    if g2.edge && g2.lo > z_lo && g2.lo > g1.lo {
                        h.kind = WALL;
                        h.face = EDGE2;
                        h.t = g2.lo;
                    } else if g1.edge && g1.lo > z_lo {
                        h.kind = WALL;
                        h.face = EDGE;
                        h.t = g1.lo;
                    } else if z_roof {
                        h.kind = ROOF;
                        h.t = z_lo;
                    } else if it == 0 && entered_top {
                        h.kind = ROOF;
                        h.t = t_in;
                    } else {
                        h.kind = WALL;
                        h.face = face;
                        h.t = t_in;
                    }
                    return h;
                }
            }
        } else if code > 0u {
            if za <= hh {
                h.i = i;
                h.j = j;
                h.t = t_in;
                if it == 0 && entered_top {
                    h.kind = ROOF;
                } else {
                    h.kind = WALL;
                    h.face = face;
                }
                return h;
            }
            if zb <= hh {
                h.kind = ROOF;
                h.i = i;
                h.j = j;
                h.t = t_in + (za - hh) / (-d.z);
                return h;
            }
        }
        if t_out >= t1 {
            return h;
        }
        if tmx < tmy {
            i += sx;
            t_in = tmx;
            tmx = tmx + tdx;
            face = select(EAST, WEST, sx > 0);
        } else {
            j += sy;
            t_in = tmy;
            tmy = tmy + tdy;
            face = select(NORTH, SOUTH, sy > 0);
        }
        if i < 0 || i >= k || j < 0 || j >= k {
            return h;
        }
    }
    return h;
}

// blockmap::cast::Interval: where the segment [t_in, t_out] is inside a half-plane.
struct Interval {
    ok: bool,
    edge: bool,
    lo: f32,
    hi: f32,
};

// blockmap::cast::plane_interval.
fn plane_interval(
    o: vec3<f32>,
    d: vec3<f32>,
    e: vec4<u32>,
    cx: f32,
    cy: f32,
    t_in: f32,
    t_out: f32,
) -> Interval {
    let nx = decode_unit(e.x);
    let ny = decode_unit(e.y);
    let eo = (f32(e.z) - 128.0) / 127.0 * EDGE_RANGE;
    let g_in = (o.x + t_in * d.x - cx) * nx + (o.y + t_in * d.y - cy) * ny - eo;
    let g_out = (o.x + t_out * d.x - cx) * nx + (o.y + t_out * d.y - cy) * ny - eo;
    var r = Interval(true, false, t_in, t_out);
    if g_in <= 0.0 {
        if g_out > 0.0 {
            r.hi = t_in + (t_out - t_in) * (g_in / (g_in - g_out));
        }
    } else if g_out <= 0.0 {
        r.lo = t_in + (t_out - t_in) * (g_in / (g_in - g_out));
        r.edge = true;
    } else {
        r.ok = false;
    }
    return r;
}

// blockmap::layout::decode_unit.
fn decode_unit(b: u32) -> f32 {
    return clamp((f32(b) - 128.0) / 127.0, -1.0, 1.0);
}

fn face_normal(face: u32) -> vec3<f32> {
    switch face {
        case 0u: { return vec3<f32>(-1.0, 0.0, 0.0); }
        case 1u: { return vec3<f32>(1.0, 0.0, 0.0); }
        case 2u: { return vec3<f32>(0.0, -1.0, 0.0); }
        case 3u: { return vec3<f32>(0.0, 1.0, 0.0); }
        default: { return vec3<f32>(0.0, 0.0, 1.0); }
    }
}

struct FsOut {
    @location(0) color: vec4<f32>,
    @location(1) map: u32,
    @builtin(frag_depth) depth: f32,
};

@fragment
fn fs_main(in: VsOut) -> FsOut {
    let m = instances[in.inst];
    let layer = i32(m.info.x);
    let k = i32(m.info.y);
    let slices = i32(m.info.z);
    let vx = in.clip.x * f.pix.x + f.pix.y;
    let vy = in.clip.y * f.pix.z + f.pix.w;
    let near = f.depth.x;
    let d = m.ax.xyz * vx + m.ay.xyz * vy + m.af.xyz;
    let o = m.b.xyz + d * near;
    let h = walk_map(o, d, k, layer);
    if h.kind == MISS {
        discard;
    }
    let dv = near + h.t;
    let depth = max((f.depth.z - f.depth.y * dv) / dv, 0.0);
    if !(depth < 1.0) {
        discard;
    }
    // blockmap::cast::surface.
    let shape = texel(layer, h.i, h.j);
    var base = texel(layer, k + h.i, h.j).xyz;
    var n: vec3<f32>;
    // The edge's normal on the half-plane's side (blockmap::cast::surface).
    var edge_n = vec3<f32>(0.0, 0.0, 1.0);
    var has_edge_n = false;
    if h.kind == WALL && (h.face == EDGE || h.face == EDGE2) {
        var e = texel(layer, 2 * k + 256 + h.i, h.j);
        if h.face == EDGE2 {
            e = texel(layer, 3 * k + 256 + h.i, h.j);
        }
        if e.w == 255u {
            let raw_e = vec3<f32>(decode_unit(e.x), decode_unit(e.y), 0.0);
            let rcp_e = 1.0 / length(raw_e);
            if rcp_e > 0.0 && rcp_e < BIG {
                edge_n = raw_e * rcp_e;
            }
            has_edge_n = true;
        }
    }
    if h.kind == ROOF {
        let x = decode_unit(shape.z);
        let y = decode_unit(shape.w);
        n = vec3<f32>(x, y, sqrt(max(1.0 - x * x - y * y, 0.0)));
    } else if shape.y == 0u || h.face == INSIDE {
        if has_edge_n {
            n = edge_n;
        } else {
            n = face_normal(h.face);
        }
    } else {
        let u = 2 * k + i32(shape.y) - 1;
        let z = o.z + h.t * d.z;
        let rows = k / slices;
        let colour_rows = rows - 1;
        let row = clamp(i32(floor(z * f32(colour_rows))), 0, colour_rows - 1);
        let slice = h.j * slices / k;
        base = texel(layer, u, slice * rows + row).xyz;
        let nb = texel(layer, u, slice * rows + rows - 1);
        let raw = vec3<f32>(decode_unit(nb.x), decode_unit(nb.y), decode_unit(nb.z));
        let rcp = 1.0 / length(raw);
        if has_edge_n {
            n = edge_n;
        } else if rcp > 0.0 && rcp < BIG {
            n = raw * rcp;
        } else {
            n = face_normal(h.face);
        }
    }
    // blockmap::colors::lit = appearance::shade of the byte colour.
    let light = AMBIENT + (1.0 - AMBIENT) * max(dot(n, SUN), 0.0);
    let c = min(vec3<f32>(base) / 255.0 * light, vec3<f32>(1.0));
    var out: FsOut;
    out.color = vec4<f32>(c, 1.0);
    out.map = m.info.w;
    out.depth = depth;
    return out;
}
