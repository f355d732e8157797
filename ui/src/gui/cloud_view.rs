//! The 3D view: the egui side of [`crate::render::point_cloud`]. The renderer lives in egui-wgpu's
//! callback resources (created once with the app); each frame this view adds a paint callback
//! that uploads the newest cloud (only when it changed) and the view matrix, then draws into
//! egui's own render pass. Dragging orbits (dragging a marker moves its point to the surface
//! point where it is dropped), right- or middle-dragging pans, scrolling zooms, a click picks
//! the surface point under the pointer and adds a control point there; markers are projected
//! with the shader's own matrix.

use super::points::{draw_marker, PointColours, PointEdit};
use crate::render::orbit::{pick, project, OrbitCamera, ViewPreset};
use crate::render::point_cloud::{pack_points, PointCloudRenderer, PointUniforms, PointVertex};
use egui::{Color32, PointerButton, Sense, Vec2};
use egui_wgpu::CallbackTrait;
use nalgebra::Vector3;
use std::sync::Arc;
use tremorscan::pipeline::CloudFrame;
use tremorscan::tremor::LiveTracker;

/// Depth buffer the app asks eframe for, shared by egui's pass and the point pipeline.
pub const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// Registers the renderer with egui-wgpu; `depth_format` must match the render pass it will
/// draw into (eframe's depth buffer, or none).
pub fn install_renderer(
    render_state: &egui_wgpu::RenderState,
    depth_format: Option<wgpu::TextureFormat>,
) {
    let renderer = PointCloudRenderer::new(
        &render_state.device,
        render_state.target_format,
        depth_format,
    );
    render_state
        .renderer
        .write()
        .callback_resources
        .insert(renderer);
}

struct CloudCallback {
    /// The points of the newest cloud and its window number; uploaded by `prepare` when the
    /// renderer holds another window (a UI pass is not always painted, so every callback
    /// carries the points rather than only the pass where they changed).
    points: Arc<Vec<PointVertex>>,
    window: u64,
    uniforms: PointUniforms,
}

impl CallbackTrait for CloudCallback {
    fn prepare(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        _screen: &egui_wgpu::ScreenDescriptor,
        _encoder: &mut wgpu::CommandEncoder,
        resources: &mut egui_wgpu::CallbackResources,
    ) -> Vec<wgpu::CommandBuffer> {
        if let Some(renderer) = resources.get_mut::<PointCloudRenderer>() {
            if renderer.uploaded_window() != Some(self.window) {
                renderer.upload(device, queue, &self.points, self.window);
            }
            renderer.set_view(queue, &self.uniforms);
        }
        Vec::new()
    }

    fn paint(
        &self,
        _info: egui::PaintCallbackInfo,
        pass: &mut wgpu::RenderPass<'static>,
        resources: &egui_wgpu::CallbackResources,
    ) {
        if let Some(renderer) = resources.get::<PointCloudRenderer>() {
            renderer.draw(pass);
        }
    }
}

pub struct CloudView {
    pub camera: Option<OrbitCamera>,
    pub point_size_px: f32,
    packed: Arc<Vec<PointVertex>>,
    /// Window last uploaded.
    uploaded: Option<u64>,
    /// Whether a wgpu renderer was installed (false under a renderer without wgpu).
    pub has_renderer: bool,
    /// Radius of the cloud to fit into the view at the next draw (when the view's size is known).
    fit_radius_mm: Option<f32>,
    /// The control point whose marker is being dragged, and where the pointer is.
    dragging: Option<(u64, egui::Pos2)>,
}

impl CloudView {
    pub fn new(has_renderer: bool, point_size_px: f32) -> Self {
        Self {
            camera: None,
            point_size_px,
            packed: Arc::new(Vec::new()),
            uploaded: None,
            has_renderer,
            fit_radius_mm: None,
            dragging: None,
        }
    }

    /// A view of `frame` from `preset`, centred on its valid points.
    pub fn reset(&mut self, frame: Option<&CloudFrame>, preset: ViewPreset) {
        let points = frame.map_or(&[][..], |f| &f.cloud.point_in_camera_mm[..]);
        let target = centroid(points).unwrap_or(Vector3::new(0.0, 0.0, 500.0));
        self.fit_radius_mm = Some(radius_about(points, &target).unwrap_or(200.0));
        self.camera = Some(OrbitCamera::new(preset, target, 750.0));
    }

