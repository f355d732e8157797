//! The settings window: device, virtual rig size, pattern parameters (n, axis, bit depth), the
//! unwrapping method and the calibration files in use. Changes apply (and persist) with
//! "Apply", which restarts the device; the control points are kept.

use super::app::TremorApp;
use super::settings::{DeviceChoice, ProjectorKind, UnwrapChoice};
use crate::gpu_decode::DecoderChoice;
use crate::unwrap_args::CoarseAverageArg;

/// The device radio buttons, and the camera's own settings when it is chosen.
fn device_choice_ui(ui: &mut egui::Ui, device: &mut DeviceChoice, replay_path: &str) {
    #[derive(PartialEq)]
    enum Kind {
        Rig,
        Replay,
        Camera,
    }
    let mut kind = match device {
        DeviceChoice::VirtualRig => Kind::Rig,
        DeviceChoice::Replay { .. } => Kind::Replay,
        DeviceChoice::Camera { .. } => Kind::Camera,
    };
    ui.radio_value(
        &mut kind,
        Kind::Rig,
        "virtual rig (simulated projector, camera and hand)",
    );
    ui.radio_value(&mut kind, Kind::Replay, "replay of a saved session");
    ui.radio_value(
        &mut kind,
        Kind::Camera,
        "GenICam camera with a second screen as projector",
    );
    match (kind, &*device) {
        (Kind::Rig, DeviceChoice::VirtualRig)
        | (Kind::Replay, DeviceChoice::Replay { .. })
        | (Kind::Camera, DeviceChoice::Camera { .. }) => {}
        (Kind::Rig, _) => *device = DeviceChoice::VirtualRig,
        (Kind::Replay, _) => {
            *device = DeviceChoice::Replay {
                session: replay_path.trim().into(),
            }
        }
        (Kind::Camera, _) => *device = DeviceChoice::default_camera(),
    }
    if let DeviceChoice::Camera {
        camera_id,
        exposure_micros,
        monitor,
        hold_refreshes,
        projector,
        binning,
    } = device
    {
        if !cfg!(feature = "genicam") {
            ui.colored_label(
                egui::Color32::from_rgb(255, 90, 90),
                "this build has no camera support (build with --features genicam; the .deb has it)",
            );
        }
        egui::Grid::new("camera_grid")
            .num_columns(2)
            .show(ui, |ui| {
                ui.label("Projector");
                ui.horizontal(|ui| {
                    ui.radio_value(projector, ProjectorKind::SecondScreen, "second screen");
                    ui.radio_value(
                        projector,
                        ProjectorKind::LightCrafter,
                        "LightCrafter 4500 on that output",
                    );
                });
                ui.end_row();
                let l = ui.label("Camera id");
                ui.add(egui::TextEdit::singleline(camera_id).hint_text("first camera found"))
                    .labelled_by(l.id);
                ui.end_row();
                let l = ui.label("Exposure");
                ui.add(
                    egui::DragValue::new(exposure_micros)
                        .range(50.0..=100_000.0)
                        .suffix(" µs"),
                )
                .labelled_by(l.id);
                ui.end_row();
                let l = ui.label("Binning");
                ui.add(
                    egui::DragValue::new(binning)
                        .range(1..=4)
                        // Shown as "2×2"; typed as its first number.
                        .custom_formatter(|v, _| format!("{v}×{v}"))
                        .custom_parser(|text| text.split('×').next()?.trim().parse().ok()),
                )
                .labelled_by(l.id)
                .on_hover_text(
                    "2×2: each pixel sums 2×2 sensor pixels, a quarter of the pixels to decode \
                     (tremorscan bench says which binning this PC keeps up with); calibrate at \
                     the same binning",
                );
                ui.end_row();
                let l = ui.label("Projector monitor");
                ui.add(egui::DragValue::new(monitor).range(0..=8))
                    .labelled_by(l.id)
                    .on_hover_text(
                        "the screen's number in the system's order; 0 is usually the main one",
                    );
                ui.end_row();
                let l = ui.label("Refreshes per pattern");
                ui.add(egui::DragValue::new(hold_refreshes).range(1..=8))
                    .labelled_by(l.id)
                    .on_hover_text("longer holds keep more frames certain at a lower pattern rate");
                ui.end_row();
            });
        ui.label("The camera needs the rig's geometric and colour calibration files (below).");
    }
}

