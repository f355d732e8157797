// The motion model of the GPU decode (src/decode/motion*.rs), appended to decode.wgsl as one
// module (decode_stream.wgsl follows: the noise grids and the links between windows): one velocity u and one brightness change κ per connected patch,
// shared by the three frequencies, in Gauss–Newton steps from the still solution. Per window,
// when the model is on (M[M_ON] = 1):
//
//   solve         (decode.wgsl) writes each pixel's evidence at rest instead of its unit phasor
//   connect       links from the stage-1 phases (as the CPU: the support plane holds kk then)
//   noise_grid    e²/v on the grid the CPU's noise estimate samples; the host takes the median
//                 (noise_grid_final does the same on the final planes, with or without the
//                 model, for the host's mixed-pixel stage)
//   step_predicted  after the window just before: the pixels whose patch moved there start
//                 from that velocity (no sums), the others keep stage 1's evidence; every
//                 configured step then refines
//   per step      step_horizontal/step_vertical: the evidence's edge-aware sums (plain, at the
//                 model's decay) of (uu, uk, kk) and (ue, ke, count); then step_rest[_last] or
//                 step_refine[_last]: the patch's (u, κ), the correction, the next evidence
//                 or, on the last step, the unit phasor, the reasons and the acceleration
//   connect, horizontal, vertical, unwrap   as without the model, on the corrected phasors;
//                 with the moving pixels' wider average, wide_copy before horizontal keeps the
//                 corrected unit phasor in the evidence planes, and after vertical
//                 wide_horizontal/wide_vertical sum it (carried along the fine phase) and
//                 wide_select gives it to every pixel with a velocity (or refuses the pixel
//                 where the narrow one is sure of other fringe orders)
//   settle        (decode_stream.wgsl)
//   jumps         (decode.wgsl)
//   temporal      (decode_stream.wgsl)
//
// The CPU's NaNs are explicit here: a patch velocity is known or not (bit KNOWN of its plane),
// a reference has an age (none: the age of too old). The comments of the CPU code say why each
// step is as it is; this file only mirrors it.

// The basis and the constants (MotionBasis::packed), then the window's values
// (ui/src/gpu_decode/motion.rs writes them).
@group(0) @binding(6) var<storage, read> M: array<f32>;
// The model's planes (offsets below, in units of n); some are kept between windows.
@group(0) @binding(7) var<storage, read_write> state: array<f32>;
// The noise grid's values (grid_residual), read back by the host.
@group(0) @binding(8) var<storage, read_write> grid: array<f32>;

const M_P: u32 = 0u;
const M_Q: u32 = 12u;
const M_TAU: u32 = 24u;
const M_DM: u32 = 27u;
const M_N0: u32 = 31u;
const M_V: u32 = 35u;
const M_OFFSET_ROW: u32 = 37u;
const M_D: u32 = 40u;
const M_UNMIX: u32 = 46u;
const M_MIX: u32 = 55u;
const M_BIAS: u32 = 64u;
const M_MAX_KAPPA: u32 = 67u;
const M_MAX_U: u32 = 68u;
const M_INTERVAL: u32 = 69u;
const M_MEAN_TAU2: u32 = 70u;
const M_MAX_TURN: u32 = 71u;
const M_MIN_DET: u32 = 72u;
const M_SIGNIFICANCE: u32 = 73u;
const M_MIN_SHIFT: u32 = 74u;
// The camera noise variance the evidence at rest is corrected for (MotionBasis::noise_bias).
const M_BIAS_NOISE2: u32 = 75u;
// The window's values.
const M_ON: u32 = 76u;
const M_PRIOR_U: u32 = 77u;
const M_PRIOR_K: u32 = 78u;
const M_INV_NOISE2: u32 = 79u;
const M_INV_SINCE: u32 = 80u;
const M_MAX_DU: u32 = 81u;
const M_SHIFT_PER_DU: u32 = 82u;
const M_CONSECUTIVE: u32 = 83u;
const M_MAX_STEP: u32 = 84u;
const M_DECAY: u32 = 85u;
const M_HALO: u32 = 86u;
const M_CHECK_TIME: u32 = 87u;
// The moving pixels' wider unit-phasor average (src/decode/smooth_moving.rs): its decay per
// pixel, its warm-up and 1/n (0: none).
const M_WIDE_DECAY: u32 = 88u;
const M_WIDE_HALO: u32 = 89u;
const M_WIDE_UNIT_PER_FINE: u32 = 90u;
// The weight of each moving pixel's brightness change from its lit offsets in the previous
// window and this one, beside its patch's, on the last refining step (0: none).
const M_OFFSET_WEIGHT: u32 = 91u;

