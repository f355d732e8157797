//! The desktop application (eframe + egui, drawing the cloud with wgpu). It is a thin layer over
//! the library: [`source`] runs the pipeline and the tracker, the views and panels draw what
//! they produce and turn clicks into edits, and the wizards drive the calibration functions.
//! See ARCHITECTURE.md for the picture.

pub mod app;
pub mod camera_view;
pub mod cloud_view;
pub mod exports;
pub mod plot_ui;
pub mod points;
pub mod replay_ui;
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
