//! Replay controls for a saved session: play, pause, step one frame, seek on a timeline, speed;
//! and saving the control points set during the replay into the session's trial metadata.

use super::source::Source;
use tremorscan::session::manifest::ControlPointJson;

/// Speed presets.
const SPEEDS: [f64; 5] = [0.1, 0.25, 0.5, 1.0, 2.0];

/// Draws the controls; returns a message for the status bar when something happened.
pub fn replay_ui(ui: &mut egui::Ui, source: &mut Source) -> Option<String> {
    let control = source.playback.clone()?;
    ui.heading("Replay");
    let state = control.state();
    let count = control.frame_count();
    let mut message = None;
    ui.horizontal(|ui| {
        if state.playing {
            if ui.button("Pause").clicked() {
                control.pause();
            }
        } else if ui.button("Play").clicked() {
            control.play();
        }
        if ui
            .button("Step")
            .on_hover_text("Pause and show the next frame")
            .clicked()
        {
            control.step();
        }
        ui.label("Speed");
        egui::ComboBox::from_id_salt("replay_speed")
            .selected_text(format!("{}×", state.speed))
            .show_ui(ui, |ui| {
                for s in SPEEDS {
                    if ui
                        .selectable_label(state.speed == s, format!("{s}×"))
                        .clicked()
                    {
                        control.set_speed(s);
                    }
                }
            });
    });
    let shown = state.shown_frame.unwrap_or(0);
    let mut position = shown;
    let slider = ui.add(
        egui::Slider::new(&mut position, 0..=count.saturating_sub(1))
            .text("frame")
            .clamping(egui::SliderClamping::Always),
    );
    if slider.changed() && position != shown {
        if state.playing {
            control.seek(position);
        } else {
            // Paused: show the window ending at the chosen frame (its two predecessors, then it).
            control.seek(position.saturating_sub(2));
            for _ in 0..3 {
                control.step();
            }
        }
    }
    let time_s = source
        .session
        .as_ref()
        .and_then(|s| s.manifest.frames.get(shown).map(|f| f.time_s))
        .unwrap_or(0.0);
    ui.label(format!("frame {shown} of {count} · {time_s:.3} s"));
    if ui.button("Save control points to session").clicked() {
        message = Some(save_points(source));
    }
    message
}

/// Writes the current control points into the replayed session's trial.
fn save_points(source: &mut Source) -> String {
    let points: Vec<ControlPointJson> = source
        .tracker()
        .points
        .iter()
        .map(|p| ControlPointJson {
            name: p.name.clone(),
            u: p.pixel.0,
            v: p.pixel.1,
        })
        .collect();
    let Some(session) = source.session.as_mut() else {
        return "no session is open".to_string();
    };
    let mut trial = session.manifest.trial.clone().unwrap_or_default();
    let n = points.len();
    trial.control_points = points;
    match session.save_trial(trial) {
        Ok(()) => format!("saved {n} control points to {}", session.dir.display()),
        Err(e) => format!("could not save the control points: {e}"),
    }
}