// Planes of `work` beyond decode.wgsl's: the evidence (ue, ke, count) and its sums' scratch.
const UE: u32 = 7u;
const KE: u32 = 8u;
const COUNT: u32 = 9u;
const EVIDENCE_TMP: u32 = 10u;
// Planes of `state`.
const VELOCITY: u32 = 0u;
const BRIGHTNESS: u32 = 1u;
const ACCELERATION: u32 = 2u;
const COARSE: u32 = 3u;
// Kept between windows.
const PATCH_VELOCITY: u32 = 4u;
const PATCH_BITS: u32 = 5u;
const RECENT: u32 = 6u;
const AGE: u32 = 7u;
// The sum of each pixel's lit offsets in the last window (src/decode/motion_moving.rs).
const LIT_SUM: u32 = 8u;

// The weight of a predicted start's written evidence (motion_predict::PREDICTION_WEIGHT).
const PREDICTION_WEIGHT: f32 = 1.0e9;
const MOTION: u32 = 128u;
const MOVING: u32 = 1u;
const KNOWN: u32 = 2u;
const MAX_AGE_WINDOWS: f32 = 2.0;
const TOO_OLD: f32 = 255.0;
const MAX_F32: f32 = 3.40282347e38;
const GRID_STEP: u32 = 7u;

fn finite(x: f32) -> bool {
    return abs(x) <= MAX_F32;
}

fn motion_on() -> bool {
    return M[M_ON] != 0.0;
}

fn mat(base: u32) -> vec4<f32> {
    return vec4<f32>(M[base], M[base + 1u], M[base + 2u], M[base + 3u]);
}

fn apply(m: vec4<f32>, z: vec2<f32>) -> vec2<f32> {
    return vec2<f32>(m.x * z.x + m.y * z.y, m.z * z.x + m.w * z.y);
}

fn cross2(a: vec2<f32>, b: vec2<f32>) -> f32 {
    return a.x * b.y - a.y * b.x;
}

// The CPU's series (src/decode/fastmath.rs): (sin, cos).
fn sin_cos_small(x: f32) -> vec2<f32> {
    let x2 = x * x;
    let s = x * (1.0 + x2 * (-1.0 / 6.0 + x2 * (1.0 / 120.0 + x2 * (-1.0 / 5040.0
        + x2 * (1.0 / 362880.0 - x2 / 39916800.0)))));
    let c = 1.0 + x2 * (-0.5 + x2 * (1.0 / 24.0 + x2 * (-1.0 / 720.0 + x2 * (1.0 / 40320.0
        + x2 * (-1.0 / 3628800.0 + x2 / 479001600.0)))));
    return vec2<f32>(s, c);
}

fn sin_cos_phase(x: f32) -> vec2<f32> {
    let h = sin_cos_small(0.5 * (x - PI));
    return vec2<f32>(-2.0 * h.x * h.y, 2.0 * h.x * h.x - 1.0);
}

fn phasor_of(phase: f32, amp: f32) -> vec2<f32> {
    let sc = sin_cos_phase(phase);
    return vec2<f32>(amp * sc.y, amp * sc.x);
}

// A pixel's Chebyshev quantities (src/decode/motion_evidence.rs).
struct Cheb {
    phase: vec3<f32>,
    amp: vec3<f32>,
    unit: vec2<f32>,
    t: vec2<f32>,
    var_over_noise: f32,
}

fn cheb_of(z0: vec2<f32>, z1: vec2<f32>, z2: vec2<f32>, phase: vec3<f32>, amp: vec3<f32>) -> Cheb {
    let pr = z0.x * z1.x + z0.y * z1.y;
    let pi = z0.y * z1.x - z0.x * z1.y;
    let qr = z1.x * z2.x + z1.y * z2.y;
    let qi = z1.y * z2.x - z1.x * z2.y;
    let g = P.gain * P.gain * vec3<f32>(1.0, 4.0, 1.0);
    let a2 = amp * amp;
    return Cheb(
        phase,
        amp,
        vec2<f32>(pr + qr, pi + qi),
        vec2<f32>(pr * qr + pi * qi, pi * qr - pr * qi),
        g.x / a2.x + g.y / a2.y + g.z / a2.z,
    );
}

fn cheb3(z0: vec2<f32>, z1: vec2<f32>, z2: vec2<f32>) -> Cheb {
    let phase = vec3<f32>(phase_0_tau(z0.y, z0.x), phase_0_tau(z1.y, z1.x), phase_0_tau(z2.y, z2.x));
    let amp = vec3<f32>(
        sqrt(z0.x * z0.x + z0.y * z0.y),
        sqrt(z1.x * z1.x + z1.y * z1.y),
        sqrt(z2.x * z2.x + z2.y * z2.y),
    );
    return cheb_of(z0, z1, z2, phase, amp);
}

fn disagreement_limit() -> f32 {
    return P.max_disagreement_chi2 * P.camera_noise_gray * P.camera_noise_gray;
}

