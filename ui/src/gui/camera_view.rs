//! The live camera image: the raw frame, or the decoded colour, fringe amplitude or phase
//! (projector coordinate), with invalid pixels in a colour of their own. Clicking the image adds
//! a control point at that pixel; dragging a point's marker moves it.

use super::points::{draw_marker, PointColours, PointEdit};
use egui::{Color32, ColorImage, Pos2, Rect, Sense, TextureHandle, TextureOptions, Vec2};
use tremorscan::pipeline::CloudFrame;
use tremorscan::tremor::LiveTracker;

/// What the image shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ImageMode {
    Raw,
    Colour,
    Amplitude,
    Phase,
}

impl ImageMode {
    pub const ALL: [ImageMode; 4] = [
        ImageMode::Raw,
        ImageMode::Colour,
        ImageMode::Amplitude,
        ImageMode::Phase,
    ];

    pub fn label(self) -> &'static str {
        match self {
            ImageMode::Raw => "Raw",
            ImageMode::Colour => "Colour",
            ImageMode::Amplitude => "Amplitude",
            ImageMode::Phase => "Phase",
        }
    }
}

/// Pixels the decoder rejected, in the decoded views.
pub const INVALID: Color32 = Color32::from_rgb(90, 0, 90);

/// A blue → green → yellow ramp for a value in [0, 1].
fn ramp(t: f32) -> Color32 {
    let t = t.clamp(0.0, 1.0);
    let r = (255.0 * (1.5 * t - 0.5).clamp(0.0, 1.0)) as u8;
    let g = (255.0 * (1.6 * t).min(1.0) * (1.1 - 0.2 * t)).min(255.0) as u8;
    let b = (255.0 * (1.0 - 1.4 * t).clamp(0.0, 1.0) * 0.9 + 20.0) as u8;
    Color32::from_rgb(r, g, b)
}

/// Renders `frame` in `mode` into `out` (width × height pixels, row-major).
pub fn render_image(frame: &CloudFrame, mode: ImageMode, out: &mut Vec<Color32>) {
    let cloud = &frame.cloud;
    let n = cloud.width * cloud.height;
    out.clear();
    let valid = |i: usize| cloud.point_in_camera_mm[i][2].is_finite();
    match mode {
        ImageMode::Raw => {
            let Some(img) = frame.camera.as_ref().map(|c| &c.frame) else {
                out.resize(n, Color32::BLACK);
                return;
            };
            if img.width * img.height != n {
                out.resize(n, Color32::BLACK);
                return;
            }
            let c = img.channels;
            out.extend(img.data.chunks_exact(c).map(|p| {
                if c == 3 {
                    Color32::from_rgb(p[0], p[1], p[2])
                } else {
                    Color32::from_gray(p[0])
                }
            }));
        }
        ImageMode::Colour => out.extend((0..n).map(|i| {
            let [r, g, b] = cloud.colour_rgb[i];
            if valid(i) {
                Color32::from_rgb(r, g, b)
            } else {
                INVALID
            }
        })),
        ImageMode::Amplitude => {
            let max = cloud
                .fringe_amplitude
                .iter()
                .copied()
                .filter(|a| a.is_finite())
                .fold(0.0f32, f32::max)
                .max(1e-6);
            out.extend((0..n).map(|i| {
                if valid(i) {
                    Color32::from_gray((255.0 * cloud.fringe_amplitude[i] / max) as u8)
                } else {
                    INVALID
                }
            }));
        }
        ImageMode::Phase => {
            let (lo, hi) = frame
                .projector_px
                .iter()
                .filter(|v| v.is_finite())
                .fold((f32::MAX, f32::MIN), |(a, b), &v| (a.min(v), b.max(v)));
            let span = (hi - lo).max(1e-6);
            out.extend((0..n).map(|i| match frame.projector_px.get(i) {
                Some(&v) if v.is_finite() && valid(i) => ramp((v - lo) / span),
                _ => INVALID,
            }));
        }
    }
}

/// The image panel's state.
#[derive(Default)]
pub struct CameraView {
    pub mode: Option<ImageMode>,
    texture: Option<TextureHandle>,
    pixels: Vec<Color32>,
    /// Window of the texture (`window_end`) and mode shown.
    shown: Option<(u64, ImageMode)>,
    /// The point being dragged and where it is now.
    dragging: Option<(u64, (f64, f64))>,
}

impl CameraView {
    fn mode(&self) -> ImageMode {
        self.mode.unwrap_or(ImageMode::Raw)
    }

