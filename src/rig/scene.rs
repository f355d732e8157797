//! The virtual scene: a textured table plane and a hand (ellipsoid palm, capsule fingers) whose
//! fingers tremble, all in the camera frame (mm, z forward, looking down at the table).
//!
//! Each finger rotates about its knuckle by `α(t) = asin(A_tip / r)·sin(2π·f·t + φ_finger)`, where
//! `r` is the horizontal arm from the knuckle to the tracked tip point, so that point moves by
//! `A_tip` along the optical axis relative to the hand; the whole hand also oscillates vertically
//! (in phase with the index finger), which adds to every point's motion.
//!
//! Lateral motion, as a resting hand shows it: the whole hand sways sideways (camera y,
//! across the fingers) by `S·sin(2π·f·t + π/2)` and rolls about the forearm axis (the line
//! along x through the palm centre: pronation–supination) by `R·sin(2π·f·t + π/4)`. The hand's
//! parts are built in a hand frame and placed by that rigid pose: rays are taken into the hand
//! frame to hit its parts, and normals and the tracked points out of it, so the truth stays
//! exact.
//! [`Scene::at`] poses every primitive at one instant, so each camera frame is rendered at its own
//! time and motion inside the decode window is real.

use super::board::Chessboard;
use super::primitives::{Capsule, Ellipsoid, HandPart, PixelBox, Shape};
use super::skin::skin_texture;
use crate::geometry::{LensModel, Pose};
use nalgebra::{Isometry3, Point3, Rotation3, Translation3, Unit, UnitQuaternion, Vector3};
use std::f64::consts::TAU;

type V3 = Vector3<f64>;

/// Surface material of a hit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Material {
    Table,
    Skin,
    /// The calibration chessboard.
    Board,
}

/// Tremor of the hand.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tremor {
    pub frequency_hz: f64,
    /// Peak displacement of each tracked fingertip point along the optical axis relative to the
    /// hand, mm.
    pub tip_amplitude_mm: f64,
    /// Peak vertical displacement of the whole hand, mm.
    pub hand_amplitude_mm: f64,
    /// Peak sideways displacement of the whole hand (camera y), mm.
    pub sway_amplitude_mm: f64,
    /// Peak roll of the hand about the forearm axis (pronation–supination), degrees.
    pub roll_amplitude_deg: f64,
}

impl Tremor {
    /// Flexion of the fingers and a small vertical motion of the hand, no lateral motion.
    pub fn flexion(frequency_hz: f64, tip_amplitude_mm: f64, hand_amplitude_mm: f64) -> Self {
        Self {
            frequency_hz,
            tip_amplitude_mm,
            hand_amplitude_mm,
            sway_amplitude_mm: 0.0,
            roll_amplitude_deg: 0.0,
        }
    }
}

/// What the scene contains.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneConfig {
    /// Distance of the table from the camera centre along the optical axis, mm.
    pub table_distance_mm: f64,
    /// Table tilt about the camera x axis, radians.
    pub table_tilt_rad: f64,
    /// Print a colour texture on the table.
    pub table_texture: bool,
    /// Table albedo (R, G, B) where it is not textured.
    pub table_albedo: [f64; 3],
    /// The hand, or `None` for a bare table.
    pub hand: Option<Tremor>,
    /// Height of the palm centre above the table, mm.
    pub hand_height_mm: f64,
    /// A calibration chessboard in front of the table, if any.
    pub board: Option<Chessboard>,
    /// RMS relative variation of the skin's albedo (its texture, `rig::skin`); 0 is uniform.
    pub skin_texture_contrast: f64,
}

impl SceneConfig {
    /// A hand with the paper's typical parkinsonian tremor (5.3 Hz, 2 mm at the fingertips).
    pub fn trembling_hand() -> Self {
        Self {
            table_distance_mm: 500.0,
            table_tilt_rad: 0.05,
            table_texture: true,
            table_albedo: [0.72, 0.70, 0.66],
            hand: Some(Tremor::flexion(5.3, 2.0, 0.3)),
            hand_height_mm: 45.0,
            board: None,
            skin_texture_contrast: SKIN_TEXTURE_CONTRAST,
        }
    }