fn inconsistent(c: Cheb) -> bool {
    let sin2 = c.t.y * c.t.y / (c.t.x * c.t.x + c.t.y * c.t.y);
    return (c.t.x < 0.0) || (sin2 > disagreement_limit() * c.var_over_noise);
}

// `inconsistent` of phasors whose phases are not needed (the CPU's `disagrees`); a NaN
// disagrees.
fn disagrees(z0: vec2<f32>, z1: vec2<f32>, z2: vec2<f32>) -> bool {
    let c = cheb_of(z0, z1, z2, vec3<f32>(0.0), vec3<f32>(length(z0), length(z1), length(z2)));
    let sin2 = c.t.y * c.t.y / (c.t.x * c.t.x + c.t.y * c.t.y);
    return !((c.t.x >= 0.0) && (sin2 <= disagreement_limit() * c.var_over_noise));
}

// The projector-lit offset of each slot.
fn lit_offsets(offsets: vec3<f32>) -> vec3<f32> {
    let lit = offsets - vec3<f32>(M[M_BIAS], M[M_BIAS + 1u], M[M_BIAS + 2u]);
    var out: vec3<f32>;
    for (var s = 0u; s < 3u; s++) {
        let r = M_UNMIX + 3u * s;
        out[s] = M[r] * lit.x + M[r + 1u] * lit.y + M[r + 2u] * lit.z;
    }
    return out;
}

fn v_vec() -> vec2<f32> {
    return vec2<f32>(M[M_V], M[M_V + 1u]);
}

// A slot's derivatives: (∂z/∂u, ∂z/∂κ) as (xy, zw).
fn slope_at_rest(z: vec2<f32>, lit: f32, f: f32) -> vec4<f32> {
    let g = apply(mat(M_DM), z);
    let nz = apply(mat(M_N0), z);
    let v = v_vec();
    return vec4<f32>(f * g, nz + lit * v);
}

struct Evidence {
    uu: f32,
    uk: f32,
    kk: f32,
    ue: f32,
    ke: f32,
}

// The evidence in absolute terms at the (u, κ) `at` the phasors were corrected with.
fn evidence_with(z: array<vec2<f32>, 3>, dz: array<vec4<f32>, 3>, c: Cheb, keep: f32, at: vec2<f32>) -> Evidence {
    var du = 0.0;
    var dk = 0.0;
    var zz = z;
    var dd = dz;
    for (var s = 0u; s < 3u; s++) {
        let weight = select(1.0, -2.0, s == 1u);
        let zs = zz[s];
        let inv = 1.0 / (zs.x * zs.x + zs.y * zs.y);
        du += weight * cross2(zs, dd[s].xy) * inv;
        dk += weight * cross2(zs, dd[s].zw) * inv;
    }
    let e = atan2_poly(c.t.y, c.t.x) + du * at.x + dk * at.y;
    let w = keep / c.var_over_noise;
    if (finite(w) && finite(du) && finite(dk) && keep > 0.0) {
        return Evidence(w * du * du, w * du * dk, w * dk * dk, w * du * e, w * dk * e);
    }
    return Evidence(0.0, 0.0, 0.0, 0.0, 0.0);
}

fn write_evidence(i: u32, ev: Evidence, keep: f32) {
    let n = P.n;
    work[RE * n + i] = ev.uu;
    work[IM * n + i] = ev.uk;
    work[SUPPORT * n + i] = ev.kk;
    work[UE * n + i] = ev.ue;
    work[KE * n + i] = ev.ke;
    work[COUNT * n + i] = keep;
}

// What a slot's own noise adds to (D_u·e, D_κ·e) on average, over the noise variance
// (MotionBasis::noise_bias): the slope terms' turn with the phase times the slot's phase
// variance.
fn slot_noise_bias(z: vec2<f32>, lit: f32, f: f32, gain2: f32) -> vec2<f32> {
    let jz = vec2<f32>(-z.y, z.x);
    let a2 = z.x * z.x + z.y * z.y;
    let scale = gain2 / (a2 * a2);
    let turn_g = cross2(jz, apply(mat(M_DM), z)) + cross2(z, apply(mat(M_DM), jz));
    let n = apply(mat(M_N0), z) + lit * v_vec();
    let turn_n = cross2(jz, n) + cross2(z, apply(mat(M_N0), jz));
    return vec2<f32>(f * turn_g * scale, turn_n * scale);
}

