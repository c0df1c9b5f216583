// Ray-cast relief impostors (Andujar et al., §5.2): one instance per node drawn; each rasterises
// its box's back faces, and every fragment walks the node's zenithal height field over its max
// pyramid (the pyramidal displacement mapping of Oh, Ki and Lee) operation for operation as
// `relief::cast::cast_generic::<f32>` does it, or crosses the flat quad of a horizon node as
// `relief::cast::cast_flat` does, colours the hit as `relief::node::shade` and writes its depth.
//
// The rays and the depth are those of `blockmap::image` (see its module doc), as
// `relief::image::cast_image` makes them: the view direction of the pixel centre
// `(px·sx + cx, py·sy + cy, −1)`, mapped to the node's texture space with `d = ax·vx + ay·vy + af`,
// `o = b + d·near` (the ray starts on the near plane), and the depth `max((rn − r·D)/D, 0)` of the
// view depth `D = near + t`.
//
// Texture space: x, y ∈ [0, M] texels of the zenithal map, z ∈ [0, 1] over the node's height
// range; a texel's column rises to q/65535 (q its stored height, 0 for none). Texels are read
// with `textureLoad` (the loops are not uniform control flow): the pyramid is the mip chain of the
// zenithal height texture, level 0 the map itself.
//
// Infinities of the reference are the large finite `BIG` here (WGSL has no infinity literal): a
// slab or a cell line the ray never crosses; every finite parameter a walk meets is far below it.

struct Frame {
    // The box proxies' clip_from_world (local frame).
    clip_from_world: mat4x4<f32>,
    // x: sx, y: cx, z: sy, w: cy.
    pix: vec4<f32>,
    // x: near, y: r, z: rn, w: one height quantum, 1/65535 rounded to f32 as the reference
    // rounds it (the box top lies that far above the highest column).
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
    // x: the node's layer in the zenithal arrays, y: M, z: pyramid levels, w: 1 for a horizon
    // node (the flat quad), else 0.
    info: vec4<u32>,
    // x: the walk's step limit, y: the node's index (written to the node-id target).
    extra: vec4<u32>,
    // xyz: the layers of the three chosen obliques in the oblique arrays, in the order they are
    // tried; NONE where fewer were chosen.
    chosen: vec4<u32>,
    // Per chosen oblique k, rows 3k..3k+2 of its affine map (texture space → texel a, texel b,
    // quantised depth), as `relief::node::ObliqueXform::rows`.
    rows: array<vec4<f32>, 9>,
    // Per chosen oblique, the depth-match tolerance in quantised units.
    tol: vec4<f32>,
    // While a switch of obliques is blended (relief::image::MapSets): xyz the previous three's
    // layers (NONE where none), w the new set's weight of 256 (256: no blend).
    prev: vec4<u32>,
    prev_rows: array<vec4<f32>, 9>,
    prev_tol: vec4<f32>,
};

