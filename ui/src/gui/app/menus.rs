//! The toolbar (device, replay, exports, wizards, settings) and the wizards' windows, and what
//! their outcomes do to the app.

use super::TremorApp;
use crate::gui::exports::{self, ExportKind};
use crate::gui::settings::DeviceChoice;
use crate::gui::wizard_colour::{ColourWizard, WizardOutcome};
use crate::gui::wizard_geometric::GeometricWizard;
use std::path::PathBuf;

impl TremorApp {
    fn export(&mut self, kind: ExportKind, ctx: &egui::Context) {
        let Some(path) = exports::ask_path(kind, &self.settings.export_dir) else {
            return;
        };
        if let Some(dir) = path.parent() {
            self.settings.export_dir = dir.to_path_buf();
        }
        self.export_to(kind, path, ctx);
    }

    pub(super) fn toolbar_ui(&mut self, ui: &mut egui::Ui) {
        ui.horizontal_wrapped(|ui| {
            ui.strong("tremorscan");
            ui.separator();
            let live = self.settings.device == DeviceChoice::VirtualRig;
            if ui.selectable_label(live, "Virtual rig").clicked() && !live {
                self.use_virtual_rig();
            }
            if ui.button("Open session…").clicked() {
                if let Some(dir) = rfd::FileDialog::new()
                    .set_title("Open a session folder")
                    .pick_folder()
                {
                    self.open_replay(dir);
                }
            }
            let l = ui.label("Session:");
            ui.add(
                egui::TextEdit::singleline(&mut self.replay_path)
                    .hint_text("session folder")
                    .desired_width(180.0)
                    .id_salt("replay_path"),
            )
            .labelled_by(l.id);
            if ui.button("Open replay").clicked() && !self.replay_path.trim().is_empty() {
                self.open_replay(PathBuf::from(self.replay_path.trim()));
            }
            ui.separator();
            ui.menu_button("Export", |ui| {
                for kind in [
                    ExportKind::CloudPly,
                    ExportKind::TrackCsv,
                    ExportKind::ReportPng,
                    ExportKind::Screenshot,
                ] {
                    if ui.button(kind.label()).clicked() {
                        ui.close();
                        self.export(kind, ui.ctx());
                    }
                }
            });
            if ui.button("Colour calibration…").clicked() {
                self.start_colour_wizard();
            }
            if ui.button("Geometric calibration…").clicked() {
                self.start_geometric_wizard();
            }
            if ui.button("Settings…").clicked() {
                self.settings_draft = self.settings.clone();
                self.show_settings = true;
            }
        });
    }

    pub fn start_colour_wizard(&mut self) {
        match crate::gui::source::virtual_rig(&self.settings) {
            Ok(rig) => {
                let path = self.settings.export_dir.join("colour-calibration.json");
                self.colour_wizard = Some(ColourWizard::new(rig.config, path));
            }
            Err(e) => self.messages.error(format!("{e:#}")),
        }
    }

    pub fn start_geometric_wizard(&mut self) {
        match crate::gui::source::virtual_rig(&self.settings) {
            Ok(rig) => {
                let path = self.settings.export_dir.join("calibration.json");
                self.geometric_wizard = Some(GeometricWizard::new(rig.config, path));
            }
            Err(e) => self.messages.error(format!("{e:#}")),
        }
    }

    pub(super) fn wizards_ui(&mut self, ctx: &egui::Context) {
        if let Some(w) = &mut self.colour_wizard {
            let mut outcome = WizardOutcome::Open;
            egui::Window::new("Colour calibration").show(ctx, |ui| {
                outcome = crate::gui::wizard_colour::colour_wizard_ui(ui, w);
            });
            match outcome {
                WizardOutcome::Open => {}
                WizardOutcome::Closed => self.colour_wizard = None,
                WizardOutcome::Saved(path) => {
                    self.messages.info(format!(
                        "saved the colour calibration to {}; the virtual rig now decodes with it",
                        path.display()
                    ));
                    self.settings.colour_file = Some(path);
                    self.colour_wizard = None;
                    self.restart_source();
                }
            }
        }
        if let Some(w) = &mut self.geometric_wizard {
            let mut outcome = WizardOutcome::Open;
            egui::Window::new("Geometric calibration").show(ctx, |ui| {
                outcome = crate::gui::wizard_geometric::geometric_wizard_ui(ui, w);
            });
            match outcome {
                WizardOutcome::Open => {}
                WizardOutcome::Closed => self.geometric_wizard = None,
                WizardOutcome::Saved(path) => {
                    self.messages.info(format!(
                        "saved the calibration to {}; the virtual rig now triangulates with it",
                        path.display()
                    ));
                    self.settings.calibration_file = Some(path);
                    self.geometric_wizard = None;
                    self.restart_source();
                }
            }
        }
    }
}