// A still pixel's evidence (stage 1, and a step's pixels at rest), less what its own noise
// adds on average at the basis's noise level (motion_evidence::evidence).
fn evidence_at_rest(z0: vec2<f32>, z1: vec2<f32>, z2: vec2<f32>, c: Cheb, lit: vec3<f32>, keep: f32) -> Evidence {
    let z = array<vec2<f32>, 3>(z0, z1, z2);
    let dz = array<vec4<f32>, 3>(
        slope_at_rest(z0, lit.x, P.freq.x),
        slope_at_rest(z1, lit.y, P.freq.y),
        slope_at_rest(z2, lit.z, P.freq.z),
    );
    var ev = evidence_with(z, dz, c, keep, vec2<f32>(0.0));
    let g = P.gain * P.gain * vec3<f32>(1.0, 4.0, 1.0);
    let bias = slot_noise_bias(z0, lit.x, P.freq.x, g.x) + slot_noise_bias(z1, lit.y, P.freq.y, g.y)
        + slot_noise_bias(z2, lit.z, P.freq.z, g.z);
    let w = M[M_BIAS_NOISE2] * keep / c.var_over_noise;
    let b = w * bias;
    if (finite(b.x) && finite(b.y)) {
        ev.ue -= b.x;
        ev.ke -= b.y;
    }
    return ev;
}

// Stage 1's part (called by `solve`): the still pixel's evidence from its solved phasors.
fn stage1_evidence(i: u32, z0: vec2<f32>, z1: vec2<f32>, z2: vec2<f32>, c: Cheb, offsets: vec3<f32>, keep: f32) {
    write_evidence(i, evidence_at_rest(z0, z1, z2, c, lit_offsets(offsets), keep), keep);
}

// The model's response M(g) + κ·N(g) (src/decode/motion_basis.rs).
fn response(g: f32, kappa: f32) -> vec4<f32> {
    var m = vec4<f32>(0.0);
    let max_turn = M[M_MAX_TURN];
    for (var k = 0u; k < 3u; k++) {
        let tau = M[M_TAU + k];
        let sc = sin_cos_small(clamp(g * tau, -max_turn, max_turn));
        let scale = 1.0 + kappa * tau;
        m += (sc.y * scale) * mat(M_P + 4u * k) + (sc.x * scale) * mat(M_Q + 4u * k);
    }
    return m;
}

struct Linearised {
    inverse: vec4<f32>,
    db: vec4<f32>,
    n: vec4<f32>,
    det: f32,
    within: bool,
}

fn linearised(g: f32, kappa: f32) -> Linearised {
    var b = vec4<f32>(0.0);
    var db = vec4<f32>(0.0);
    var nm = vec4<f32>(0.0);
    var within = true;
    let max_turn = M[M_MAX_TURN];
    for (var k = 0u; k < 3u; k++) {
        let tau = M[M_TAU + k];
        let turn = g * tau;
        within = within && (abs(turn) <= max_turn);
        let sc = sin_cos_small(clamp(turn, -max_turn, max_turn));
        let scale = 1.0 + kappa * tau;
        let p = mat(M_P + 4u * k);
        let q = mat(M_Q + 4u * k);
        let rotated = sc.y * p + sc.x * q;
        b += scale * rotated;
        nm += tau * rotated;
        db += (scale * tau) * (sc.y * q - sc.x * p);
    }
    let det = b.x * b.w - b.y * b.z;
    return Linearised(vec4<f32>(b.w / det, -b.y / det, -b.z / det, b.x / det), db, nm, det, within);
}

struct PatchStep {
    u: f32,
    kappa: f32,
    solvable: bool,
    bright_ok: bool,
    moving: bool,
}

// The patch's (u, κ) from its summed evidence (src/decode/motion_correct.rs).
fn patch_step(i: u32, refine: bool) -> PatchStep {
    let n = P.n;
    let a = work[RE * n + i] + M[M_PRIOR_U];
    let b = work[IM * n + i];
    let c = work[SUPPORT * n + i] + M[M_PRIOR_K];
    let det = a * c - b * b;
    let ru = work[UE * n + i];
    let rk = work[KE * n + i];
    let solvable = (det > 0.0) && (work[COUNT * n + i] > 0.0);
    var u_new = 0.0;
    var k_new = 0.0;
    if (refine) {
        u_new = state[VELOCITY * n + i];
        k_new = state[BRIGHTNESS * n + i];
    }
    if (solvable) {
        u_new = (c * ru - b * rk) / det;
        k_new = (a * rk - b * ru) / det;
    }
    let max_k = M[M_MAX_KAPPA];
    let u = clamp(u_new, -M[M_MAX_U], M[M_MAX_U]);
    let kappa = clamp(k_new, -max_k, max_k);
    let significance = (a * u * u + 2.0 * b * u * kappa + c * kappa * kappa) * M[M_INV_NOISE2];
    return PatchStep(u, kappa, solvable, abs(k_new) <= max_k, significance > M[M_SIGNIFICANCE]);
}

