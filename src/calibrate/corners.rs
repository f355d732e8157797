//! Sub-pixel chessboard corners in a camera image, labelled with the board's own indices.
//!
//! The ChESS corner detector of the `chess-corners` crate finds X-junctions; its saddle-point
//! refiner fits a quadratic surface to the image patch around each one (sub-pixel). The
//! `calib-targets-chessboard` crate then labels them as a grid. That labelling is only defined
//! up to the grid's orientation in the image, so this module maps it onto the board's indices
//! `(i, j)` (inner corner `(i, j)` at `(i·s, j·s)` on the board, see [`crate::rig::Chessboard`]):
//!
//! - a board is used only when every inner corner was found, so the labels cannot be shifted;
//! - of the four in-plane rotations, those whose extent matches the board are candidates (a
//!   board seen from the front keeps its handedness, so no mirror image is possible);
//! - between them, the printed squares decide: the square with lower corner `(a, b)` is dark
//!   when `a + b` is even. Each candidate predicts which cell centres are dark, and the one that
//!   agrees with the image wins. For boards whose corner counts sum to an even number the 180°
//!   turn predicts the same squares; the image orientation then decides (keep such boards less
//!   than a quarter turn from upright).

use super::CalibrationError;
use crate::frame::Frame;
use calib_targets_chessboard::{
    default_chess_config, detect_corners, ChessboardDetector, ChessboardParams, GrayImageView,
};

/// The printed board: inner corners per row (`cols`, along the board's x) and per column
/// (`rows`), and the square size.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoardSpec {
    pub cols: usize,
    pub rows: usize,
    pub square_mm: f64,
}

impl BoardSpec {
    /// Board-frame position of every inner corner, `j` outer and `i` inner, mm (z = 0).
    pub fn corners_on_board_mm(&self) -> Vec<[f64; 2]> {
        (0..self.rows)
            .flat_map(|j| {
                (0..self.cols).map(move |i| [i as f64 * self.square_mm, j as f64 * self.square_mm])
            })
            .collect()
    }

    pub fn corner_count(&self) -> usize {
        self.cols * self.rows
    }
}

/// 8-bit gray image of a frame (the mean of R, G and B for colour frames).
pub fn gray_of(frame: &Frame) -> Vec<u8> {
    if frame.channels == 1 {
        return frame.data.clone();
    }
    frame
        .data
        .chunks_exact(3)
        .map(|p| ((u16::from(p[0]) + u16::from(p[1]) + u16::from(p[2]) + 1) / 3) as u8)
        .collect()
}

