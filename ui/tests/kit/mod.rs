//! Shared helpers of the UI (kittest) tests: a scratch folder, test settings, the app in a kittest harness
//! on wgpu, and stepping until a condition holds.
#![allow(
    dead_code,
    reason = "each test binary uses a different subset of the helpers"
)]

use egui_kittest::Harness;
use std::path::PathBuf;
use std::time::{Duration, Instant};
use tremorscan_ui::gui::app::TremorApp;
use tremorscan_ui::gui::cloud_view::install_renderer;
use tremorscan_ui::gui::settings::Settings;

#[path = "../../../tests/common/scratch.rs"]
mod scratch_folder;
pub use scratch_folder::Scratch;

/// A fresh, created scratch folder for one GUI test.
pub fn scratch(name: &str) -> Scratch {
    scratch_folder::scratch_dir(&format!("gui-{name}"))
}

pub fn settings(dir: &std::path::Path) -> Settings {
    Settings {
        sessions_dir: dir.join("sessions"),
        export_dir: dir.join("exports"),
        countdown_seconds: 0.0,
        ..Settings::default()
    }
}

pub fn harness(settings: Settings) -> Harness<'static, TremorApp> {
    harness_persisting(settings, None)
}

/// The app in a harness, persisting its settings to `settings_path` when given.
pub fn harness_persisting(
    settings: Settings,
    settings_path: Option<PathBuf>,
) -> Harness<'static, TremorApp> {
    Harness::builder()
        .with_size(egui::vec2(1400.0, 900.0))
        .wgpu()
        .build_eframe(move |cc| {
            // Kittest's wgpu pass has no depth attachment, so the renderer gets none either.
            let has_renderer = cc.wgpu_render_state.as_ref().is_some_and(|s| {
                install_renderer(s, None);
                true
            });
            TremorApp::new(settings, settings_path, has_renderer)
        })
}

/// Steps the app until `done` holds, failing after `timeout`.
pub fn step_until(
    h: &mut Harness<'_, TremorApp>,
    timeout: Duration,
    what: &str,
    done: impl Fn(&TremorApp) -> bool,
) {
    let start = Instant::now();
    while !done(h.state()) {
        assert!(start.elapsed() < timeout, "timed out waiting for {what}");
        h.run_steps(1);
        std::thread::sleep(Duration::from_millis(10));
    }
}
