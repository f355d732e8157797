// GPU decode of one CPS-RGB window with the robust unwrap: the CPU decoder's stages
// (src/decode/{phasor,connect,smooth,unwrap,consistency}.rs) one entry point each, run in order:
//
//   solve       per pixel: 9×9 solve, wrapped phases, amplitudes, colour, unit phasor, flags
//   connect     per pixel: RIGHT / DOWN links of the edge-aware filter
//   horizontal  per row:   forward + backward recursion of (re, im, support) into tmp, the
//                          phasor turned along the fine phase at each step when transported
//   vertical    per column: the same down the columns, back into (re, im, support)
//   unwrap      per pixel: coarse coordinate, eq. 8 for each frequency, combination, checks
//   jumps       per pixel: fringe-order jumps between linked neighbours, final flags
//
// Planes are pixel-planar: plane p of pixel i is at p·n + i. The coordinate is written whatever
// the flags; the host sets it to NaN where the final flags are not 0 (WGSL has no reliable NaN).
// The host side and the uniform's Rust twin are ui/src/gpu_decode/.

struct Params {
    width: u32,
    height: u32,
    frame_words: u32,
    n: u32,
    saturation_level: u32,
    check_jumps: u32,
    // The slot of `frames` holding the window's oldest frame; frame k is in slot
    // (first_slot + k) mod 3, so a new frame replaces only the oldest one.
    first_slot: u32,
    _pad1: u32,
    // Angular frequency of each slot (n, n−1, n−2), rad per projector px, and 1/f_1.
    freq: vec3<f32>,
    inv_f_unit: f32,
    // Noise gain of each slot's rows of the pseudo-inverse.
    gain: vec3<f32>,
    x_max: f32,
    min_amplitude: f32,
    camera_noise_gray: f32,
    max_disagreement_chi2: f32,
    max_rounding_residual: f32,
    decay: f32,
    edge_phase_rad: f32,
    edge_colour_ratio: f32,
    edge_chromaticity: f32,
    min_support: f32,
    half_period_px: f32,
    // 1/n when the unit phasor's sum is carried along the fine phase (slot 0), 0 when summed
    // plainly (src/decode/smooth_transport.rs).
    unit_per_fine: f32,
    // Pixels each recursion segment warms up on beyond its ends: decay^halo is below f32
    // resolution.
    halo: u32,
}

@group(0) @binding(0) var<uniform> P: Params;
// Three slots of one frame of interleaved 8-bit RGB each, padded to frame_words words.
@group(0) @binding(1) var<storage, read> frames: array<u32>;
// The solver's pseudo-inverse, row-major 9×9.
@group(0) @binding(2) var<storage, read> pinv: array<f32>;
// phase (3 planes), amplitude (3), colour (3).
@group(0) @binding(3) var<storage, read_write> solved: array<f32>;
// re, im, support, tmp (3), coordinate.
@group(0) @binding(4) var<storage, read_write> work: array<f32>;
// flags, links, final flags.
@group(0) @binding(5) var<storage, read_write> bits: array<u32>;

const PI: f32 = 3.14159265358979;
const TAU: f32 = 6.28318530717959;
const FRAC_PI_2: f32 = 1.57079632679490;

const LOW_AMPLITUDE: u32 = 1u;
const SATURATED: u32 = 2u;
const UNWRAP_MARGIN: u32 = 4u;
const DISAGREEMENT: u32 = 8u;
const LOW_SUPPORT: u32 = 16u;
const OUT_OF_RANGE: u32 = 32u;
const ORDER_JUMP: u32 = 64u;
const RIGHT: u32 = 1u;
const DOWN: u32 = 2u;

// Plane offsets, in units of n.
const PHASE: u32 = 0u;
const AMP: u32 = 3u;
const COLOUR: u32 = 6u;
const RE: u32 = 0u;
const IM: u32 = 1u;
const SUPPORT: u32 = 2u;
const TMP: u32 = 3u;
const COORD: u32 = 6u;
const FLAGS: u32 = 0u;
const LINKS: u32 = 1u;
const FINAL: u32 = 2u;

fn byte_at(index: u32) -> u32 {
    return (frames[index >> 2u] >> ((index & 3u) * 8u)) & 0xffu;
}