    pub fn cloud_view_ui(
        &mut self,
        ui: &mut egui::Ui,
        frame: Option<&CloudFrame>,
        tracker: &LiveTracker,
        colours: &mut PointColours,
        edits: &mut Vec<PointEdit>,
    ) {
        ui.horizontal_wrapped(|ui| {
            ui.label("3D:");
            if ui.button("Reset view").clicked() {
                self.reset(frame, ViewPreset::Top);
            }
            if ui.button("Top").clicked() {
                self.reset(frame, ViewPreset::Top);
            }
            if ui.button("Side").clicked() {
                self.reset(frame, ViewPreset::Side);
            }
            let l = ui.label("point size");
            ui.add(
                egui::DragValue::new(&mut self.point_size_px)
                    .range(1.0..=6.0)
                    .speed(0.1)
                    .suffix(" px"),
            )
            .labelled_by(l.id);
            if let Some(f) = frame {
                ui.label(format!(
                    "{} points",
                    self.packed.len().min(f.cloud.width * f.cloud.height)
                ));
            }
        });
        if self.camera.is_none() && frame.is_some() {
            self.reset(frame, ViewPreset::Top);
        }
        // What is left of the column and visible: the projection is centred on this rect.
        let rect = ui.available_rect_before_wrap().intersect(ui.clip_rect());
        let rect = egui::Rect::from_min_size(rect.min, rect.size().max(Vec2::splat(50.0)));
        let response = ui.allocate_rect(rect, Sense::click_and_drag());
        response.widget_info(|| egui::WidgetInfo::labeled(egui::Role::Image, true, "3D view"));
        ui.painter().rect_filled(rect, 0.0, Color32::from_gray(18));
        let Some(camera) = &mut self.camera else {
            ui.painter().text(
                rect.center(),
                egui::Align2::CENTER_CENTER,
                "Waiting for the first cloud…",
                egui::FontId::proportional(14.0),
                Color32::GRAY,
            );
            return;
        };
        if let Some(radius) = self.fit_radius_mm.take() {
            // Far enough that a sphere of `radius` fits the narrower of the two fields of view.
            let half_y = camera.fov_y_rad / 2.0;
            let aspect = rect.width() / rect.height().max(1.0);
            let half_x = (aspect * half_y.tan()).atan();
            camera.distance_mm = radius / half_y.min(half_x).sin().max(0.05);
        }
        let aspect = rect.width() / rect.height().max(1.0);
        let view_size = [rect.width(), rect.height()];
        if response.drag_started_by(PointerButton::Primary) {
            // A drag that starts on a marker moves that point; anywhere else it orbits.
            let origin = ui.input(|i| i.pointer.press_origin());
            let m = camera.clip_from_world(aspect);
            self.dragging = origin.and_then(|o| {
                tracker
                    .points
                    .iter()
                    .find(|p| {
                        marker_at(&m, p, rect, view_size).is_some_and(|c| c.distance(o) < 10.0)
                    })
                    .map(|p| (p.id, o))
            });
        }
        if response.dragged_by(PointerButton::Primary) {
            match (&mut self.dragging, response.interact_pointer_pos()) {
                (Some((_, at)), Some(now)) => *at = now,
                (Some(_), None) => {}
                (None, _) => {
                    let d = response.drag_delta();
                    camera.orbit(d.x, d.y);
                }
            }
        }
        if response.dragged_by(PointerButton::Secondary)
            || response.dragged_by(PointerButton::Middle)
        {
            let d = response.drag_delta();
            camera.pan(d.x, d.y, rect.height());
        }
        if response.hovered() {
            let scroll = ui.input(|i| i.smooth_scroll_delta.y);
            if scroll != 0.0 {
                camera.zoom((scroll * 0.002).exp());
            }
        }
        let clip_from_world = camera.clip_from_world(aspect);
        // The camera pixel of the surface point drawn under `at` (screen points).
        let pixel_under = |at: egui::Pos2| {
            let f = frame?;
            let local = at - rect.min;
            let i = pick(
                &clip_from_world,
                &f.cloud.point_in_camera_mm,
                view_size,
                [local.x, local.y],
                8.0,
            )?;
            Some(((i % f.cloud.width) as f64, (i / f.cloud.width) as f64))
        };
        if response.drag_stopped() {
            if let Some((id, at)) = self.dragging.take() {
                if let Some(pixel) = pixel_under(at) {
                    edits.push(PointEdit::Move { id, pixel });
                }
            }
        }
        if response.clicked() {
            if let Some(pixel) = response.interact_pointer_pos().and_then(pixel_under) {
                edits.push(PointEdit::Add { pixel });
            }
        }
        if let Some(f) = frame {
            if self.uploaded != Some(f.window_end) {
                // Reuse the buffer once the renderer's callbacks have let go of it.
                let mut packed =
                    Arc::try_unwrap(std::mem::take(&mut self.packed)).unwrap_or_default();
                pack_points(&f.cloud, 1, &mut packed);
                self.packed = Arc::new(packed);
                self.uploaded = Some(f.window_end);
            }
        }
        if self.has_renderer {
            let ppp = ui.ctx().pixels_per_point();
            let uniforms = PointUniforms {
                clip_from_world: clip_from_world.into(),
                viewport_px: [rect.width() * ppp, rect.height() * ppp],
                point_size_px: self.point_size_px * ppp,
                padding: 0.0,
            };
            ui.painter().add(egui_wgpu::Callback::new_paint_callback(
                rect,
                CloudCallback {
                    points: Arc::clone(&self.packed),
                    window: self.uploaded.unwrap_or(0),
                    uniforms,
                },
            ));
        } else {
            ui.painter().text(
                rect.center(),
                egui::Align2::CENTER_CENTER,
                "The 3D view needs the wgpu renderer",
                egui::FontId::proportional(14.0),
                Color32::GRAY,
            );
        }
        let painter = ui.painter_at(rect);
        for p in &tracker.points {
            draw_trail(
                &painter,
                &clip_from_world,
                p,
                rect,
                view_size,
                colours.colour(p.id),
            );
            let centre = match self.dragging {
                Some((id, at)) if id == p.id => Some(at),
                _ => marker_at(&clip_from_world, p, rect, view_size),
            };
            if let Some(centre) = centre {
                draw_marker(&painter, centre, colours.colour(p.id), &p.name);
            }
        }
        response.on_hover_text(
            "Drag: orbit (on a marker: move the point) · right/middle drag: pan · scroll: zoom · click: add a control point",
        );
    }
}