    /// A bare, untextured, untilted plane: the simplest accuracy target.
    pub fn plane() -> Self {
        Self {
            table_distance_mm: 500.0,
            table_tilt_rad: 0.0,
            table_texture: false,
            table_albedo: [0.72, 0.70, 0.66],
            hand: None,
            hand_height_mm: 0.0,
            board: None,
            skin_texture_contrast: 0.0,
        }
    }

    /// A chessboard at `camera_from_board` in front of a plain table: a geometric calibration
    /// view.
    pub fn chessboard(board: Chessboard) -> Self {
        Self {
            table_distance_mm: 650.0,
            board: Some(board),
            ..Self::plane()
        }
    }

    /// A flat white target (albedo 1) filling the view: the colour calibration's scene.
    pub fn white_target() -> Self {
        Self {
            table_albedo: [1.0, 1.0, 1.0],
            ..Self::plane()
        }
    }
}

/// Names of the tracked surface points, in the order of [`PosedScene::points`].
pub const POINT_NAMES: [&str; 6] = [
    "index_tip",
    "middle_tip",
    "ring_tip",
    "little_tip",
    "thumb_tip",
    "back_of_hand",
];

/// The skin's texture contrast of the trembling hand: faint, as skin is at 0.4 mm per pixel.
pub const SKIN_TEXTURE_CONTRAST: f64 = 0.03;

/// A ray hit.
#[derive(Debug, Clone, Copy)]
pub struct Hit {
    pub distance_mm: f64,
    pub normal: V3,
    pub material: Material,
    /// Where the hit lies on the hand at rest (skin only; zero elsewhere), mm: what the skin's
    /// texture is a function of.
    pub rest_point_mm: V3,
}

/// The scene posed at one instant.
#[derive(Debug, Clone)]
pub struct PosedScene {
    table_point: V3,
    table_normal: V3,
    pub table_texture: bool,
    table_albedo: [f64; 3],
    board: Option<Chessboard>,
    skin_texture_contrast: f64,
    parts: Vec<HandPart>,
    /// Rigid pose of the hand frame (in which `parts` are built) in the camera frame.
    camera_from_hand: Isometry3<f64>,
    /// True positions of [`POINT_NAMES`] (empty without a hand), camera frame, mm.
    pub points: Vec<V3>,
}

/// Knuckle offset from the palm centre (x, y), proximal and distal lengths, radius, tremor phase.
const FINGERS: [(f64, f64, f64, f64, f64, f64); 4] = [
    (-40.0, -27.0, 44.0, 42.0, 8.5, 0.0),
    (-40.0, -9.0, 49.0, 47.0, 9.0, 0.15),
    (-40.0, 9.0, 46.0, 43.0, 8.5, 0.3),
    (-37.0, 26.0, 37.0, 33.0, 7.5, 0.45),
];

/// The scene description and its pose at any time.
#[derive(Debug, Clone)]
pub struct Scene {
    pub config: SceneConfig,
}

impl Scene {
    pub fn new(config: SceneConfig) -> Self {
        Self { config }
    }

