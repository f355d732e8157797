//! The virtual rig: a simulated projector and colour camera looking at a trembling hand, with
//! exact ground truth. It is the embedded default device and the test oracle.
//!
//! Image model per camera pixel (see [`render`]): cast the undistorted camera ray (precomputed
//! once), find the nearest surface of the posed [`scene`], project the point into the projector
//! (pinhole + OpenCV distortion, `projector_from_camera` extrinsics) to get its coded coordinate,
//! test the cast shadow towards the projector centre, evaluate each channel's quantised pattern,
//! blur the pattern's AC part on skin (subsurface scattering), shade it (Lambert and inverse-square
//! falloff), multiply by albedo, mix through the cross-talk `c = A·p + b`, add ambient light,
//! blur the image with the lens's point-spread function ([`optics`]: pixels at depth edges mix
//! two surfaces), add read and shot noise, and quantise to 8 bits with saturation.

pub mod board;
pub mod captures;
pub mod edge_eval;
pub mod evaluate;
pub mod faults;
pub mod motion_eval;
pub mod noise;
pub mod optics;
pub mod primitives;
pub mod render;
pub mod scene;
pub mod skin;
pub mod skin_eval;
pub mod tremor_eval;
pub mod truth;

pub use board::Chessboard;
pub use noise::NoiseModel;
pub use render::Projection;
pub use scene::{Scene, SceneConfig, Tremor, POINT_NAMES};
pub use truth::GroundTruth;

use crate::color::CrossTalk;
use crate::frame::Frame;
use crate::geometry::{Distortion, GeometryError, Intrinsics, LensModel, Pose};
use crate::pattern::{cps_rgb, Axis, PatternError, PatternSequence};
use nalgebra::Vector3;
use rayon::prelude::*;

