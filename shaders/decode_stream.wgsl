// The GPU decode's links between the windows of a stream and its noise estimates, appended to
// decode.wgsl and decode_motion.wgsl as one module (their constants and buffers are used here):
//
//   noise_grid        e²/v of stage 1's phasors on the grid the CPU's noise estimate samples
//                     (src/decode/motion_noise.rs), for the motion model's significance test;
//                     the host reads the grid back and takes the library's median
//   noise_grid_final  the same on the final planes, with or without the model, for the host's
//                     mixed-pixel stage (src/decode/edges.rs)
//   settle            the rounding margin settled by the pixel's own recent past (siding with
//                     either of stage 2's averages where they contradicted each other), then
//                     the coordinate moved from the frames' mean to the window's centre time
//   temporal          fringe-order jumps in time (src/decode/temporal.rs); the references carried
//                     on; the patch velocity forgotten where the pixel's signal or neighbourhood
//                     failed (DecodeOutput::clear_motion_where_invalid)
//
// The references (RECENT, AGE) and the patch velocities (PATCH_VELOCITY, PATCH_BITS) are planes of
// `state` kept between windows; the host tells whether the previous window was the one just
// before (M[M_CONSECUTIVE]).

// The grid of the noise estimate (src/decode/motion_noise.rs): e²/v of each grid pixel whose
// flags (plane `flag_plane` of `bits`) are 0, −1 elsewhere, in grid order, into `grid`.
fn grid_residual(index: u32, flag_plane: u32) {
    let half = GRID_STEP / 2u;
    if (P.width <= half || P.height <= half) {
        return;
    }
    let gw = (P.width - half + GRID_STEP - 1u) / GRID_STEP;
    let gh = (P.height - half + GRID_STEP - 1u) / GRID_STEP;
    if (index >= gw * gh) {
        return;
    }
    let n = P.n;
    let x = half + (index % gw) * GRID_STEP;
    let y = half + (index / gw) * GRID_STEP;
    let i = y * P.width + x;
    var scaled = -1.0;
    if (bits[flag_plane * n + i] == 0u) {
        let z0 = phasor_of(solved[PHASE * n + i], solved[AMP * n + i]);
        let z1 = phasor_of(solved[(PHASE + 1u) * n + i], solved[(AMP + 1u) * n + i]);
        let z2 = phasor_of(solved[(PHASE + 2u) * n + i], solved[(AMP + 2u) * n + i]);
        let c = cheb3(z0, z1, z2);
        let e = atan2_poly(c.t.y, c.t.x);
        let s = e * e / c.var_over_noise;
        if (finite(s)) {
            scaled = s;
        }
    }
    grid[index] = scaled;
}

// Stage 1's noise, for the motion model's significance test.
@compute @workgroup_size(64)
fn noise_grid(@builtin(global_invocation_id) id: vec3<u32>) {
    grid_residual(id.x, FLAGS);
}

// The final planes' noise, for the host's mixed-pixel stage (src/decode/edges.rs), with or
// without the model.
@compute @workgroup_size(64)
fn noise_grid_final(@builtin(global_invocation_id) id: vec3<u32>) {
    grid_residual(id.x, FINAL);
}

// The rounding margin settled by the pixel's own recent past (src/decode/temporal.rs), then
// the coordinate moved from the frames' mean to the window's centre time.
@compute @workgroup_size(8, 8)
fn settle(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= P.width || id.y >= P.height) {
        return;
    }
    let n = P.n;
    let i = id.y * P.width + id.x;
    let older = min(state[AGE * n + i] + 1.0, TOO_OLD);
    if (M[M_CHECK_TIME] != 0.0 && M[M_CONSECUTIVE] != 0.0 && bits[FLAGS * n + i] == UNWRAP_MARGIN
        && older <= MAX_AGE_WINDOWS) {
        let predicted = state[RECENT * n + i] + known_velocity(i) * M[M_INTERVAL];
        let temporal = cps_unwrap(predicted, i);
        var spatial = cps_unwrap(state[COARSE * n + i], i);
        // Where stage 2's two averages contradicted each other, the past may side with the wide
        // one (wide_select left its coarse coordinate in UE).
        if (abs(spatial.x - temporal.x) >= 0.5 && M[M_WIDE_DECAY] != 0.0
            && work[KE * n + i] != 0.0) {
            spatial = cps_unwrap(work[UE * n + i], i);
        }
        if (abs(spatial.x - temporal.x) < 0.5 && temporal.y <= P.max_rounding_residual) {
            bits[FLAGS * n + i] = 0u;
            work[COORD * n + i] = spatial.x;
        }
    }
    work[COORD * n + i] -= state[ACCELERATION * n + i] * (0.5 * M[M_MEAN_TAU2]);
}

// The patch's velocity where the model kept it (significant and known), else rest.
fn known_velocity(i: u32) -> f32 {
    let b = u32(state[PATCH_BITS * P.n + i]);
    return select(0.0, state[PATCH_VELOCITY * P.n + i], (b & (MOVING | KNOWN)) == (MOVING | KNOWN));
}

// Fringe-order jumps in time; the references carried on; the patch velocity forgotten where the
// pixel's own signal or neighbourhood failed (DecodeOutput::clear_motion_where_invalid).
@compute @workgroup_size(8, 8)
fn temporal(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= P.width || id.y >= P.height) {
        return;
    }
    let n = P.n;
    let i = id.y * P.width + id.x;
    var flags = bits[FINAL * n + i];
    if (M[M_CHECK_TIME] != 0.0) {
        let older = select(TOO_OLD, min(state[AGE * n + i] + 1.0, TOO_OLD), M[M_CONSECUTIVE] != 0.0);
        let c = work[COORD * n + i];
        let predicted = state[RECENT * n + i] + known_velocity(i) * M[M_INTERVAL];
        let moved = c - predicted;
        let period = 2.0 * P.half_period_px;
        let periods = round(moved * (1.0 / period));
        let off = abs(moved - periods * period);
        let valid = flags == 0u;
        let jumped = valid && (older <= MAX_AGE_WINDOWS) && (periods != 0.0)
            && (off <= older * M[M_MAX_STEP]);
        if (jumped) {
            flags |= ORDER_JUMP;
        }
        let keep = valid && !jumped;
        state[RECENT * n + i] = select(predicted, c, keep);
        state[AGE * n + i] = select(older, 0.0, keep);
    }
    bits[FINAL * n + i] = flags;
    if ((flags & (LOW_AMPLITUDE | SATURATED | DISAGREEMENT | LOW_SUPPORT)) != 0u) {
        state[PATCH_BITS * n + i] = f32(u32(state[PATCH_BITS * n + i]) & MOVING);
    }
}