    /// Draws the view; pushes the point edits the user made.
    pub fn camera_view_ui(
        &mut self,
        ui: &mut egui::Ui,
        frame: Option<&CloudFrame>,
        tracker: &LiveTracker,
        colours: &mut PointColours,
        edits: &mut Vec<PointEdit>,
    ) {
        ui.horizontal(|ui| {
            ui.label("Camera:");
            let mut mode = self.mode();
            for m in ImageMode::ALL {
                ui.selectable_value(&mut mode, m, m.label());
            }
            self.mode = Some(mode);
            if mode != ImageMode::Raw {
                let (rect, _) = ui.allocate_exact_size(Vec2::splat(12.0), Sense::hover());
                ui.painter().rect_filled(rect, 2.0, INVALID);
                ui.label("invalid");
            }
        });
        let Some(frame) = frame else {
            ui.centered_and_justified(|ui| ui.label("Waiting for the first decoded frame…"));
            return;
        };
        let (w, h) = (frame.cloud.width, frame.cloud.height);
        if self.shown != Some((frame.window_end, self.mode())) {
            render_image(frame, self.mode(), &mut self.pixels);
            let image = ColorImage::new([w, h], std::mem::take(&mut self.pixels));
            match &mut self.texture {
                Some(t) => t.set(image, TextureOptions::NEAREST),
                None => {
                    self.texture = Some(ui.ctx().load_texture(
                        "camera",
                        image,
                        TextureOptions::NEAREST,
                    ));
                }
            }
            self.shown = Some((frame.window_end, self.mode()));
        }
        let Some(texture) = &self.texture else {
            return;
        };
        let available = ui.available_size();
        let scale = (available.x / w as f32)
            .min(available.y / h as f32)
            .max(0.05);
        let size = Vec2::new(w as f32 * scale, h as f32 * scale);
        let (rect, response) = ui.allocate_exact_size(size, Sense::click_and_drag());
        response.widget_info(|| egui::WidgetInfo::labeled(egui::Role::Image, true, "camera image"));
        ui.painter().image(
            texture.id(),
            rect,
            Rect::from_min_max(Pos2::ZERO, Pos2::new(1.0, 1.0)),
            Color32::WHITE,
        );
        let to_screen = |(u, v): (f64, f64)| {
            Pos2::new(
                rect.min.x + (u as f32 + 0.5) * scale,
                rect.min.y + (v as f32 + 0.5) * scale,
            )
        };
        let to_pixel = |p: Pos2| {
            let u = ((p.x - rect.min.x) / scale - 0.5).round() as f64;
            let v = ((p.y - rect.min.y) / scale - 0.5).round() as f64;
            (u.clamp(0.0, w as f64 - 1.0), v.clamp(0.0, h as f64 - 1.0))
        };
        if response.drag_started() {
            // Where the button went down: a drag only starts once the pointer has moved.
            let origin = ui.input(|i| i.pointer.press_origin());
            if let Some(at) = origin.or(response.interact_pointer_pos()) {
                self.dragging = tracker
                    .points
                    .iter()
                    .find(|p| to_screen(p.current_pixel()).distance(at) < 10.0)
                    .map(|p| (p.id, p.current_pixel()));
            }
        }
        if let (Some((id, _)), Some(at)) = (self.dragging, response.interact_pointer_pos()) {
            if response.dragged() {
                self.dragging = Some((id, to_pixel(at)));
            }
        }
        if response.drag_stopped() {
            if let Some((id, pixel)) = self.dragging.take() {
                edits.push(PointEdit::Move { id, pixel });
            }
        }
        if response.clicked() {
            if let Some(at) = response.interact_pointer_pos() {
                let on_marker = tracker
                    .points
                    .iter()
                    .any(|p| to_screen(p.current_pixel()).distance(at) < 6.0);
                if !on_marker {
                    edits.push(PointEdit::Add {
                        pixel: to_pixel(at),
                    });
                }
            }
        }
        let painter = ui.painter_at(rect);
        for p in &tracker.points {
            let pixel = match self.dragging {
                Some((id, pixel)) if id == p.id => pixel,
                _ => p.current_pixel(),
            };
            draw_marker(&painter, to_screen(pixel), colours.colour(p.id), &p.name);
        }
        response.on_hover_text("Click to add a control point; drag a marker to move it");
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;
    use tremorscan::frame::Frame;
    use tremorscan::pipeline::CapturedFrame;
    use tremorscan::triangulate::PointCloud;

    #[test]
    fn decoded_views_mark_invalid_pixels_and_raw_shows_the_frame() {
        let frame = CloudFrame {
            cloud: PointCloud {
                width: 2,
                height: 1,
                time_s: 0.0,
                point_in_camera_mm: vec![[0.0, 0.0, 500.0], [f32::NAN; 3]],
                colour_rgb: vec![[10, 20, 30], [40, 50, 60]],
                fringe_amplitude: vec![4.0, 0.0],
            },
            camera: Some(Arc::new(CapturedFrame {
                frame: Frame::from_data(2, 1, 3, vec![1, 2, 3, 4, 5, 6]).expect("frame"),
                sequence_number: 7,
                arrived: std::time::Instant::now(),
            })),
            projector_px: vec![100.0, f32::NAN],
            window_end: 7,
            latency: Default::default(),
        };
        let mut out = Vec::new();
        render_image(&frame, ImageMode::Raw, &mut out);
        assert_eq!(
            out,
            [Color32::from_rgb(1, 2, 3), Color32::from_rgb(4, 5, 6)]
        );
        render_image(&frame, ImageMode::Colour, &mut out);
        assert_eq!(out, [Color32::from_rgb(10, 20, 30), INVALID]);
        render_image(&frame, ImageMode::Amplitude, &mut out);
        assert_eq!(out, [Color32::from_gray(255), INVALID]);
        render_image(&frame, ImageMode::Phase, &mut out);
        assert_eq!(out[1], INVALID);
        assert_ne!(out[0], INVALID);
    }
}