struct SlotCorrection {
    still: vec2<f32>,
    z: vec2<f32>,
    dz: vec4<f32>,
    within: bool,
    det: f32,
}

fn correct_slot(refine: bool, f: f32, phase: f32, amp: f32, lit: f32, corrected_before: bool,
                u0: f32, k0: f32, moving: bool, u: f32, kappa: f32) -> SlotCorrection {
    let v = v_vec();
    var seen = phasor_of(phase, amp);
    if (refine && corrected_before) {
        seen = apply(response(f * u0, k0), seen) + (k0 * lit) * v;
    }
    let model = linearised(f * u, kappa);
    let zs = apply(model.inverse, seen - (kappa * lit) * v);
    let gz = apply(model.db, zs);
    let nz = apply(model.n, zs);
    let slopes = vec4<f32>(apply(model.inverse, f * gz), apply(model.inverse, nz + lit * v));
    return SlotCorrection(
        seen,
        select(seen, zs, moving),
        select(vec4<f32>(0.0), slopes, moving),
        model.within,
        model.det,
    );
}

// The sum of the slots' lit offsets, Σ_c (Σ_s unmix[s][c])·(o_c − bias_c), in the CPU's order.
fn lit_sum(offsets: vec3<f32>) -> f32 {
    var w = vec3<f32>(0.0);
    for (var c = 0u; c < 3u; c++) {
        w[c] = M[M_UNMIX + c] + M[M_UNMIX + 3u + c] + M[M_UNMIX + 6u + c];
    }
    let lit = offsets - vec3<f32>(M[M_BIAS], M[M_BIAS + 1u], M[M_BIAS + 2u]);
    return w.x * lit.x + w.y * lit.y + w.z * lit.z;
}

// The pixel's brightness change from its lit offsets in the previous window and this one, this
// window's without the fringe the previous step's correction leaked into them; x: the rate,
// y: 1 where it is taken (src/decode/motion_moving.rs, brightness_from_offsets).
fn brightness_from_offsets(i: u32, phases: vec3<f32>, amps: vec3<f32>, offsets: vec3<f32>,
                           corrected_before: bool, u0: f32, k0: f32) -> vec2<f32> {
    let leak = vec3<f32>(
        leak_of_slot(P.freq.x, corrected_before, u0, k0, phasor_of(phases.x, amps.x)),
        leak_of_slot(P.freq.y, corrected_before, u0, k0, phasor_of(phases.y, amps.y)),
        leak_of_slot(P.freq.z, corrected_before, u0, k0, phasor_of(phases.z, amps.z)),
    );
    var now_offsets = offsets;
    for (var j = 0u; j < 3u; j++) {
        let mix = vec3<f32>(M[M_MIX + j], M[M_MIX + 3u + j], M[M_MIX + 6u + j]);
        now_offsets[j] = offsets[j] - dot(mix, leak);
    }
    let now = lit_sum(now_offsets);
    let before = state[LIT_SUM * P.n + i];
    let rate = (now - before) * M[M_INV_SINCE] / now;
    let taken = (M[M_OFFSET_WEIGHT] > 0.0) && (M[M_INV_SINCE] > 0.0) && (before > 0.0)
        && (now > 0.0) && (abs(rate) <= M[M_MAX_KAPPA]);
    return vec2<f32>(rate, select(0.0, 1.0, taken));
}

// The fringe the motion leaks into a slot's offset.
fn leak_of_slot(f: f32, moving: bool, u: f32, kappa: f32, z: vec2<f32>) -> f32 {
    if (!moving) {
        return 0.0;
    }
    let g = f * u;
    let max_turn = M[M_MAX_TURN];
    var r = 0.0;
    for (var k = 0u; k < 3u; k++) {
        let tau = M[M_TAU + k];
        let sc = sin_cos_small(clamp(g * tau, -max_turn, max_turn));
        let d = vec2<f32>(M[M_D + 2u * k], M[M_D + 2u * k + 1u]);
        let scale = 1.0 + kappa * tau;
        let turned = vec2<f32>(d.x * sc.y + d.y * sc.x, -d.x * sc.x + d.y * sc.y);
        r += M[M_OFFSET_ROW + k] * (scale * dot(turned, z) - dot(d, z));
    }
    return r;
}

fn reason_bits(c: Cheb, flags: u32) -> u32 {
    let min_amp = min(c.amp.x, min(c.amp.y, c.amp.z));
    var reason = 0u;
    if (!(min_amp >= P.min_amplitude)) {
        reason |= LOW_AMPLITUDE;
    }
    reason |= flags & SATURATED;
    if (inconsistent(c)) {
        reason |= DISAGREEMENT;
    }
    return reason;
}