// The CPU's polynomial atan2 (src/decode/fastmath.rs), so both paths round alike.
fn atan2_poly(y: f32, x: f32) -> f32 {
    let ax = abs(x);
    let ay = abs(y);
    let big = max(ax, ay);
    let small = min(ax, ay);
    var t = 0.0;
    if (big > 0.0) {
        t = small / big;
    }
    let t2 = t * t;
    let p = t * (0.999866 + t2 * (-0.3302995 + t2 * (0.180141 + t2 * (-0.085133 + t2 * 0.0208351))));
    var r = select(p, FRAC_PI_2 - p, ay > ax);
    r = select(r, PI - r, x < 0.0);
    return select(r, -r, y < 0.0);
}

fn phase_0_tau(y: f32, x: f32) -> f32 {
    let a = atan2_poly(y, x);
    return select(a, a + TAU, a < 0.0);
}

@compute @workgroup_size(8, 8)
fn solve(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= P.width || id.y >= P.height) {
        return;
    }
    let n = P.n;
    let i = id.y * P.width + id.x;
    var obs: array<f32, 9>;
    var saturated = false;
    for (var k = 0u; k < 3u; k++) {
        let base = ((P.first_slot + k) % 3u) * P.frame_words * 4u + i * 3u;
        for (var j = 0u; j < 3u; j++) {
            let v = byte_at(base + j);
            obs[k * 3u + j] = f32(v);
            saturated = saturated || (v >= P.saturation_level);
        }
    }
    var u: array<f32, 9>;
    for (var q = 0u; q < 9u; q++) {
        var acc = 0.0;
        for (var o = 0u; o < 9u; o++) {
            acc += pinv[q * 9u + o] * obs[o];
        }
        u[q] = acc;
    }
    for (var c = 0u; c < 3u; c++) {
        solved[(COLOUR + c) * n + i] = u[c];
    }
    var amp: array<f32, 3>;
    for (var f = 0u; f < 3u; f++) {
        let cu = u[3u + 2u * f];
        let sv = u[4u + 2u * f];
        solved[(PHASE + f) * n + i] = phase_0_tau(sv, cu);
        amp[f] = sqrt(cu * cu + sv * sv);
        solved[(AMP + f) * n + i] = amp[f];
    }
    let c0 = u[3];
    let s0 = u[4];
    let c1 = u[5];
    let s1 = u[6];
    let c2 = u[7];
    let s2 = u[8];
    // p = z0·conj(z1), q = z1·conj(z2): both a0·a1·e^{i f1 x}; the unit phasor is their sum.
    let pr = c0 * c1 + s0 * s1;
    let pi = s0 * c1 - c0 * s1;
    let qr = c1 * c2 + s1 * s2;
    let qi = s1 * c2 - c1 * s2;
    let tr = pr * qr + pi * qi;
    let ti = pi * qr - pr * qi;
    let sin2 = ti * ti / (tr * tr + ti * ti);
    let a0 = c0 * c0 + s0 * s0;
    let a1 = c1 * c1 + s1 * s1;
    let a2 = c2 * c2 + s2 * s2;
    let g0 = P.gain.x * P.gain.x;
    let g1 = 4.0 * P.gain.y * P.gain.y;
    let g2 = P.gain.z * P.gain.z;
    let limit = P.max_disagreement_chi2 * P.camera_noise_gray * P.camera_noise_gray;
    let var_over_noise = g0 / a0 + g1 / a1 + g2 / a2;
    let odd = (tr < 0.0) || (sin2 > limit * var_over_noise);
    let min_amp = min(amp[0], min(amp[1], amp[2]));
    if (motion_on()) {
        // The motion model (decode_motion.wgsl): the signal's reasons alone, and the evidence
        // for the patch's motion instead of the unit phasor; the residual is tested after the
        // correction.
        var signal = select(0u, LOW_AMPLITUDE, !(min_amp >= P.min_amplitude));
        signal |= select(0u, SATURATED, saturated);
        bits[FLAGS * n + i] = signal;
        let z0 = vec2<f32>(c0, s0);
        let z1 = vec2<f32>(c1, s1);
        let z2 = vec2<f32>(c2, s2);
        let phases = vec3<f32>(solved[PHASE * n + i], solved[(PHASE + 1u) * n + i], solved[(PHASE + 2u) * n + i]);
        let cheb = cheb_of(z0, z1, z2, phases, vec3<f32>(amp[0], amp[1], amp[2]));
        let keep = select(0.0, 1.0, signal == 0u);
        stage1_evidence(i, z0, z1, z2, cheb, vec3<f32>(u[0], u[1], u[2]), keep);
        return;
    }
    var reason = 0u;
    if (min_amp < P.min_amplitude) {
        reason |= LOW_AMPLITUDE;
    }
    if (saturated) {
        reason |= SATURATED;
    }
    if (odd) {
        reason |= DISAGREEMENT;
    }
    bits[FLAGS * n + i] = reason;
    let keep = select(0.0, 1.0, reason == 0u);
    work[SUPPORT * n + i] = keep;
    work[RE * n + i] = (pr + qr) * keep;
    work[IM * n + i] = (pi + qi) * keep;
}

