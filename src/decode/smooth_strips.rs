//! The vertical recursion of the edge-aware filters over whole columns, in parallel strips of
//! columns: every column's sum is exact (no warm-up is cut short), and how the image is split
//! among the threads changes no bit of it, so a session decodes to the same values on any
//! machine.
//!
//! Both the plain sum ([`super::smooth`]) and the transported one ([`super::smooth_transport`])
//! run here, each with its own step. The plain pass once ran in two blocks of rows, each warming
//! its recursion up on [`super::smooth::recursion_halo`] rows beyond its end: at 640×400 the
//! 200-row blocks warmed up on 52 or 83 more (a quarter to two fifths more steps), at 1920×1200
//! the 600-row blocks on 155 or 247 (a fifth to two fifths). Strips of columns need none.

use super::smooth::Planes;
use rayon::prelude::*;

/// The width of the strips for an image `w` pixels wide: two per thread, to even out the
/// threads' shares, of at least 16 columns (so each row's segment still vectorises).
pub(super) fn strip_width(w: usize) -> usize {
    w.div_ceil(2 * rayon::current_num_threads()).max(16).min(w)
}

/// The length of the state [`vertical_strips`] needs for an image `w` pixels wide, whatever
/// the number of threads: three planes of each strip's width, the last strip counted whole.
pub(crate) fn vertical_state_len(w: usize) -> usize {
    // strips × strip width < w + strip width ≤ 2·w.
    6 * w.max(1)
}

/// Where one vertical step of a strip stands: the step carries the state from row `from` to
/// row `to` (`to = from ± 1`), on the strip's columns from `x0`.
#[derive(Clone, Copy)]
pub(super) struct StripStep {
    pub(super) from: usize,
    pub(super) to: usize,
    pub(super) x0: usize,
}

/// Vertical recursion over whole columns, exactly, in parallel strips of columns: each strip runs down its columns (`F[y] = v[y] + carry(F[y − 1])`, written to the planes)
/// and back up (`B[y] = v[y] + carry(B[y + 1])`, adding `B − v`), reading each row's segment of
/// the horizontal pass's output once per direction. `step(state, v, links, at)` sets the state to
/// `v + carry(state)` across `links` (the DOWN bits between the two rows).
pub(super) fn vertical_strips<F>(p: &mut Planes<'_>, step: F)
where
    F: Fn([&mut [f32]; 3], [&[f32]; 3], &[u8], StripStep) + Sync,
{
    let w = p.w;
    let h = p.h;
    let n = w * h;
    if n == 0 {
        return;
    }
    let orig: &[f32] = &p.tmp[..3 * n];
    let connect = p.connect;
    let strip_w = strip_width(w);
    let strips = w.div_ceil(strip_w);
    // Every strip must get its state: a shorter buffer would leave the last strips out of the
    // zip below, silently.
    assert!(
        p.vertical_state.len() >= 3 * strips * strip_w,
        "the vertical state holds {} values, the strips need {}",
        p.vertical_state.len(),
        3 * strips * strip_w
    );
    // Each strip's segments of every row of the three planes (a few pointers per row).
    let mut segments: Vec<[Vec<&mut [f32]>; 3]> = (0..strips)
        .map(|_| [(); 3].map(|()| Vec::with_capacity(h)))
        .collect();
    for (k, plane) in p.planes.iter_mut().enumerate() {
        for row in plane[..n].chunks_mut(w) {
            for (s, segment) in row.chunks_mut(strip_w).enumerate() {
                segments[s][k].push(segment);
            }
        }
    }
    segments
        .into_par_iter()
        .zip(p.vertical_state.par_chunks_mut(3 * strip_w))
        .enumerate()
        .for_each(|(strip, ([mut p0, mut p1, mut p2], state))| {
            let x0 = strip * strip_w;
            let sw = strip_w.min(w - x0);
            let (s0, rest) = state.split_at_mut(sw);
            let (s1, rest) = rest.split_at_mut(sw);
            let s2 = &mut rest[..sw];
            let v = |k: usize, y: usize| &orig[k * n + y * w + x0..k * n + y * w + x0 + sw];
            let links = |y: usize| &connect[y * w + x0..y * w + x0 + sw];
            for y in 0..h {
                let a = [v(0, y), v(1, y), v(2, y)];
                if y == 0 {
                    s0.copy_from_slice(a[0]);
                    s1.copy_from_slice(a[1]);
                    s2.copy_from_slice(a[2]);
                } else {
                    let at = StripStep {
                        from: y - 1,
                        to: y,
                        x0,
                    };
                    step([s0, s1, s2], a, links(y - 1), at);
                }
                p0[y].copy_from_slice(s0);
                p1[y].copy_from_slice(s1);
                p2[y].copy_from_slice(s2);
            }
            for y in (0..h).rev() {
                let a = [v(0, y), v(1, y), v(2, y)];
                if y + 1 == h {
                    s0.copy_from_slice(a[0]);
                    s1.copy_from_slice(a[1]);
                    s2.copy_from_slice(a[2]);
                } else {
                    let at = StripStep {
                        from: y + 1,
                        to: y,
                        x0,
                    };
                    step([s0, s1, s2], a, links(y), at);
                }
                add_difference([&mut *p0[y], &mut *p1[y], &mut *p2[y]], [s0, s1, s2], a);
            }
        });
}

/// `dst += state − v`, per plane.
#[inline(always)]
fn add_difference(dst: [&mut [f32]; 3], state: [&[f32]; 3], v: [&[f32]; 3]) {
    for ((d, s), v) in dst.into_iter().zip(state).zip(v) {
        for ((d, s), v) in d.iter_mut().zip(s).zip(v) {
            *d += s - v;
        }
    }
}