/// Errors of the virtual rig.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum RigError {
    #[error(transparent)]
    Geometry(#[from] GeometryError),
    #[error(transparent)]
    Pattern(#[from] PatternError),
    #[error("frame rate must be positive, got {0}")]
    BadFrameRate(f64),
    #[error("output frame is {got_width}×{got_height}, the rig's camera is {width}×{height}")]
    WrongFrameSize {
        width: usize,
        height: usize,
        got_width: usize,
        got_height: usize,
    },
}

/// Everything that defines the simulated rig.
#[derive(Debug, Clone, PartialEq)]
pub struct RigConfig {
    pub camera: LensModel,
    pub projector: LensModel,
    pub projector_from_camera: Pose,
    pub cross_talk: CrossTalk,
    pub noise: NoiseModel,
    /// Gray levels a white (p = 1) projector channel produces on a white, frontal surface at the
    /// reference distance, before cross-talk.
    pub projector_gain_gray: f64,
    /// Distance at which the inverse-square falloff is 1, mm.
    pub reference_distance_mm: f64,
    /// Ambient light on a white surface, gray levels.
    pub ambient_gray: f64,
    /// Subsurface scattering of skin as a Gaussian blur of the pattern, projector px.
    pub subsurface_sigma_px: f64,
    /// The camera's optical blur: the σ of its Gaussian point-spread function, pixels of the
    /// rendered image ([`optics`]); 0 renders every pixel from its own ray alone.
    pub camera_psf_sigma_px: f64,
    pub scene: SceneConfig,
    pub fps: f64,
    pub seed: u64,
}

impl RigConfig {
    /// The paper's rig (1920×1200 camera binned to `width`×`height`, a 912×1140 LightCrafter 4500
    /// 150 mm to the side, 121 FPS, eq. 24 cross-talk) looking at a trembling hand.
    pub fn paper(width: usize, height: usize) -> Result<Self, RigError> {
        let camera_full = LensModel {
            width: 1920,
            height: 1200,
            intrinsics: Intrinsics {
                fx: 3250.0,
                fy: 3250.0,
                cx: 962.5,
                cy: 596.0,
            },
            distortion: Distortion {
                k1: -0.08,
                k2: 0.05,
                p1: 0.0004,
                p2: -0.0003,
                k3: 0.0,
            },
        };
        let projector = LensModel {
            width: 912,
            height: 1140,
            intrinsics: Intrinsics {
                fx: 1380.0,
                fy: 1380.0,
                cx: 455.5,
                cy: 575.0,
            },
            distortion: Distortion {
                k1: 0.03,
                k2: -0.01,
                ..Distortion::default()
            },
        };
        let projector_from_camera = Pose::look_at(
            Vector3::new(150.0, 0.0, 20.0),
            Vector3::new(10.0, 0.0, 480.0),
        );
        Ok(Self {
            camera: camera_full.resized(width, height)?,
            projector,
            projector_from_camera,
            cross_talk: CrossTalk::paper(),
            noise: NoiseModel::default(),
            projector_gain_gray: 250.0,
            reference_distance_mm: 480.0,
            ambient_gray: 6.0,
            subsurface_sigma_px: 2.5,
            // A lens of about 1.2 sensor pixels FWHM at 2×–3× binning (optics.rs).
            camera_psf_sigma_px: 0.4,
            scene: SceneConfig::trembling_hand(),
            fps: 121.0,
            seed: 1,
        })
    }

    /// The CPS-RGB sequence this rig projects by default: n = 65 on 912 projector columns
    /// (periods of about 28 px, as in the paper), 6-bit.
    pub fn default_sequence(&self) -> Result<PatternSequence, RigError> {
        Ok(cps_rgb(65, 912.0, Axis::Columns, 6)?)
    }
}

/// The simulated rig, ready to render frames.
#[derive(Debug, Clone)]
pub struct VirtualRig {
    pub config: RigConfig,
    pub sequence: PatternSequence,
    scene: Scene,
    /// Unit camera ray per pixel, row-major, camera frame.
    rays: Vec<[f32; 3]>,
    projector_centre_in_camera: Vector3<f64>,
}

impl VirtualRig {
    /// Precomputes the camera rays for `config` projecting `sequence`.
    pub fn new(config: RigConfig, sequence: PatternSequence) -> Result<Self, RigError> {
        sequence.validate()?;
        sequence.check_covers(config.projector.width, config.projector.height)?;
        if !(config.fps.is_finite() && config.fps > 0.0) {
            return Err(RigError::BadFrameRate(config.fps));
        }
        let cam = config.camera;
        for lens in [&config.camera, &config.projector] {
            if lens.width == 0 || lens.height == 0 {
                return Err(GeometryError::EmptySize {
                    width: lens.width,
                    height: lens.height,
                }
                .into());
            }
        }
        let rays = (0..cam.width * cam.height)
            .into_par_iter()
            .map(|i| {
                let r = cam.ray((i % cam.width) as f64, (i / cam.width) as f64)?;
                Ok([r.x as f32, r.y as f32, r.z as f32])
            })
            .collect::<Result<Vec<_>, GeometryError>>()?;
        let projector_centre_in_camera = config.projector_from_camera.inverse().translation_mm;
        Ok(Self {
            scene: Scene::new(config.scene.clone()),
            config,
            sequence,
            rays,
            projector_centre_in_camera,
        })
    }

    pub fn width(&self) -> usize {
        self.config.camera.width
    }

    /// The rig's exact calibration, as a triangulator needs it.
    pub fn stereo_model(&self) -> crate::triangulate::StereoModel {
        crate::triangulate::StereoModel {
            camera: self.config.camera,
            projector: self.config.projector,
            projector_from_camera: self.config.projector_from_camera,
            axis: self.sequence.axis,
        }
    }

    pub fn height(&self) -> usize {
        self.config.camera.height
    }

    /// Time of frame `index`, seconds.
    pub fn frame_time_s(&self, index: u64) -> f64 {
        index as f64 / self.config.fps
    }

    /// Pattern entry shown in frame `index`: the sequence repeats cyclically.
    pub fn pattern_index(&self, index: u64) -> usize {
        (index % self.sequence.entries.len() as u64) as usize
    }

    /// A black RGB frame of the camera's size, to render into.
    pub fn blank_frame(&self) -> Frame {
        Frame {
            width: self.width(),
            height: self.height(),
            channels: 3,
            data: vec![0; self.width() * self.height() * 3],
            time_s: 0.0,
            pattern_index: 0,
        }
    }

    /// Renders frame `index` of the endless stream into `frame`, and its truth into `truth`.
    pub fn render(
        &self,
        index: u64,
        frame: &mut Frame,
        truth: Option<&mut GroundTruth>,
    ) -> Result<(), RigError> {
        let pattern_index = self.pattern_index(index);
        self.render_pattern(index, pattern_index, self.frame_time_s(index), frame, truth)
    }

    /// Renders pattern entry `pattern_index` at `time_s`; `noise_frame` selects the noise draw.
    pub fn render_pattern(
        &self,
        noise_frame: u64,
        pattern_index: usize,
        time_s: f64,
        frame: &mut Frame,
        truth: Option<&mut GroundTruth>,
    ) -> Result<(), RigError> {
        let entry =
            *self
                .sequence
                .entries
                .get(pattern_index)
                .ok_or(PatternError::IndexOutOfRange {
                    index: pattern_index,
                    len: self.sequence.entries.len(),
                })?;
        self.render_projection(
            noise_frame,
            Projection::Pattern(entry),
            time_s,
            frame,
            truth,
        )?;
        frame.pattern_index = pattern_index;
        Ok(())
    }

    /// Renders the scene under a constant projected colour (8-bit levels per channel, as in the
    /// paper's Table 1) at `time_s`. The frame's `pattern_index` is set to 0.
    pub fn render_flat(
        &self,
        noise_frame: u64,
        levels: [u8; 3],
        time_s: f64,
        frame: &mut Frame,
        truth: Option<&mut GroundTruth>,
    ) -> Result<(), RigError> {
        self.render_projection(noise_frame, Projection::Flat(levels), time_s, frame, truth)
    }

    fn render_projection(
        &self,
        noise_frame: u64,
        projection: Projection,
        time_s: f64,
        frame: &mut Frame,
        truth: Option<&mut GroundTruth>,
    ) -> Result<(), RigError> {
        let (w, h) = (self.width(), self.height());
        if frame.width != w || frame.height != h || frame.channels != 3 {
            return Err(RigError::WrongFrameSize {
                width: w,
                height: h,
                got_width: frame.width,
                got_height: frame.height,
            });
        }
        frame.data.resize(w * h * 3, 0);
        frame.time_s = time_s;
        frame.pattern_index = 0;
        let mut posed = self.scene.at(time_s);
        posed.cull(
            &self.config.camera,
            &self.config.projector,
            &self.config.projector_from_camera,
        );
        let ctx = render::Context::new(
            self,
            &posed,
            projection,
            noise_frame,
            self.projector_centre_in_camera,
        );
        match truth {
            Some(t) => {
                t.resize(w, h);
                t.time_s = time_s;
                t.points_in_camera.clone_from(&posed.points);
                t.board_corners_in_camera.clear();
                if let Some(board) = posed.board() {
                    t.board_corners_in_camera.extend(board.corners_in_camera());
                }
                render::render_rows(&ctx, &self.rays, &mut frame.data, Some(t));
            }
            None => render::render_rows(&ctx, &self.rays, &mut frame.data, None),
        }
        Ok(())
    }
}
