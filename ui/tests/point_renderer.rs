//! The wgpu point renderer draws a full 1920×1200 organised cloud, each point in its decoded
//! colour, through the same egui paint callback the app uses (rendered offscreen by egui_kittest
//! on lavapipe here).

use egui_kittest::wgpu::{create_render_state, default_wgpu_setup, WgpuTestRenderer};
use egui_kittest::Harness;
use tremorscan::pipeline::CloudFrame;
use tremorscan::tremor::LiveTracker;
use tremorscan::triangulate::PointCloud;
use tremorscan_ui::gui::cloud_view::{install_renderer, CloudView};
use tremorscan_ui::gui::points::PointColours;
use tremorscan_ui::render::orbit::ViewPreset;

/// A flat 480 × 300 mm card 500 mm away, one point per pixel: the left half red, the right green,
/// a band of invalid points (NaN) across the middle rows.
fn card() -> CloudFrame {
    let (w, h) = (1920usize, 1200usize);
    let mut points = Vec::with_capacity(w * h);
    let mut colours = Vec::with_capacity(w * h);
    for y in 0..h {
        for x in 0..w {
            let invalid = (590..610).contains(&y);
            let p = [
                (x as f32 / w as f32 - 0.5) * 480.0,
                (y as f32 / h as f32 - 0.5) * 300.0,
                500.0,
            ];
            points.push(if invalid { [f32::NAN; 3] } else { p });
            colours.push(if x < w / 2 { [255, 0, 0] } else { [0, 255, 0] });
        }
    }
    CloudFrame {
        cloud: PointCloud {
            width: w,
            height: h,
            time_s: 0.0,
            point_in_camera_mm: points,
            colour_rgb: colours,
            fringe_amplitude: vec![1.0; w * h],
        },
        camera: None,
        projector_px: Vec::new(),
        window_end: 1,
        latency: Default::default(),
    }
}

#[test]
fn a_full_resolution_cloud_is_drawn_in_its_colours() {
    let render_state = create_render_state(
        default_wgpu_setup(),
        egui_wgpu::RendererOptions::PREDICTABLE,
    );
    // Kittest's pass has no depth attachment.
    install_renderer(&render_state, None);
    let frame = card();
    let tracker = LiveTracker::new(5.0);
    let mut view = CloudView::new(true, 2.0);
    view.reset(Some(&frame), ViewPreset::Top);
    let mut colours = PointColours::default();
    let mut harness = Harness::builder()
        .with_size(egui::vec2(480.0, 360.0))
        .renderer(WgpuTestRenderer::from_render_state(render_state))
        .build_ui(move |ui| {
            let mut edits = Vec::new();
            view.cloud_view_ui(ui, Some(&frame), &tracker, &mut colours, &mut edits);
        });
    harness.run_steps(2);
    let image = harness.render().expect("rendered");
    if let Ok(path) = std::env::var("TREMORSCAN_SAVE_RENDER") {
        image.save(path).expect("save the render");
    }
    let (mut red, mut green) = (Vec::new(), Vec::new());
    for (x, y, p) in image.enumerate_pixels() {
        match p.0 {
            [r, g, b, _] if r > 200 && g < 40 && b < 40 => red.push((x, y)),
            [r, g, b, _] if g > 200 && r < 40 && b < 40 => green.push((x, y)),
            _ => {}
        }
    }
    let total = (image.width() * image.height()) as usize;
    // The card fills a good part of the view, half of it each colour.
    assert!(
        red.len() > total / 20 && green.len() > total / 20,
        "red {} green {} of {total}",
        red.len(),
        green.len()
    );
    let mean_x = |v: &[(u32, u32)]| v.iter().map(|p| f64::from(p.0)).sum::<f64>() / v.len() as f64;
    assert!(
        mean_x(&red) < mean_x(&green),
        "red is on the left as seen from the rig camera"
    );
    // The invalid band is not drawn: the middle row of the card shows the background.
    let mean_y = |v: &[(u32, u32)]| v.iter().map(|p| f64::from(p.1)).sum::<f64>() / v.len() as f64;
    let centre = (mean_x(&red) as u32 + 10, mean_y(&red) as u32);
    let p = image.get_pixel(centre.0, centre.1).0;
    assert!(
        !(p[0] > 200 && p[1] < 40),
        "pixel {centre:?} inside the invalid band is {p:?}"
    );
}
