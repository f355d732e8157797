//! Calibration captures rendered by the virtual rig: a chessboard at several poses, each seen
//! once under room light with the projector dark and then under the column and the row coding
//! patterns with the room light dimmed, exactly what an operator records at a real rig; and the
//! manifest of a measurement session recorded with the rig.

use super::{Chessboard, GroundTruth, RigConfig, RigError, SceneConfig, VirtualRig};
use crate::calibrate::{CalibrationCapture, TABLE1_LEVELS};
use crate::geometry::Pose;
use crate::pattern::{cps_rgb, Axis, PatternSequence};
use crate::session::Manifest;
use nalgebra::{Rotation3, Vector3};

/// The rig `config` looking at a white target for the colour calibration, its projector gain set
/// so that one projector level gives the cross-talk's `A` gray levels at the image centre (so
/// the calibration there must return the rig's own `A`); room light `ambient_gray`.
pub fn colour_target(config: &RigConfig, ambient_gray: f64) -> Result<RigConfig, RigError> {
    let mut config = config.clone();
    config.scene = SceneConfig::white_target();
    config.ambient_gray = ambient_gray;
    // Shading at the centre pixel from the geometry alone: Lambert towards the projector times
    // the inverse-square falloff.
    let (w, h) = (config.camera.width as f64, config.camera.height as f64);
    let ray = config.camera.ray(w / 2.0, h / 2.0)?;
    let point = ray * (config.scene.table_distance_mm / ray.z);
    let to_projector = config.projector_from_camera.inverse().translation_mm - point;
    let distance = to_projector.norm();
    let lambert = Vector3::new(0.0, 0.0, -1.0).dot(&to_projector) / distance;
    let falloff = (config.reference_distance_mm / distance).powi(2);
    config.projector_gain_gray = 255.0 / (lambert * falloff);
    Ok(config)
}

/// Renders the ten Table 1 captures of the colour calibration, in [`TABLE1_LEVELS`] order.
pub fn render_colour_captures(config: &RigConfig) -> Result<Vec<crate::frame::Frame>, RigError> {
    let rig = VirtualRig::new(config.clone(), config.default_sequence()?)?;
    TABLE1_LEVELS
        .iter()
        .enumerate()
        .map(|(i, &levels)| {
            let mut frame = rig.blank_frame();
            rig.render_flat(i as u64, levels, 0.0, &mut frame, None)?;
            Ok(frame)
        })
        .collect()
}

impl VirtualRig {
    /// The manifest of a measurement session recorded with this rig: its sequence, cross-talk
    /// and exact calibration; no frames listed yet.
    pub fn session_manifest(&self) -> Manifest {
        Manifest::for_rig(
            &self.sequence,
            &self.config.cross_talk,
            &self.stereo_model(),
        )
    }
}

/// Room light for the board image with the projector dark, gray levels on white.
pub const ROOM_LIGHT_GRAY: f64 = 150.0;

/// The row-coding sequence matching [`RigConfig::default_sequence`]: n = 81 on the projector's
/// 1140 rows gives the same ~28 px period as n = 65 on its 912 columns.
pub fn row_sequence() -> Result<PatternSequence, RigError> {
    Ok(cps_rgb(81, 1140.0, Axis::Rows, 6)?)
}

/// A standard board whose inner-corner centre sits at `centre_in_camera_mm`, turned by
/// `euler_rad` (roll, pitch, yaw about the camera axes) from facing the camera.
pub fn board_at(centre_in_camera_mm: Vector3<f64>, euler_rad: [f64; 3]) -> Chessboard {
    let rotation = Rotation3::from_euler_angles(euler_rad[0], euler_rad[1], euler_rad[2]);
    let mut board = Chessboard::standard(Pose::identity());
    let centre_on_board = Vector3::new(
        0.5 * (board.inner_cols - 1) as f64 * board.square_mm,
        0.5 * (board.inner_rows - 1) as f64 * board.square_mm,
        0.0,
    );
    board.camera_from_board = Pose {
        rotation: rotation.into_inner(),
        translation_mm: centre_in_camera_mm - rotation * centre_on_board,
    };
    board
}

/// Twelve poses an operator would choose: tilted up to about 30° each way, turned in-plane,
/// 520–620 mm away, the whole board inside the camera image and the projected area.
pub fn standard_poses() -> Vec<Chessboard> {
    [
        ([0.0, 0.0, 540.0], [0.0, 0.0, 0.0]),
        ([-15.0, 5.0, 560.0], [0.35, 0.0, 0.05]),
        ([15.0, -5.0, 560.0], [-0.35, 0.1, -0.05]),
        ([10.0, 10.0, 580.0], [0.0, 0.42, 0.1]),
        ([-10.0, -8.0, 580.0], [0.1, -0.42, -0.1]),
        ([0.0, 0.0, 610.0], [0.25, 0.25, 0.3]),
        ([5.0, 0.0, 520.0], [-0.2, -0.25, -0.25]),
        ([0.0, 5.0, 600.0], [-0.3, 0.3, 0.0]),
        ([-20.0, 0.0, 560.0], [0.42, -0.2, 0.15]),
        ([20.0, 0.0, 560.0], [-0.42, 0.2, -0.15]),
        ([-25.0, -12.0, 600.0], [0.15, 0.5, 0.2]),
        ([25.0, 12.0, 600.0], [-0.15, -0.5, -0.2]),
    ]
    .into_iter()
    .map(|(c, e)| board_at(Vector3::new(c[0], c[1], c[2]), e))
    .collect()
}

/// Renders one calibration capture of `board` with the rig `config` (its scene is replaced by
/// the board); returns it with the exact truth of the room-light image. `view` selects the
/// noise draws, so every view has its own noise.
pub fn render_capture(
    config: &RigConfig,
    board: Chessboard,
    view: u64,
) -> Result<(CalibrationCapture, GroundTruth), RigError> {
    let mut config = config.clone();
    config.scene = SceneConfig::chessboard(board);
    let dimmed = config.ambient_gray;
    config.ambient_gray = ROOM_LIGHT_GRAY;
    let columns = config.default_sequence()?;
    let rows = row_sequence()?;
    let mut rig = VirtualRig::new(config, columns.clone())?;
    let noise = |k: u64| view * 16 + k;
    let mut ambient = rig.blank_frame();
    let mut truth = GroundTruth::default();
    rig.render_flat(noise(0), [0, 0, 0], 0.0, &mut ambient, Some(&mut truth))?;
    rig.config.ambient_gray = dimmed;
    let mut column_frames = Vec::with_capacity(columns.entries.len());
    for k in 0..columns.entries.len() {
        let mut frame = rig.blank_frame();
        rig.render_pattern(noise(1 + k as u64), k, 0.0, &mut frame, None)?;
        column_frames.push(frame);
    }
    rig.sequence = rows.clone();
    let mut row_frames = Vec::with_capacity(rows.entries.len());
    for k in 0..rows.entries.len() {
        let mut frame = rig.blank_frame();
        rig.render_pattern(noise(8 + k as u64), k, 0.0, &mut frame, None)?;
        row_frames.push(frame);
    }
    Ok((
        CalibrationCapture {
            ambient,
            column_sequence: columns,
            column_frames,
            row_sequence: rows,
            row_frames,
        },
        truth,
    ))
}