    /// Poses every primitive at `time_s`.
    pub fn at(&self, time_s: f64) -> PosedScene {
        let c = &self.config;
        let table_normal = V3::new(0.0, c.table_tilt_rad.sin(), -c.table_tilt_rad.cos());
        let table_point = V3::new(0.0, 0.0, c.table_distance_mm);
        let mut posed = PosedScene {
            table_point,
            table_normal,
            table_texture: c.table_texture,
            table_albedo: c.table_albedo,
            board: c.board,
            skin_texture_contrast: c.skin_texture_contrast,
            parts: Vec::with_capacity(11),
            camera_from_hand: Isometry3::identity(),
            points: Vec::with_capacity(POINT_NAMES.len()),
        };
        let Some(tremor) = c.hand else {
            return posed;
        };
        let omega_t = TAU * tremor.frequency_hz * time_s;
        let lift = tremor.hand_amplitude_mm * omega_t.sin();
        let palm_centre = V3::new(45.0, 0.0, c.table_distance_mm - c.hand_height_mm + lift);
        let palm = Ellipsoid::new(palm_centre, V3::new(46.0, 42.0, 12.0));
        // The hand at rest is the hand before its lift: the palm and thumb move rigidly with it.
        let rest_from_lifted = Isometry3::translation(0.0, 0.0, -lift);
        let up = V3::new(0.0, 0.0, -1.0);
        let mut tips = Vec::with_capacity(5);
        for &(kx, ky, l1, l2, radius, phase) in &FINGERS {
            let knuckle = palm_centre + V3::new(kx, ky, 1.0);
            // Rest pose: along −x, curled slightly down towards the table.
            let rest_d1 = V3::new(-1.0, 0.0, 0.12).normalize();
            let rest_d2 = V3::new(-1.0, 0.0, 0.30).normalize();
            // A rotation α about y moves a point at horizontal arm |Δx| by α·|Δx| along z: choose
            // α so that the tracked tip point moves by exactly the configured amplitude.
            let rest_joint = knuckle + rest_d1 * l1;
            let rest_tracked =
                surface_above(rest_joint, rest_joint + rest_d2 * l2, radius, 0.8, up);
            let arm = (rest_tracked.x - knuckle.x).abs();
            let alpha = (tremor.tip_amplitude_mm / arm).asin() * (omega_t + TAU * phase).sin();
            let rot = Rotation3::from_axis_angle(&Vector3::y_axis(), alpha);
            let joint = knuckle + rot * rest_d1 * l1;
            let tip = joint + rot * rest_d2 * l2;
            let unflex = Isometry3::from_parts(
                Translation3::from(knuckle),
                UnitQuaternion::from_axis_angle(&Vector3::y_axis(), -alpha),
            ) * Translation3::from(-knuckle);
            let rest = rest_from_lifted * unflex;
            posed.push(Shape::Capsule(Capsule::new(knuckle, joint, radius)), rest);
            posed.push(Shape::Capsule(Capsule::new(joint, tip, radius)), rest);
            tips.push(surface_above(joint, tip, radius, 0.8, up));
        }
        // Thumb: two segments towards +y, trembling with the hand only.
        let base = palm_centre + V3::new(-8.0, 34.0, 3.0);
        let joint = base + V3::new(-22.0, 22.0, 4.0);
        let tip = joint + V3::new(-24.0, 8.0, 6.0);
        posed.push(
            Shape::Capsule(Capsule::new(base, joint, 10.5)),
            rest_from_lifted,
        );
        posed.push(
            Shape::Capsule(Capsule::new(joint, tip, 9.5)),
            rest_from_lifted,
        );
        tips.push(surface_above(joint, tip, 9.5, 0.8, up));
        posed.points.extend(tips);
        posed
            .points
            .push(palm_centre + V3::new(0.0, 0.0, -palm.radii.z));
        posed.push(Shape::Ellipsoid(palm), rest_from_lifted);
        // Sway and roll: the hand frame about the forearm axis through the palm centre.
        let roll = tremor.roll_amplitude_deg.to_radians() * (omega_t + TAU / 8.0).sin();
        let sway = tremor.sway_amplitude_mm * (omega_t + TAU / 4.0).sin();
        let about_axis = Isometry3::from_parts(
            Translation3::from(palm_centre + V3::new(0.0, sway, 0.0)),
            UnitQuaternion::from_axis_angle(&Vector3::x_axis(), roll),
        ) * Translation3::from(-palm_centre);
        posed.camera_from_hand = about_axis;
        for p in &mut posed.points {
            *p = about_axis.transform_point(&Point3::from(*p)).coords;
        }
        posed
    }
}