@group(0) @binding(0) var<uniform> f: Frame;
@group(0) @binding(1) var<storage, read> instances: array<Inst>;
// Zenithal colour (RGBA8) per node.
@group(1) @binding(0) var zen_color: texture_2d_array<u32>;
// Zenithal height (16 bits) per node, its max pyramid as the mip chain.
@group(1) @binding(1) var pyramid: texture_2d_array<u32>;
// Oblique colour (RGBA8) and depth (16 bits) per oblique map.
@group(1) @binding(2) var obl_color: texture_2d_array<u32>;
@group(1) @binding(3) var obl_depth: texture_2d_array<u32>;

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
    let c = CUBE[vi];
    let lo = instances[ii].box_min;
    let hi = instances[ii].box_max;
    let p = vec3<f32>(
        select(lo.x, hi.x, (c & 1u) != 0u),
        select(lo.y, hi.y, (c & 2u) != 0u),
        select(lo.z, hi.z, (c & 4u) != 0u),
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
const NONE: u32 = 0xffffffffu;
// Faces (relief::cast::Face).
const TOP: u32 = 0u;
const WALL_X: u32 = 1u;
const WALL_Y: u32 = 2u;
const INSIDE: u32 = 3u;
const FLAT: u32 = 4u;

struct Hit {
    ok: bool,
    t: f32,
    i: i32,
    j: i32,
    face: u32,
};

// The height stored at cell (x, y) of pyramid level `level`.
fn height(layer: i32, level: i32, x: i32, y: i32) -> u32 {
    return textureLoad(pyramid, vec2<i32>(x, y), layer, level).x;
}

// relief::cast's floor_i: ⌊v⌋ as an integer (every v a walk floors is a point of the box, far
// inside the clamp).
fn floor_i(v: f32) -> i32 {
    return i32(clamp(floor(v), -1.0e9, 1.0e9));
}

// relief::cast::cast_generic's `start`: the cell of the entry point along one axis.
fn start_cell(o: f32, d: f32, t: f32, m: i32) -> i32 {
    let p = o + d * t;
    var i = floor_i(p);
    if d < 0.0 && floor(p) == p {
        i -= 1;
    }
    return clamp(i, 0, m - 1);
}

// relief::cast::cast_generic::<f32> without the tie margins.
fn walk(o: vec3<f32>, d: vec3<f32>, layer: i32, m: i32, levels: i32, limit: u32) -> Hit {
    var h: Hit;
    h.ok = false;
    let mf = f32(m);
    let top = levels - 1;
    // The box's top lies a height quantum above the highest column.
    let zbox = f32(height(layer, top, 0, 0)) / 65535.0 + f.depth.w;
    let hi = vec3<f32>(mf, mf, zbox);
    var t0 = -BIG;
    var t1 = BIG;
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
        if lo > t0 {
            t0 = lo;
            entry_axis = a;
        }
        if up < t1 {
            t1 = up;
        }
    }
    var face = INSIDE;
    if entry_axis == 0u {
        face = WALL_X;
    } else if entry_axis == 1u {
        face = WALL_Y;
    } else if entry_axis == 2u {
        face = TOP;
    }
    if t0 < 0.0 {
        t0 = 0.0;
        face = INSIDE;
    }
    if !(t0 <= t1) {
        return h;
    }
    var ix = start_cell(o.x, d.x, t0, m);
    var iy = start_cell(o.y, d.y, t0, m);
    var level = top;
    var t = t0;
    for (var steps = 0u; steps < limit; steps++) {
        let size = 1 << u32(level);
        let cx = ix >> u32(level);
        let cy = iy >> u32(level);
        let q = height(layer, level, cx, cy);
        let x_lo = f32(cx * size);
        let x_hi = f32((cx + 1) * size);
        let y_lo = f32(cy * size);
        let y_hi = f32((cy + 1) * size);
        var tx = BIG;
        if d.x > 0.0 {
            tx = (x_hi - o.x) / d.x;
        } else if d.x < 0.0 {
            tx = (x_lo - o.x) / d.x;
        }
        var ty = BIG;
        if d.y > 0.0 {
            ty = (y_hi - o.y) / d.y;
        } else if d.y < 0.0 {
            ty = (y_lo - o.y) / d.y;
        }
        let te = min(min(tx, ty), t1);
        let hq = f32(q) / 65535.0;
        let zt = o.z + d.z * t;
        let ze = o.z + d.z * te;
        let below = q != 0u && !(zt > hq && ze > hq);
        if below && level > 0 {
            level -= 1;
            continue;
        }
        if below {
            // A column the ray reaches below its top: a wall (or the start inside it) when the
            // ray is already below the top where it enters the cell, else the top.
            h.ok = true;
            h.i = ix;
            h.j = iy;
            if zt <= hq {
                h.t = t;
                h.face = face;
            } else {
                h.t = (hq - o.z) / d.z;
                h.face = TOP;
            }
            return h;
        }
        // Skip the cell.
        if !(te < t1) {
            return h;
        }
        t = te;
        let step_x = tx <= ty;
        let step_y = ty <= tx;
        if step_x {
            if d.x > 0.0 {
                ix = (cx + 1) * size;
            } else {
                ix = cx * size - 1;
            }
            face = WALL_X;
        } else {
            ix = clamp(floor_i(o.x + d.x * t), cx * size, (cx + 1) * size - 1);
        }
        if step_y {
            if d.y > 0.0 {
                iy = (cy + 1) * size;
            } else {
                iy = cy * size - 1;
            }
            face = WALL_Y;
        } else {
            iy = clamp(floor_i(o.y + d.y * t), cy * size, (cy + 1) * size - 1);
        }
        if ix < 0 || iy < 0 || ix >= m || iy >= m {
            return h;
        }
        // Rise a level on leaving the parent cell.
        if level < top
            && ((ix >> u32(level + 1)) != (cx >> 1u) || (iy >> u32(level + 1)) != (cy >> 1u)) {
            level += 1;
        }
    }
    return h;
}

// relief::cast::cast_flat::<f32>: the crossing with z = z_max/2 over a covered texel.
fn flat_quad(o: vec3<f32>, d: vec3<f32>, layer: i32, m: i32, levels: i32) -> Hit {
    var h: Hit;
    h.ok = false;
    let zmax = f32(height(layer, levels - 1, 0, 0)) / 65535.0;
    let zf = zmax * 0.5;
    if d.z == 0.0 {
        return h;
    }
    let t = (zf - o.z) / d.z;
    if t < 0.0 {
        return h;
    }
    let x = o.x + d.x * t;
    let y = o.y + d.y * t;
    let mf = f32(m);
    if !(x >= 0.0 && y >= 0.0 && x < mf && y < mf) {
        return h;
    }
    let i = floor_i(x);
    let j = floor_i(y);
    if height(layer, 0, i, j) != 0u {
        h.ok = true;
        h.t = t;
        h.i = i;
        h.j = j;
        h.face = FLAT;
    }
    return h;
}