fn wrapped_diff(a: f32, b: f32) -> f32 {
    let d = abs(a - b);
    return min(d, TAU - d);
}

// Whether pixels a and b lie on one surface (src/decode/connect.rs, colour sequences).
fn linked(a: u32, b: u32) -> bool {
    let n = P.n;
    if (!(work[SUPPORT * n + a] > 0.0 && work[SUPPORT * n + b] > 0.0)) {
        return false;
    }
    for (var f = 0u; f < 3u; f++) {
        if (wrapped_diff(solved[(PHASE + f) * n + a], solved[(PHASE + f) * n + b]) > P.edge_phase_rad) {
            return false;
        }
    }
    let red1 = max(solved[COLOUR * n + a], 0.0);
    let blue1 = max(solved[(COLOUR + 2u) * n + a], 0.0);
    let red2 = max(solved[COLOUR * n + b], 0.0);
    let blue2 = max(solved[(COLOUR + 2u) * n + b], 0.0);
    let sum1 = red1 + max(solved[(COLOUR + 1u) * n + a], 0.0) + blue1;
    let sum2 = red2 + max(solved[(COLOUR + 1u) * n + b], 0.0) + blue2;
    let tol = P.edge_chromaticity * sum1 * sum2 + 6.0 * max(sum1, sum2);
    return (abs(sum1 - sum2) <= P.edge_colour_ratio * max(sum1, sum2) + 6.0)
        && (abs(red1 * sum2 - red2 * sum1) <= tol)
        && (abs(blue1 * sum2 - blue2 * sum1) <= tol);
}

@compute @workgroup_size(8, 8)
fn connect(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= P.width || id.y >= P.height) {
        return;
    }
    let i = id.y * P.width + id.x;
    var link = 0u;
    if (id.x + 1u < P.width && linked(i, i + 1u)) {
        link |= RIGHT;
    }
    if (id.y + 1u < P.height && linked(i, i + P.width)) {
        link |= DOWN;
    }
    bits[LINKS * P.n + i] = link;
}

fn gain_of(i: u32, bit: u32, decay: f32) -> f32 {
    return select(0.0, decay, (bits[LINKS * P.n + i] & bit) != 0u);
}

// The recursions run in segments of SEGMENT pixels, one invocation each (36 000 at 1920×1200
// instead of one per row or column), each warmed up on `halo` pixels beyond its ends, chosen by
// the host so that decay^halo is below f32 resolution (52 at 0.7, 83 at 0.8, 114 at 0.85): the
// result is that of one recursion over the whole line. Every segment reads the pass's input, which the
// pass does not modify, and writes only its own pixels.
const SEGMENT: u32 = 64u;

// The running sum `s` carried from pixel `src_px` to its linked neighbour `dst_px`: scaled by the
// decay, and, when transported, its phasor turned by the unit angle's change between them,
// wrap(φ_0(dst_px) − φ_0(src_px))·unit_per_fine (1/n; 0: not turned; the series to θ³, as on
// the CPU; |θ| < π/n).
fn carry(s: vec3<f32>, src_px: u32, dst_px: u32, g: f32, unit_per_fine: f32) -> vec3<f32> {
    if (unit_per_fine == 0.0) {
        return g * s;
    }
    let d = solved[PHASE * P.n + dst_px] - solved[PHASE * P.n + src_px];
    let theta = (d - TAU * round(d / TAU)) * unit_per_fine;
    let t2 = theta * theta;
    let c = g * (1.0 - 0.5 * t2);
    let sn = g * theta * (1.0 - t2 / 6.0);
    return vec3<f32>(c * s.x - sn * s.y, sn * s.x + c * s.y, g * s.z);
}

