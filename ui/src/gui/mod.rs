//! The desktop application (eframe + egui, drawing the cloud with wgpu). It is a thin layer over
//! the library: [`source`] runs the pipeline and the tracker, the views and panels draw what
//! they produce and turn clicks into edits, and the wizards drive the calibration functions.
//! See ARCHITECTURE.md for the picture.

pub mod app;
pub mod camera_view;
pub mod cloud_view;
pub mod exports;
pub mod live_rig;
pub mod plot_ui;
pub mod points;
pub mod projector_screen;
pub mod replay_ui;
pub mod rig_devices;
pub mod settings;
pub mod settings_ui;
pub mod source;
pub mod status_ui;
pub mod tremor_ui;
pub mod trial_ui;
pub mod wizard_colour;
pub mod wizard_geometric;

use anyhow::{anyhow, Result};

/// Options of `tremorscan gui`.
#[derive(clap::Args, Debug, Clone, Default)]
pub struct GuiArgs {
    /// Start with a control point at camera pixel `U,V` (repeatable).
    #[arg(long = "point", value_name = "U,V")]
    pub points: Vec<String>,
}

/// The window icon, from the embedded 256 px PNG (an empty icon if it cannot be decoded).
fn window_icon() -> egui::IconData {
    const PNG: &[u8] = include_bytes!("../../../assets/icons/tremorscan-256.png");
    decode_icon(PNG).unwrap_or_default()
}

fn decode_icon(bytes: &[u8]) -> Option<egui::IconData> {
    let mut decoder = png::Decoder::new(std::io::Cursor::new(bytes));
    decoder.set_transformations(png::Transformations::normalize_to_color8());
    let mut reader = decoder.read_info().ok()?;
    let mut buf = vec![0; reader.output_buffer_size()?];
    let info = reader.next_frame(&mut buf).ok()?;
    let rgba: Vec<u8> = match info.color_type {
        png::ColorType::Rgba => buf[..info.buffer_size()].to_vec(),
        png::ColorType::Rgb => buf[..info.buffer_size()]
            .chunks_exact(3)
            .flat_map(|p| [p[0], p[1], p[2], 255])
            .collect(),
        _ => return None,
    };
    Some(egui::IconData {
        rgba,
        width: info.width,
        height: info.height,
    })
}

/// Parses `U,V` into a pixel.
fn parse_pixel(text: &str) -> Result<(f64, f64)> {
    let parts: Vec<f64> = text
        .split(',')
        .map(|p| p.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| anyhow!("--point {text}: expected U,V (two numbers)"))?;
    match parts.as_slice() {
        [u, v] if u.is_finite() && v.is_finite() => Ok((*u, *v)),
        _ => Err(anyhow!("--point {text}: expected U,V (two numbers)")),
    }
}

/// Opens the main window on the device of the saved settings (the virtual rig by default).
pub fn run(args: &GuiArgs) -> Result<()> {
    let points = args
        .points
        .iter()
        .map(|p| parse_pixel(p))
        .collect::<Result<Vec<_>>>()?;
    let path = settings::default_path();
    let (settings, problem) = settings::load(&path);
    let options = eframe::NativeOptions {
        renderer: eframe::Renderer::Wgpu,
        // Eframe's depth buffer lets near points hide far ones (see cloud_view::DEPTH_FORMAT).
        depth_buffer: 32,
        viewport: egui::ViewportBuilder::default()
            .with_title("tremorscan")
            .with_app_id("tremorscan")
            .with_icon(window_icon())
            .with_inner_size([1400.0, 900.0])
            .with_min_inner_size([900.0, 600.0]),
        ..Default::default()
    };
    eframe::run_native(
        "tremorscan",
        options,
        Box::new(move |cc| {
            let has_renderer = match &cc.wgpu_render_state {
                Some(state) => {
                    cloud_view::install_renderer(state, Some(cloud_view::DEPTH_FORMAT));
                    true
                }
                None => false,
            };
            let mut app = app::TremorApp::new(settings, Some(path), has_renderer);
            if let Some(problem) = problem {
                app.messages.error(problem);
            }
            app.apply_edits(
                points
                    .into_iter()
                    .map(|pixel| points::PointEdit::Add { pixel })
                    .collect(),
            );
            Ok(Box::new(app))
        }),
    )
    .map_err(|e| anyhow!("the window could not open: {e}"))
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_embedded_icon_decodes_to_256_px_rgba() {
        let icon = super::window_icon();
        assert_eq!((icon.width, icon.height), (256, 256));
        assert_eq!(icon.rgba.len(), 256 * 256 * 4);
        // Transparent corners, opaque centre.
        assert_eq!(icon.rgba[3], 0);
        assert_eq!(icon.rgba[(128 * 256 + 128) * 4 + 3], 255);
    }

    #[test]
    fn points_parse_or_say_what_is_expected() {
        assert_eq!(super::parse_pixel("320, 200").ok(), Some((320.0, 200.0)));
        for bad in ["320", "a,b", "1,2,3", "nan,1"] {
            let e = super::parse_pixel(bad).expect_err(bad);
            assert!(e.to_string().contains("expected U,V"), "{e}");
        }
    }
}