fn zenithal(layer: i32, i: i32, j: i32) -> vec4<u32> {
    let c = textureLoad(zen_color, vec2<i32>(i, j), layer, 0);
    return vec4<u32>(c.xyz, 255u);
}

// relief::node::shade over the chosen three (`prev` false) or the previous three (`prev` true):
// the first oblique whose depth matches the wall point's within the tolerance, else the integer
// average of the covered ones, else the zenithal colour.
fn shade_wall(ii: u32, prev: bool, p: vec3<f32>, h: Hit) -> vec4<u32> {
    let layer = i32(instances[ii].info.x);
    let mf = f32(instances[ii].info.y);
    var sum = vec3<u32>(0u);
    var n = 0u;
    for (var k = 0u; k < 3u; k++) {
        var ob = instances[ii].chosen[k];
        var ra = instances[ii].rows[3u * k];
        var rb = instances[ii].rows[3u * k + 1u];
        var rd = instances[ii].rows[3u * k + 2u];
        var tol = instances[ii].tol[k];
        if prev {
            ob = instances[ii].prev[k];
            ra = instances[ii].prev_rows[3u * k];
            rb = instances[ii].prev_rows[3u * k + 1u];
            rd = instances[ii].prev_rows[3u * k + 2u];
            tol = instances[ii].prev_tol[k];
        }
        if ob == NONE {
            continue;
        }
        let a = ra.x * p.x + ra.y * p.y + ra.z * p.z + ra.w;
        let b = rb.x * p.x + rb.y * p.y + rb.z * p.z + rb.w;
        let dq = rd.x * p.x + rd.y * p.y + rd.z * p.z + rd.w;
        if !(a >= 0.0 && b >= 0.0 && a < mf && b < mf) {
            continue;
        }
        let at = vec2<i32>(floor_i(a), floor_i(b));
        let q = textureLoad(obl_depth, at, i32(ob), 0).x;
        if q == 0u {
            continue;
        }
        let c = textureLoad(obl_color, at, i32(ob), 0).xyz;
        if abs(f32(q) - dq) <= tol {
            return vec4<u32>(c, 255u);
        }
        sum += c;
        n += 1u;
    }
    if n == 0u {
        return zenithal(layer, h.i, h.j);
    }
    return vec4<u32>((sum + vec3<u32>(n / 2u)) / n, 255u);
}

// relief::node::shade_blended: the zenithal colour on tops; on walls the chosen three's colour,
// mixed with the previous three's by the new set's weight while a switch is blended.
fn shade(ii: u32, o: vec3<f32>, d: vec3<f32>, h: Hit) -> vec4<u32> {
    let layer = i32(instances[ii].info.x);
    if h.face != WALL_X && h.face != WALL_Y {
        return zenithal(layer, h.i, h.j);
    }
    let t = h.t;
    let p = vec3<f32>(o.x + d.x * t, o.y + d.y * t, o.z + d.z * t);
    let c_new = shade_wall(ii, false, p, h);
    let w = instances[ii].prev.w;
    if w >= 256u {
        return c_new;
    }
    let c_old = shade_wall(ii, true, p, h);
    let mixed = (c_old.xyz * (256u - w) + c_new.xyz * w + vec3<u32>(128u)) >> vec3<u32>(8u);
    return vec4<u32>(mixed, 255u);
}

struct FsOut {
    @location(0) color: vec4<f32>,
    @location(1) node: u32,
    @builtin(frag_depth) depth: f32,
};

@fragment
fn fs_main(in: VsOut) -> FsOut {
    let ii = in.inst;
    let info = instances[ii].info;
    let layer = i32(info.x);
    let m = i32(info.y);
    let levels = i32(info.z);
    let vx = in.clip.x * f.pix.x + f.pix.y;
    let vy = in.clip.y * f.pix.z + f.pix.w;
    let near = f.depth.x;
    let d = instances[ii].ax.xyz * vx + instances[ii].ay.xyz * vy + instances[ii].af.xyz;
    let o = instances[ii].b.xyz + d * near;
    var h: Hit;
    if info.w != 0u {
        h = flat_quad(o, d, layer, m, levels);
    } else {
        h = walk(o, d, layer, m, levels, instances[ii].extra.x);
    }
    if !h.ok {
        discard;
    }
    let dv = near + h.t;
    let depth = max((f.depth.z - f.depth.y * dv) / dv, 0.0);
    if !(depth < 1.0) {
        discard;
    }
    let c = shade(ii, o, d, h);
    var out: FsOut;
    out.color = vec4<f32>(c) / 255.0;
    out.node = instances[ii].extra.y;
    out.depth = depth;
    return out;
}