/// Finds every inner corner of `board` in `gray` (`width`×`height`, row-major). Returns the image
/// positions in board order (`j` outer, `i` inner), in pixels with the centre of the top-left
/// pixel at (0, 0).
pub fn find_board_corners(
    gray: &[u8],
    width: usize,
    height: usize,
    board: &BoardSpec,
    view: usize,
) -> Result<Vec<[f64; 2]>, CalibrationError> {
    if board.cols < 2 || board.rows < 2 {
        return Err(CalibrationError::BadBoard {
            cols: board.cols,
            rows: board.rows,
        });
    }
    if gray.len() != width * height {
        return Err(CalibrationError::BadCapture {
            view,
            why: format!(
                "the gray image holds {} bytes, {width}×{height} needs {}",
                gray.len(),
                width * height
            ),
        });
    }
    let image = GrayImageView {
        width,
        height,
        data: gray,
    };
    let config = default_chess_config().with_refiner(chess_corners::ImageRefiner::saddle_point());
    let corners = detect_corners(&image, &config);
    let not_found = |found| CalibrationError::CornersNotFound {
        view,
        found,
        expected: board.corner_count(),
    };
    let detector =
        ChessboardDetector::new(ChessboardParams::default()).map_err(|_| not_found(0))?;
    let detection = detector.detect(&corners).ok_or(not_found(0))?;
    if detection.corners.len() != board.corner_count() {
        return Err(not_found(detection.corners.len()));
    }
    let (mut u_max, mut v_max) = (0, 0);
    for c in &detection.corners {
        if c.grid.u < 0 || c.grid.v < 0 {
            return Err(not_found(detection.corners.len()));
        }
        u_max = u_max.max(c.grid.u as usize);
        v_max = v_max.max(c.grid.v as usize);
    }
    let mut by_label = vec![None; (u_max + 1) * (v_max + 1)];
    for c in &detection.corners {
        let slot = c.grid.v as usize * (u_max + 1) + c.grid.u as usize;
        by_label[slot] = Some([f64::from(c.position.x), f64::from(c.position.y)]);
    }
    let labelled = Labelled {
        positions: by_label,
        u_max,
        v_max,
    };
    let candidates: Vec<Turn> = Turn::ALL
        .into_iter()
        .filter(|t| t.fits(&labelled, board))
        .collect();
    let mut best: Option<(f64, Turn)> = None;
    for turn in candidates {
        let Some(ordered) = labelled.in_board_order(turn, board) else {
            continue;
        };
        let score = dark_square_agreement(gray, width, height, board, &ordered);
        // Strictly better only: on a tie the earlier (less turned) candidate stays.
        if best.is_none_or(|(s, _)| score > s + 1e-9) {
            best = Some((score, turn));
        }
    }
    let (score, turn) = best.ok_or(not_found(detection.corners.len()))?;
    if score <= 0.0 {
        // No orientation sees dark squares where the board has them: not this board.
        return Err(not_found(detection.corners.len()));
    }
    let mut ordered = labelled
        .in_board_order(turn, board)
        .ok_or(not_found(detection.corners.len()))?;
    let spacing_px = median_spacing_px(&ordered, board);
    let radius_px = (0.3 * spacing_px).clamp(2.0, 12.0) as usize;
    for corner in &mut ordered {
        *corner = refine_saddle(gray, width, height, *corner, radius_px);
    }
    Ok(ordered)
}

/// Median distance between neighbouring corners along the board's rows, pixels.
fn median_spacing_px(ordered: &[[f64; 2]], board: &BoardSpec) -> f64 {
    let mut d: Vec<f64> = (0..board.rows)
        .flat_map(|j| (1..board.cols).map(move |i| (j * board.cols + i - 1, j * board.cols + i)))
        .map(|(a, b)| (ordered[a][0] - ordered[b][0]).hypot(ordered[a][1] - ordered[b][1]))
        .collect();
    d.sort_by(f64::total_cmp);
    d[d.len() / 2]
}

/// Gradient-orthogonality refinement of an X-junction (Förstner's operator): at the true
/// corner `q`, every image gradient `g` at a pixel `p` nearby is orthogonal to `p − q`, since `p`
/// lies either inside a uniform square (g = 0) or on an edge through `q`. Minimising
/// `Σ w·(gᵀ(p − q))²` gives `(Σ w·g·gᵀ) q = Σ w·g·gᵀ·p`, solved repeatedly around the new
/// estimate (Gaussian weights of half the window). Returns the input when the window leaves the
/// image or the system is singular (no edges), and never moves a corner by more than the window.
fn refine_saddle(
    gray: &[u8],
    width: usize,
    height: usize,
    start: [f64; 2],
    radius_px: usize,
) -> [f64; 2] {
    let r = radius_px as isize;
    let sigma2 = (0.5 * radius_px as f64).powi(2).max(1.0);
    let at = |x: isize, y: isize| f64::from(gray[y as usize * width + x as usize]);
    let mut q = start;
    for _ in 0..10 {
        let (cx, cy) = (q[0].round() as isize, q[1].round() as isize);
        if cx - r - 1 < 0
            || cy - r - 1 < 0
            || cx + r + 1 >= width as isize
            || cy + r + 1 >= height as isize
        {
            return start;
        }
        let (mut a, mut b, mut c, mut bx, mut by) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for y in cy - r..=cy + r {
            for x in cx - r..=cx + r {
                let gx = 0.5 * (at(x + 1, y) - at(x - 1, y));
                let gy = 0.5 * (at(x, y + 1) - at(x, y - 1));
                let (dx, dy) = (x as f64 - q[0], y as f64 - q[1]);
                let w = (-(dx * dx + dy * dy) / (2.0 * sigma2)).exp();
                let (gxx, gxy, gyy) = (w * gx * gx, w * gx * gy, w * gy * gy);
                a += gxx;
                b += gxy;
                c += gyy;
                bx += gxx * x as f64 + gxy * y as f64;
                by += gxy * x as f64 + gyy * y as f64;
            }
        }
        let det = a * c - b * b;
        if det <= 1e-9 * (a + c).powi(2) {
            return start;
        }
        let next = [(c * bx - b * by) / det, (a * by - b * bx) / det];
        if (next[0] - start[0]).hypot(next[1] - start[1]) > radius_px as f64 {
            return start;
        }
        let step = (next[0] - q[0]).hypot(next[1] - q[1]);
        q = next;
        if step < 1e-3 {
            break;
        }
    }
    q
}