/// The surface point of capsule `a→b` at fraction `s` along its axis, on the side facing `up`.
fn surface_above(a: V3, b: V3, radius: f64, s: f64, up: V3) -> V3 {
    let axis = (b - a).normalize();
    let side = Unit::new_normalize(up - axis * up.dot(&axis));
    a + (b - a) * s + side.into_inner() * radius
}

impl PosedScene {
    fn push(&mut self, shape: Shape, rest_from_hand: Isometry3<f64>) {
        self.parts.push(HandPart {
            shape,
            camera_box: PixelBox::EVERYWHERE,
            projector_box: PixelBox::EVERYWHERE,
            rest_from_hand,
        });
    }

    /// The skin's albedo (R, G, B) at a skin hit: the skin's colour times its texture there.
    pub fn skin_albedo(&self, hit: &Hit) -> [f64; 3] {
        let k = skin_texture(&hit.rest_point_mm, self.skin_texture_contrast);
        SKIN_ALBEDO.map(|a| a * k)
    }

    /// Computes each hand part's bounding box in the camera and projector images, so that rays
    /// through pixels outside a box skip that part. Without this call every part is tested.
    pub fn cull(
        &mut self,
        camera: &LensModel,
        projector: &LensModel,
        projector_from_camera: &Pose,
    ) {
        for part in &mut self.parts {
            let (centre_in_hand, radius) = part.shape.bounding_sphere();
            let centre = self
                .camera_from_hand
                .transform_point(&Point3::from(centre_in_hand))
                .coords;
            part.camera_box = PixelBox::around_sphere(camera, &Pose::identity(), centre, radius);
            part.projector_box =
                PixelBox::around_sphere(projector, projector_from_camera, centre, radius);
        }
    }