fn write_unit(i: u32, c: Cheb, reason: u32) {
    let n = P.n;
    let keep = select(0.0, 1.0, reason == 0u);
    state[ACCELERATION * n + i] *= keep;
    work[SUPPORT * n + i] = keep;
    work[RE * n + i] = c.unit.x * keep;
    work[IM * n + i] = c.unit.y * keep;
    bits[FLAGS * n + i] = reason;
}

// One Gauss–Newton step at pixel `i`: from rest or refining the previous step, the last or not.
fn motion_step(id: vec3<u32>, refine: bool, last: bool) {
    if (id.x >= P.width || id.y >= P.height) {
        return;
    }
    let n = P.n;
    let i = id.y * P.width + id.x;
    let p = patch_step(i, refine);
    if (last) {
        // The acceleration from the previous window's patch velocity, where known.
        let before = u32(state[PATCH_BITS * n + i]);
        let du = p.u - state[PATCH_VELOCITY * n + i];
        let accelerating = p.solvable
            && (p.moving || (before & MOVING) != 0u)
            && ((before & KNOWN) != 0u)
            && (M[M_INV_SINCE] > 0.0)
            && (abs(du) <= M[M_MAX_DU]);
        // All from the smallest shift up, none below half of it, in proportion between (the
        // CPU's `acceleration_onset`): no step in the coordinate at the threshold.
        let half = 0.5 * M[M_MIN_SHIFT];
        let onset = clamp((abs(du) * M[M_SHIFT_PER_DU] - half) / half, 0.0, 1.0);
        state[ACCELERATION * n + i] = select(0.0, du * M[M_INV_SINCE] * onset, accelerating);
        state[PATCH_VELOCITY * n + i] = select(0.0, p.u, p.solvable);
        state[PATCH_BITS * n + i] = f32(select(0u, MOVING, p.moving) | select(0u, KNOWN, p.solvable));
    }
    var u0 = 0.0;
    var k0 = 0.0;
    if (refine) {
        u0 = state[VELOCITY * n + i];
        k0 = state[BRIGHTNESS * n + i];
    }
    let corrected_before = refine && ((u0 != 0.0) || (k0 != 0.0));
    let phases = vec3<f32>(solved[PHASE * n + i], solved[(PHASE + 1u) * n + i], solved[(PHASE + 2u) * n + i]);
    let amps = vec3<f32>(solved[AMP * n + i], solved[(AMP + 1u) * n + i], solved[(AMP + 2u) * n + i]);
    let offsets = vec3<f32>(solved[COLOUR * n + i], solved[(COLOUR + 1u) * n + i], solved[(COLOUR + 2u) * n + i]);
    let lit = lit_offsets(offsets);
    if (!(p.moving || corrected_before)) {
        // A still pixel: its phasors are the still solution.
        let z0 = phasor_of(phases.x, amps.x);
        let z1 = phasor_of(phases.y, amps.y);
        let z2 = phasor_of(phases.z, amps.z);
        let c = cheb_of(z0, z1, z2, phases, amps);
        state[VELOCITY * n + i] = 0.0;
        state[BRIGHTNESS * n + i] = 0.0;
        if (last) {
            state[LIT_SUM * n + i] = lit_sum(offsets);
            write_unit(i, c, reason_bits(c, bits[FLAGS * n + i]));
        } else {
            let keep = select(0.0, 1.0, bits[FLAGS * n + i] == 0u);
            write_evidence(i, evidence_at_rest(z0, z1, z2, c, lit, keep), keep);
        }
        return;
    }
    // The full model.
    var u = 0.0;
    var kappa = 0.0;
    if (p.moving) {
        u = p.u;
        kappa = p.kappa;
        if (refine && last) {
            let measured = brightness_from_offsets(i, phases, amps, offsets, corrected_before, u0, k0);
            if (measured.y > 0.0) {
                let w = M[M_OFFSET_WEIGHT];
                kappa = (1.0 - w) * kappa + w * measured.x;
            }
        }
    }
    var moving = p.moving;
    var bright_ok = p.bright_ok;
    var s0 = correct_slot(refine, P.freq.x, phases.x, amps.x, lit.x, corrected_before, u0, k0, moving, u, kappa);
    var s1 = correct_slot(refine, P.freq.y, phases.y, amps.y, lit.y, corrected_before, u0, k0, moving, u, kappa);
    var s2 = correct_slot(refine, P.freq.z, phases.z, amps.z, lit.z, corrected_before, u0, k0, moving, u, kappa);
    // A step that breaks a consistent correction is refused for this pixel: it keeps the
    // previous step's, redone at (u0, k0) (src/decode/motion.rs).
    if (corrected_before && disagrees(s0.z, s1.z, s2.z)) {
        let k0s = correct_slot(refine, P.freq.x, phases.x, amps.x, lit.x, true, u0, k0, true, u0, k0);
        let k1s = correct_slot(refine, P.freq.y, phases.y, amps.y, lit.y, true, u0, k0, true, u0, k0);
        let k2s = correct_slot(refine, P.freq.z, phases.z, amps.z, lit.z, true, u0, k0, true, u0, k0);
        if (!disagrees(k0s.z, k1s.z, k2s.z)) {
            s0 = k0s;
            s1 = k1s;
            s2 = k2s;
            u = u0;
            kappa = k0;
            moving = true;
            bright_ok = true;
        }
    }
    let within = !moving || (bright_ok && s0.within && s1.within && s2.within);
    var worst_det = 1.0;
    if (moving) {
        worst_det = min(s0.det, min(s1.det, s2.det));
    }
    state[VELOCITY * n + i] = u;
    state[BRIGHTNESS * n + i] = kappa;
    let c = cheb3(s0.z, s1.z, s2.z);
    for (var s = 0u; s < 3u; s++) {
        solved[(PHASE + s) * n + i] = c.phase[s];
        solved[(AMP + s) * n + i] = c.amp[s];
    }
    if (!last) {
        let keep = select(0.0, 1.0, bits[FLAGS * n + i] == 0u);
        let rest = array<vec4<f32>, 3>(
            slope_at_rest(s0.still, lit.x, P.freq.x),
            slope_at_rest(s1.still, lit.y, P.freq.y),
            slope_at_rest(s2.still, lit.z, P.freq.z),
        );
        let dz = array<vec4<f32>, 3>(
            select(rest[0], s0.dz, moving),
            select(rest[1], s1.dz, moving),
            select(rest[2], s2.dz, moving),
        );
        let z = array<vec2<f32>, 3>(s0.z, s1.z, s2.z);
        write_evidence(i, evidence_with(z, dz, c, keep, vec2<f32>(u, kappa)), keep);
        return;
    }
    let leak = vec3<f32>(
        leak_of_slot(P.freq.x, moving, u, kappa, s0.z),
        leak_of_slot(P.freq.y, moving, u, kappa, s1.z),
        leak_of_slot(P.freq.z, moving, u, kappa, s2.z),
    );
    for (var j = 0u; j < 3u; j++) {
        // Row j of A, its columns in slot order.
        let mix = vec3<f32>(M[M_MIX + j], M[M_MIX + 3u + j], M[M_MIX + 6u + j]);
        solved[(COLOUR + j) * n + i] = offsets[j] - dot(mix, leak);
    }
    state[LIT_SUM * n + i] = lit_sum(vec3<f32>(solved[COLOUR * n + i], solved[(COLOUR + 1u) * n + i], solved[(COLOUR + 2u) * n + i]));
    var reason = reason_bits(c, bits[FLAGS * n + i]);
    if (!within || (worst_det < M[M_MIN_DET])) {
        reason |= MOTION;
    }
    let keep = select(0.0, 1.0, reason == 0u);
    state[VELOCITY * n + i] = u * keep;
    state[BRIGHTNESS * n + i] = kappa * keep;
    write_unit(i, c, reason);
}