// Forward + backward recursion of three planes of `work` along one segment of pixels
// `first + k·step`, k in [start, end) of a line of `len`, from planes `src` into planes `dst`, at
// `decay`, warmed up on `halo` pixels, the first two planes turned along the fine phase when
// `unit_per_fine` (1/n) is not 0.
fn recurse_segment(first: u32, step: u32, len: u32, start: u32, end: u32, bit: u32, src: u32,
                   dst: u32, decay: f32, halo: u32, unit_per_fine: f32) {
    let n = P.n;
    let warm = select(start - halo, 0u, start < halo);
    var f = vec3<f32>(0.0);
    for (var k = warm; k < end; k++) {
        let i = first + k * step;
        let v = vec3<f32>(work[src * n + i], work[(src + 1u) * n + i], work[(src + 2u) * n + i]);
        if (k > warm) {
            f = v + carry(f, i - step, i, gain_of(i - step, bit, decay), unit_per_fine);
        } else {
            f = v;
        }
        if (k >= start) {
            work[dst * n + i] = f.x;
            work[(dst + 1u) * n + i] = f.y;
            work[(dst + 2u) * n + i] = f.z;
        }
    }
    let stop = min(end + halo, len);
    var b = vec3<f32>(0.0);
    for (var k = stop; k > start; k--) {
        let i = first + (k - 1u) * step;
        let v = vec3<f32>(work[src * n + i], work[(src + 1u) * n + i], work[(src + 2u) * n + i]);
        if (k < stop) {
            b = v + carry(b, i + step, i, gain_of(i, bit, decay), unit_per_fine);
        } else {
            b = v;
        }
        if (k <= end) {
            work[dst * n + i] += b.x - v.x;
            work[(dst + 1u) * n + i] += b.y - v.y;
            work[(dst + 2u) * n + i] += b.z - v.z;
        }
    }
}

// Along the rows: invocation `id` is (segment, row); from planes `src` into `dst`.
fn horizontal_segment(id: u32, src: u32, dst: u32, decay: f32, halo: u32, unit_per_fine: f32) {
    let segments = (P.width + SEGMENT - 1u) / SEGMENT;
    let y = id / segments;
    if (y >= P.height) {
        return;
    }
    let start = (id % segments) * SEGMENT;
    let end = min(start + SEGMENT, P.width);
    recurse_segment(y * P.width, 1u, P.width, start, end, RIGHT, src, dst, decay, halo,
        unit_per_fine);
}

// Down the columns: invocation `id` is (column, segment), neighbouring invocations on
// neighbouring columns; from planes `src` into `dst`.
fn vertical_segment(id: u32, src: u32, dst: u32, decay: f32, halo: u32, unit_per_fine: f32) {
    let x = id % P.width;
    let start = (id / P.width) * SEGMENT;
    if (start >= P.height) {
        return;
    }
    let end = min(start + SEGMENT, P.height);
    recurse_segment(x, P.width, P.height, start, end, DOWN, src, dst, decay, halo,
        unit_per_fine);
}

// The unit phasor's average: (re, im, support) along the rows into tmp, down the columns back.
@compute @workgroup_size(64)
fn horizontal(@builtin(global_invocation_id) id: vec3<u32>) {
    horizontal_segment(id.x, RE, TMP, P.decay, P.halo, P.unit_per_fine);
}

@compute @workgroup_size(64)
fn vertical(@builtin(global_invocation_id) id: vec3<u32>) {
    vertical_segment(id.x, TMP, RE, P.decay, P.halo, P.unit_per_fine);
}

// Eq. 8 for one frequency: the unwrapped coordinate and the rounding residual.
fn unwrap_one(xc: f32, phase: f32, f: f32) -> vec2<f32> {
    let arg = (xc * f - phase) * (1.0 / TAU);
    let k = round(arg);
    return vec2<f32>((TAU * k + phase) / f, abs(arg - k));
}