/// The seconds of a point's path drawn behind its marker.
const TRAIL_S: f64 = 1.0;

/// A control point's path over the last [`TRAIL_S`], broken where it was not measured.
fn draw_trail(
    painter: &egui::Painter,
    clip_from_world: &nalgebra::Matrix4<f32>,
    p: &tremorscan::tremor::LivePoint,
    rect: egui::Rect,
    view_size: [f32; 2],
    colour: Color32,
) {
    let Some(newest) = p.samples.back().map(|s| s.time_s) else {
        return;
    };
    let stroke = egui::Stroke::new(1.5, colour.gamma_multiply(0.8));
    let mut run: Vec<egui::Pos2> = Vec::new();
    for s in p.samples.iter().filter(|s| s.time_s >= newest - TRAIL_S) {
        let at = s.position_mm.and_then(|q| {
            project(
                clip_from_world,
                [q[0] as f32, q[1] as f32, q[2] as f32],
                view_size,
            )
            .map(|(s, _)| rect.min + Vec2::new(s[0], s[1]))
        });
        match at {
            Some(at) => run.push(at),
            None => {
                if run.len() > 1 {
                    painter.add(egui::Shape::line(std::mem::take(&mut run), stroke));
                }
                run.clear();
            }
        }
    }
    if run.len() > 1 {
        painter.add(egui::Shape::line(run, stroke));
    }
}

/// Where a control point's newest measured position is drawn, screen points.
fn marker_at(
    clip_from_world: &nalgebra::Matrix4<f32>,
    p: &tremorscan::tremor::LivePoint,
    rect: egui::Rect,
    view_size: [f32; 2],
) -> Option<egui::Pos2> {
    let q = p.latest_position_mm()?;
    let (s, _) = project(
        clip_from_world,
        [q[0] as f32, q[1] as f32, q[2] as f32],
        view_size,
    )?;
    Some(rect.min + Vec2::new(s[0], s[1]))
}

/// The distance from `centre` within which 95 % of the valid points lie (every 7th point), mm.
fn radius_about(points: &[[f32; 3]], centre: &Vector3<f32>) -> Option<f32> {
    let mut d: Vec<f32> = points
        .iter()
        .step_by(7)
        .filter(|p| p[2].is_finite())
        .map(|p| (Vector3::new(p[0], p[1], p[2]) - centre).norm())
        .collect();
    if d.is_empty() {
        return None;
    }
    let k = (d.len() * 95 / 100).min(d.len() - 1);
    let (_, r, _) = d.select_nth_unstable_by(k, f32::total_cmp);
    Some(*r)
}

/// Mean of the valid points (every 7th, enough for a view centre), mm.
fn centroid(points: &[[f32; 3]]) -> Option<Vector3<f32>> {
    let mut sum = Vector3::zeros();
    let mut n = 0usize;
    for p in points.iter().step_by(7).filter(|p| p[2].is_finite()) {
        sum += Vector3::new(p[0], p[1], p[2]);
        n += 1;
    }
    (n > 0).then(|| sum / n as f32)
}