// The first step of a window started from the previous one (src/decode/motion_predict.rs): a
// pixel whose patch moved there takes the evidence of that velocity as its sums, so strong that
// the patch solve returns it, and the step from rest; every other pixel keeps stage 1's evidence
// and no motion.
@compute @workgroup_size(8, 8)
fn step_predicted(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= P.width || id.y >= P.height) {
        return;
    }
    let n = P.n;
    let i = id.y * P.width + id.x;
    let u = known_velocity(i);
    if (u == 0.0) {
        state[VELOCITY * n + i] = 0.0;
        state[BRIGHTNESS * n + i] = 0.0;
        return;
    }
    work[RE * n + i] = PREDICTION_WEIGHT;
    work[IM * n + i] = 0.0;
    work[SUPPORT * n + i] = PREDICTION_WEIGHT;
    work[UE * n + i] = PREDICTION_WEIGHT * u;
    work[KE * n + i] = 0.0;
    work[COUNT * n + i] = 1.0;
    motion_step(id, false, false);
}

@compute @workgroup_size(8, 8)
fn step_rest(@builtin(global_invocation_id) id: vec3<u32>) {
    motion_step(id, false, false);
}

@compute @workgroup_size(8, 8)
fn step_rest_last(@builtin(global_invocation_id) id: vec3<u32>) {
    motion_step(id, false, true);
}

@compute @workgroup_size(8, 8)
fn step_refine(@builtin(global_invocation_id) id: vec3<u32>) {
    motion_step(id, true, false);
}

@compute @workgroup_size(8, 8)
fn step_refine_last(@builtin(global_invocation_id) id: vec3<u32>) {
    motion_step(id, true, true);
}