/// The detector's labels and positions, `v` outer.
struct Labelled {
    positions: Vec<Option<[f64; 2]>>,
    u_max: usize,
    v_max: usize,
}

impl Labelled {
    fn in_board_order(&self, turn: Turn, board: &BoardSpec) -> Option<Vec<[f64; 2]>> {
        let mut ordered = Vec::with_capacity(board.corner_count());
        for j in 0..board.rows {
            for i in 0..board.cols {
                let (u, v) = turn.label_of(i, j, board);
                ordered.push(self.positions.get(v * (self.u_max + 1) + u).copied()??);
            }
        }
        Some(ordered)
    }
}

/// In-plane turn from board indices to the detector's labels, in quarter turns.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Turn {
    None,
    Quarter,
    Half,
    ThreeQuarters,
}

impl Turn {
    const ALL: [Turn; 4] = [Turn::None, Turn::Quarter, Turn::Half, Turn::ThreeQuarters];

    fn fits(&self, labelled: &Labelled, board: &BoardSpec) -> bool {
        let (c, r) = (board.cols - 1, board.rows - 1);
        match self {
            Turn::None | Turn::Half => labelled.u_max == c && labelled.v_max == r,
            Turn::Quarter | Turn::ThreeQuarters => labelled.u_max == r && labelled.v_max == c,
        }
    }

    /// The label `(u, v)` of board corner `(i, j)`; every map keeps the handedness.
    fn label_of(&self, i: usize, j: usize, board: &BoardSpec) -> (usize, usize) {
        let (c, r) = (board.cols - 1, board.rows - 1);
        match self {
            Turn::None => (i, j),
            Turn::Half => (c - i, r - j),
            Turn::Quarter => (r - j, i),
            Turn::ThreeQuarters => (j, c - i),
        }
    }
}

/// How well the dark squares predicted by corner positions in board order match the image:
/// mean over inner cells of (image mean − cell brightness) signed by the predicted colour.
fn dark_square_agreement(
    gray: &[u8],
    width: usize,
    height: usize,
    board: &BoardSpec,
    ordered: &[[f64; 2]],
) -> f64 {
    let (mut sum, mut count) = (0.0, 0usize);
    let mut cells = Vec::with_capacity((board.cols - 1) * (board.rows - 1));
    for b in 0..board.rows - 1 {
        for a in 0..board.cols - 1 {
            let corner = |i: usize, j: usize| ordered[j * board.cols + i];
            let quad = [
                corner(a, b),
                corner(a + 1, b),
                corner(a, b + 1),
                corner(a + 1, b + 1),
            ];
            let x = quad.iter().map(|p| p[0]).sum::<f64>() / 4.0;
            let y = quad.iter().map(|p| p[1]).sum::<f64>() / 4.0;
            let (xi, yi) = (x.round(), y.round());
            if xi < 0.0 || yi < 0.0 || xi >= width as f64 || yi >= height as f64 {
                continue;
            }
            let value = f64::from(gray[yi as usize * width + xi as usize]);
            cells.push((value, (a + b) % 2 == 0));
            sum += value;
            count += 1;
        }
    }
    if count == 0 {
        return 0.0;
    }
    let mean = sum / count as f64;
    cells
        .iter()
        .map(|&(value, dark)| if dark { mean - value } else { value - mean })
        .sum::<f64>()
        / count as f64
}