pub fn settings_window_ui(ctx: &egui::Context, app: &mut TremorApp) {
    if !app.show_settings {
        return;
    }
    let mut open = true;
    let mut apply = false;
    egui::Window::new("Settings")
        .open(&mut open)
        .show(ctx, |ui| {
            let d = &mut app.settings_draft;
            egui::Grid::new("settings_grid")
                .num_columns(2)
                .show(ui, |ui| {
                    ui.label("Device");
                    ui.vertical(|ui| device_choice_ui(ui, &mut d.device, &app.replay_path));
                    ui.end_row();
                    let l = ui.label("Virtual camera");
                    ui.horizontal(|ui| {
                        ui.add(
                            egui::DragValue::new(&mut d.rig_width)
                                .range(64..=1920)
                                .suffix(" px"),
                        )
                        .labelled_by(l.id);
                        ui.label("×");
                        ui.add(
                            egui::DragValue::new(&mut d.rig_height)
                                .range(40..=1200)
                                .suffix(" px"),
                        )
                        .labelled_by(l.id);
                    });
                    ui.end_row();
                    let l = ui.label("Virtual hand tremor");
                    ui.horizontal(|ui| {
                        ui.add(
                            egui::DragValue::new(&mut d.rig_tip_amplitude_mm)
                                .range(0.0..=30.0)
                                .speed(0.1)
                                .prefix("flexion ")
                                .suffix(" mm"),
                        )
                        .labelled_by(l.id);
                        ui.add(
                            egui::DragValue::new(&mut d.rig_sway_mm)
                                .range(0.0..=20.0)
                                .speed(0.1)
                                .prefix("sway ")
                                .suffix(" mm"),
                        )
                        .labelled_by(l.id);
                        ui.add(
                            egui::DragValue::new(&mut d.rig_roll_deg)
                                .range(0.0..=20.0)
                                .speed(0.1)
                                .prefix("roll ")
                                .suffix("°"),
                        )
                        .labelled_by(l.id)
                        .on_hover_text(
                            "peak values: fingertip flexion along the optical axis, sideways \
                             sway of the whole hand, roll about the forearm",
                        );
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
                    ui.label("Unwrapping").on_hover_text(
                        "CPS sequences; a replayed session from another scanner takes the method its sequence needs",
                    );
                    ui.horizontal(|ui| {
                        ui.radio_value(
                            &mut d.unwrap,
                            UnwrapChoice::Robust,
                            "robust (neighbourhood)",
                        );
                        ui.radio_value(&mut d.unwrap, UnwrapChoice::PerPixel, "per pixel (paper)");
                    });
                    ui.end_row();
                    ui.label("Coarse average").on_hover_text(
                        "how the robust unwrap averages the coarse phase over a neighbourhood",
                    );
                    ui.horizontal(|ui| {
                        ui.radio_value(&mut d.coarse_average, CoarseAverageArg::Plain, "plain")
                            .on_hover_text(
                                "the default: the unit phasor summed as it is (moving skin \
                                 takes a wider average of its own either way)",
                            );
                        ui.radio_value(
                            &mut d.coarse_average,
                            CoarseAverageArg::Transported,
                            "transported",
                        )
                        .on_hover_text(
                            "carried along the fine phase: keeps a little more of a swaying \
                             hand, with more made-up points behind a soft lens (docs/accuracy.md)",
                        );
                    });
                    ui.end_row();
                    ui.label("Decode on");
                    ui.horizontal(|ui| {
                        ui.radio_value(&mut d.decoder, DecoderChoice::Auto, "auto")
                            .on_hover_text("a hardware GPU when there is one, else the CPU");
                        ui.radio_value(&mut d.decoder, DecoderChoice::Cpu, "CPU");
                        ui.radio_value(&mut d.decoder, DecoderChoice::Gpu, "GPU")
                            .on_hover_text("robust unwrapping only; a software GPU is slow");
                    });
                    ui.end_row();
                    ui.label("Colour calibration");
                    ui.horizontal(|ui| {
                        ui.label(
                            d.colour_file
                                .as_ref()
                                .map_or("the rig's own".to_string(), |p| p.display().to_string()),
                        );
                        if ui.small_button("choose…").clicked() {
                            if let Some(p) = rfd::FileDialog::new()
                                .add_filter("colour calibration", &["json"])
                                .pick_file()
                            {
                                d.colour_file = Some(p);
                            }
                        }
                        if d.colour_file.is_some() && ui.small_button("clear").clicked() {
                            d.colour_file = None;
                        }
                    });
                    ui.end_row();
                    ui.label("Geometric calibration");
                    ui.horizontal(|ui| {
                        ui.label(
                            d.calibration_file
                                .as_ref()
                                .map_or("the rig's own".to_string(), |p| p.display().to_string()),
                        );
                        if ui.small_button("choose…").clicked() {
                            if let Some(p) = rfd::FileDialog::new()
                                .add_filter("calibration", &["json"])
                                .pick_file()
                            {
                                d.calibration_file = Some(p);
                            }
                        }
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