// The evidence's sums: (uu, uk, kk) then (ue, ke, count), plainly at the model's decay, each
// along the rows into tmp and down the columns back.
@compute @workgroup_size(64)
fn step_horizontal(@builtin(global_invocation_id) id: vec3<u32>) {
    let segments = (P.width + SEGMENT - 1u) / SEGMENT;
    let y = (id.x / segments) % P.height;
    let which = id.x / (segments * P.height);
    if (which >= 2u) {
        return;
    }
    let start = (id.x % segments) * SEGMENT;
    let end = min(start + SEGMENT, P.width);
    let first = y * P.width;
    let halo = u32(M[M_HALO]);
    if (which == 0u) {
        recurse_segment(first, 1u, P.width, start, end, RIGHT, RE, TMP, M[M_DECAY], halo, 0.0);
    } else {
        recurse_segment(first, 1u, P.width, start, end, RIGHT, UE, EVIDENCE_TMP, M[M_DECAY], halo, 0.0);
    }
}

@compute @workgroup_size(64)
fn step_vertical(@builtin(global_invocation_id) id: vec3<u32>) {
    let x = id.x % P.width;
    let segments = (P.height + SEGMENT - 1u) / SEGMENT;
    let segment = (id.x / P.width) % segments;
    let which = id.x / (P.width * segments);
    if (which >= 2u) {
        return;
    }
    let start = segment * SEGMENT;
    let end = min(start + SEGMENT, P.height);
    let halo = u32(M[M_HALO]);
    if (which == 0u) {
        recurse_segment(x, P.width, P.height, start, end, DOWN, TMP, RE, M[M_DECAY], halo, 0.0);
    } else {
        recurse_segment(x, P.width, P.height, start, end, DOWN, EVIDENCE_TMP, UE, M[M_DECAY], halo, 0.0);
    }
}

// The moving pixels' wider average of the unit phasor (src/decode/smooth_moving.rs): the
// corrected (re, im, support) copied into the evidence planes, which the last step has
// finished with, summed there along the fine phase, and taken where the velocity is not 0
// unless the narrow average is sure of other fringe orders.
@compute @workgroup_size(8, 8)
fn wide_copy(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= P.width || id.y >= P.height) {
        return;
    }
    let n = P.n;
    let i = id.y * P.width + id.x;
    work[UE * n + i] = work[RE * n + i];
    work[KE * n + i] = work[IM * n + i];
    work[COUNT * n + i] = work[SUPPORT * n + i];
}

@compute @workgroup_size(64)
fn wide_horizontal(@builtin(global_invocation_id) id: vec3<u32>) {
    horizontal_segment(id.x, UE, EVIDENCE_TMP, M[M_WIDE_DECAY], u32(M[M_WIDE_HALO]),
        M[M_WIDE_UNIT_PER_FINE]);
}

@compute @workgroup_size(64)
fn wide_vertical(@builtin(global_invocation_id) id: vec3<u32>) {
    vertical_segment(id.x, EVIDENCE_TMP, UE, M[M_WIDE_DECAY], u32(M[M_WIDE_HALO]),
        M[M_WIDE_UNIT_PER_FINE]);
}

@compute @workgroup_size(8, 8)
fn wide_select(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= P.width || id.y >= P.height) {
        return;
    }
    let n = P.n;
    let i = id.y * P.width + id.x;
    // Where the two contradict each other, the wide average's coarse coordinate stays in UE for
    // `settle`, marked by KE = 1; KE = 0 elsewhere.
    if (state[VELOCITY * n + i] == 0.0) {
        work[KE * n + i] = 0.0;
        return;
    }
    // The narrow average sure of its fringe orders and the wide one picking others: neither
    // (smooth_moving.rs, Agreement).
    let narrow = cps_unwrap(unit_coarse(work[RE * n + i], work[IM * n + i]), i);
    let sure = narrow.y <= P.max_rounding_residual && work[SUPPORT * n + i] >= P.min_support;
    if (sure) {
        let wide_px = unit_coarse(work[UE * n + i], work[KE * n + i]);
        let wide = cps_unwrap(wide_px, i);
        if (abs(wide.x - narrow.x) >= P.half_period_px) {
            bits[FLAGS * n + i] |= UNWRAP_MARGIN;
            work[UE * n + i] = wide_px;
            work[KE * n + i] = 1.0;
            return;
        }
    }
    work[RE * n + i] = work[UE * n + i];
    work[IM * n + i] = work[KE * n + i];
    work[SUPPORT * n + i] = work[COUNT * n + i];
    work[KE * n + i] = 0.0;
}

// The coarse coordinate of a unit phasor, as `unwrap` takes it.
fn unit_coarse(re: f32, im: f32) -> f32 {
    var angle = atan2_poly(im, re);
    angle = select(angle, angle + TAU, angle < -0.5 * PI);
    return angle * P.inv_f_unit;
}