    /// Nearest hit along the camera ray `dir` (unit) through camera pixel `pixel`.
    pub fn intersect(&self, origin: &V3, dir: &V3, pixel: (f64, f64)) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        let denom = dir.dot(&self.table_normal);
        if denom.abs() > 1e-12 {
            let t = (self.table_point - origin).dot(&self.table_normal) / denom;
            if t > 1e-6 {
                best = Some(Hit {
                    distance_mm: t,
                    normal: self.table_normal,
                    material: Material::Table,
                    rest_point_mm: V3::zeros(),
                });
            }
        }
        if let Some(board) = &self.board {
            if let Some((t, _)) = board.intersect(origin, dir) {
                if best.is_none_or(|h| t < h.distance_mm) {
                    best = Some(Hit {
                        distance_mm: t,
                        normal: board.normal_in_camera(),
                        material: Material::Board,
                        rest_point_mm: V3::zeros(),
                    });
                }
            }
        }
        let mut limit = best.map_or(f64::INFINITY, |h| h.distance_mm);
        let (origin_in_hand, dir_in_hand) = self.ray_in_hand(origin, dir);
        for part in &self.parts {
            if !part.camera_box.contains(pixel) {
                continue;
            }
            if let Some((t, normal)) = part.shape.intersect(&origin_in_hand, &dir_in_hand) {
                if t < limit {
                    limit = t;
                    let in_hand = Point3::from(origin_in_hand + dir_in_hand * t);
                    best = Some(Hit {
                        distance_mm: t,
                        normal: self.camera_from_hand.rotation * normal,
                        material: Material::Skin,
                        rest_point_mm: part.rest_from_hand.transform_point(&in_hand).coords,
                    });
                }
            }
        }
        best
    }

    /// Whether the hand or the board blocks the segment from `origin` to `origin + max_t·dir`,
    /// where `projector_pixel` is where `origin` appears in the projector image.
    pub fn occludes(&self, origin: &V3, dir: &V3, max_t: f64, projector_pixel: (f64, f64)) -> bool {
        let board_blocks = self
            .board
            .as_ref()
            .and_then(|b| b.intersect(origin, dir))
            .is_some_and(|(t, _)| t < max_t);
        let (origin_in_hand, dir_in_hand) = self.ray_in_hand(origin, dir);
        board_blocks
            || self.parts.iter().any(|part| {
                part.projector_box.contains(projector_pixel)
                    && part
                        .shape
                        .intersect(&origin_in_hand, &dir_in_hand)
                        .is_some_and(|(t, _)| t < max_t)
            })
    }

    /// A camera-frame ray in the hand frame (a rigid map: distances along it are unchanged).
    #[inline]
    fn ray_in_hand(&self, origin: &V3, dir: &V3) -> (V3, V3) {
        let inverse = self.camera_from_hand.inverse();
        (
            inverse.transform_point(&Point3::from(*origin)).coords,
            inverse.transform_vector(dir),
        )
    }

    /// The chessboard, if the scene has one.
    pub fn board(&self) -> Option<&Chessboard> {
        self.board.as_ref()
    }

    /// Albedo (R, G, B) of the chessboard at a camera-frame point on it.
    pub fn board_albedo(&self, point_in_camera: &V3) -> [f64; 3] {
        self.board.as_ref().map_or([0.0; 3], |b| {
            let in_board = b.camera_from_board.inverse().transform(point_in_camera);
            [b.albedo(&in_board); 3]
        })
    }

    /// Mean albedo of the chessboard over one camera pixel: the pixel's footprint on the board
    /// is the parallelogram spanned by the hits of the neighbouring pixels' rays (`step_u`,
    /// `step_v`, board frame), averaged over 16 samples, as a sensor integrates over its
    /// pixel. Without it the square edges would be point-sampled and step by whole pixels.
    pub fn board_albedo_over_pixel(&self, dir: &V3, step_u_dir: &V3, step_v_dir: &V3) -> [f64; 3] {
        let Some(b) = self.board.as_ref() else {
            return [0.0; 3];
        };
        let origin = V3::zeros();
        let at = |d: &V3| b.intersect_plane(&origin, d);
        let Some(centre) = at(dir) else {
            return [b.light_albedo; 3];
        };
        let (Some(pu), Some(pv)) = (at(step_u_dir), at(step_v_dir)) else {
            return [b.albedo(&centre); 3];
        };
        let (du, dv) = (pu - centre, pv - centre);
        // 16 samples, one in every row and every column of a 16×16 sub-grid (the column of
        // row k is 5·k mod 16), so an edge parallel to the pixel grid is resolved to 1/16 px
        // rather than the 1/4 px of a regular 4×4 grid.
        const N: usize = 16;
        let mut sum = 0.0;
        for k in 0..N {
            let s = (k as f64 + 0.5) / N as f64 - 0.5;
            let t = ((5 * k) % N) as f64 / N as f64 + 0.5 / N as f64 - 0.5;
            sum += b.albedo(&(centre + du * s + dv * t));
        }
        [sum / N as f64; 3]
    }

    /// Table albedo (R, G, B) at a table point: light paper with a printed pattern.
    pub fn table_albedo(&self, p: &V3) -> [f64; 3] {
        if !self.table_texture {
            return self.table_albedo;
        }
        let checker = ((p.x / 40.0).floor() + (p.y / 40.0).floor()).rem_euclid(2.0);
        let stripe = 0.5 + 0.5 * (p.x * 0.11 + p.y * 0.07).sin();
        let k = 0.78 + 0.12 * checker;
        [
            k * (0.80 - 0.10 * stripe),
            k * 0.74,
            k * (0.58 + 0.18 * stripe),
        ]
    }
}

/// Skin albedo per projector channel (R, G, B).
pub const SKIN_ALBEDO: [f64; 3] = [0.78, 0.55, 0.44];

#[cfg(test)]
mod tests;