// Pixel i's three maps unwrapped around the coarse coordinate `xc` and combined by inverse
// variance (src/decode/unwrap.rs, CpsMaps): (combined, largest rounding residual, the weighted
// spread Σ w·(x − x̄)² over the noise variance's scale, 0).
fn cps_unwrap(xc: f32, i: u32) -> vec4<f32> {
    let n = P.n;
    let u0 = unwrap_one(xc, solved[PHASE * n + i], P.freq.x);
    let u1 = unwrap_one(xc, solved[(PHASE + 1u) * n + i], P.freq.y);
    let u2 = unwrap_one(xc, solved[(PHASE + 2u) * n + i], P.freq.z);
    let k = P.freq / P.gain;
    let k2 = k * k;
    let a = vec3<f32>(solved[AMP * n + i], solved[(AMP + 1u) * n + i], solved[(AMP + 2u) * n + i]);
    let wt = k2 * a * a;
    let total = wt.x + wt.y + wt.z;
    var combined = u0.x;
    if (total > 0.0) {
        combined = (u0.x * wt.x + u1.x * wt.y + u2.x * wt.z) / total;
    }
    let d = vec3<f32>(u0.x, u1.x, u2.x) - combined;
    let spread = wt.x * d.x * d.x + wt.y * d.y * d.y + wt.z * d.z * d.z;
    return vec4<f32>(combined, max(u0.y, max(u1.y, u2.y)), spread, 0.0);
}

@compute @workgroup_size(8, 8)
fn unwrap(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= P.width || id.y >= P.height) {
        return;
    }
    let n = P.n;
    let i = id.y * P.width + id.x;
    var reason = bits[FLAGS * n + i];
    // The unit phasor's angle in [−π/2, 3π/2): the true f_1·x lies in [0, π).
    var angle = atan2_poly(work[IM * n + i], work[RE * n + i]);
    angle = select(angle, angle + TAU, angle < -0.5 * PI);
    let xc = angle * P.inv_f_unit;
    if (work[SUPPORT * n + i] < P.min_support) {
        reason |= LOW_SUPPORT;
    }
    if (motion_on()) {
        state[COARSE * n + i] = xc;
    }
    let maps = cps_unwrap(xc, i);
    let combined = maps.x;
    if (maps.y > P.max_rounding_residual) {
        reason |= UNWRAP_MARGIN;
    }
    let inv_noise2 = 1.0 / (P.camera_noise_gray * P.camera_noise_gray);
    if (maps.z * inv_noise2 > P.max_disagreement_chi2) {
        reason |= DISAGREEMENT;
    }
    if (!(combined >= -0.5 && combined < P.x_max)) {
        reason |= OUT_OF_RANGE;
    }
    bits[FLAGS * n + i] = reason;
    work[COORD * n + i] = combined;
}

// Whether pixel i and its neighbour j (linked by `bit` of pixel `owner`) disagree by more than
// half a fringe period; only pixels valid after unwrapping count.
fn jumps_to(i: u32, j: u32, owner: u32, bit: u32) -> bool {
    let n = P.n;
    let both_valid = bits[FLAGS * n + i] == 0u && bits[FLAGS * n + j] == 0u;
    let link = (bits[LINKS * n + owner] & bit) != 0u;
    return both_valid && link
        && abs(work[COORD * n + i] - work[COORD * n + j]) > P.half_period_px;
}

@compute @workgroup_size(8, 8)
fn jumps(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= P.width || id.y >= P.height) {
        return;
    }
    let n = P.n;
    let w = P.width;
    let i = id.y * w + id.x;
    var jump = false;
    if (P.check_jumps != 0u) {
        if (id.x + 1u < w) {
            jump = jump || jumps_to(i, i + 1u, i, RIGHT);
        }
        if (id.x > 0u) {
            jump = jump || jumps_to(i, i - 1u, i - 1u, RIGHT);
        }
        if (id.y + 1u < P.height) {
            jump = jump || jumps_to(i, i + w, i, DOWN);
        }
        if (id.y > 0u) {
            jump = jump || jumps_to(i, i - w, i - w, DOWN);
        }
    }
    bits[FINAL * n + i] = bits[FLAGS * n + i] | select(0u, ORDER_JUMP, jump);
}
