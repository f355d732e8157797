//! The settings window: device, virtual rig size, pattern parameters (n, axis, bit depth), the
//! unwrapping method and the calibration files in use. Changes apply (and persist) with
//! "Apply", which restarts the device; the control points are kept.

use super::app::TremorApp;
use super::settings::{DeviceChoice, UnwrapChoice};

pub fn settings_window_ui(ctx: &egui::Context, app: &mut TremorApp) {
    if !app.show_settings {
        return;
    }
    let mut open = true;
    let mut apply = false;
    egui::Window::new("Settings").open(&mut open).show(ctx, |ui| {
        let d = &mut app.settings_draft;
        egui::Grid::new("settings_grid").num_columns(2).show(ui, |ui| {
            ui.label("Device");
            ui.vertical(|ui| {
                let mut virtual_rig = d.device == DeviceChoice::VirtualRig;
                ui.radio_value(&mut virtual_rig, true, "virtual rig (simulated projector, camera and hand)");
                ui.radio_value(&mut virtual_rig, false, "replay of a saved session");
                if virtual_rig {
                    d.device = DeviceChoice::VirtualRig;
                } else if d.device == DeviceChoice::VirtualRig {
                    d.device = DeviceChoice::Replay {
                        session: app.replay_path.trim().into(),
                    };
                }
                ui.label("Real devices (GenICam camera, LightCrafter 4500, second screen) appear here when the app is built with their features.");
            });
            ui.end_row();
            let l = ui.label("Virtual camera");
            ui.horizontal(|ui| {
                ui.add(egui::DragValue::new(&mut d.rig_width).range(64..=1920).suffix(" px"))
                    .labelled_by(l.id);
                ui.label("×");
                ui.add(egui::DragValue::new(&mut d.rig_height).range(40..=1200).suffix(" px"))
                    .labelled_by(l.id);
            });
            ui.end_row();
            let l = ui.label("Fringes n");
            ui.add(egui::DragValue::new(&mut d.fringe_count).range(3..=200))
                .labelled_by(l.id)
                .on_hover_text("the highest of the three frequencies n, n−1, n−2");
            ui.end_row();
            ui.label("Coded axis");
            ui.horizontal(|ui| {
                ui.radio_value(&mut d.code_columns, true, "columns");
                ui.radio_value(&mut d.code_columns, false, "rows");
            });
            ui.end_row();
            let l = ui.label("Projector bits");
            ui.add(egui::DragValue::new(&mut d.projector_bits).range(1..=8))
                .labelled_by(l.id);
            ui.end_row();
            ui.label("Unwrapping");
            ui.horizontal(|ui| {
                ui.radio_value(&mut d.unwrap, UnwrapChoice::Robust, "robust (neighbourhood)");
                ui.radio_value(&mut d.unwrap, UnwrapChoice::PerPixel, "per pixel (paper)");
            });
            ui.end_row();
            ui.label("Colour calibration");
            ui.horizontal(|ui| {
                ui.label(d.colour_file.as_ref().map_or("the rig's own".to_string(), |p| p.display().to_string()));
                if d.colour_file.is_some() && ui.small_button("clear").clicked() {
                    d.colour_file = None;
                }
            });
            ui.end_row();
            ui.label("Geometric calibration");
            ui.horizontal(|ui| {
                ui.label(d.calibration_file.as_ref().map_or("the rig's own".to_string(), |p| p.display().to_string()));
                if d.calibration_file.is_some() && ui.small_button("clear").clicked() {
                    d.calibration_file = None;
                }
            });
            ui.end_row();
        });
        if ui.button("Apply").clicked() {
            apply = true;
        }
    });
    if apply {
        app.settings = app.settings_draft.clone();
        app.show_settings = false;
        app.restart_source();
    } else {
        app.show_settings = open;
    }
}
