//! UI tests of the desktop app with egui_kittest on its wgpu renderer (lavapipe here): the app
//! runs on the virtual rig as a user would see it; widgets are found by their labels, clicked,
//! and the app's state checked.

mod kit;

use egui_kittest::kittest::Queryable;
use egui_kittest::Harness;
use kit::{harness, harness_persisting, scratch, settings, step_until};
use tremorscan_ui::gpu_decode::DecoderChoice;

use std::time::{Duration, Instant};
use tremorscan_ui::gui::app::TremorApp;
use tremorscan_ui::gui::settings::{DeviceChoice, Settings, UnwrapChoice};
use tremorscan_ui::gui::trial_ui::TrialState;
use tremorscan_ui::render::orbit::project;

/// Presses at `from`, moves right by `points` in two steps, releases.
fn drag_right(h: &mut Harness<'_, TremorApp>, from: egui::Pos2, points: f32) {
    h.drag_at(from);
    h.run_steps(1);
    h.hover_at(from + egui::vec2(points / 2.0, 0.0));
    h.run_steps(1);
    h.hover_at(from + egui::vec2(points, 0.0));
    h.run_steps(1);
    h.drop_at(from + egui::vec2(points, 0.0));
    h.run_steps(2);
}

/// Types `path` into the toolbar's session field and presses "Open replay".
fn open_replay_via_toolbar(h: &mut Harness<'_, TremorApp>, path: &str) {
    h.get_by_label("Session:").focus();
    h.run_steps(1);
    h.get_by_label("Session:").type_text(path);
    h.run_steps(1);
    h.get_by_label("Open replay").click();
    h.run_steps(2);
}

fn has_cloud(app: &TremorApp) -> bool {
    app.source.as_ref().is_some_and(|s| s.latest.is_some())
}

#[test]
fn clicking_the_hand_adds_a_tracked_control_point_that_can_be_renamed_and_removed() {
    let dir = scratch("points");
    let mut h = harness(settings(&dir));
    step_until(
        &mut h,
        Duration::from_secs(120),
        "the first cloud",
        has_cloud,
    );
    h.get_by_label("camera image").click();
    h.run_steps(2);
    let tracker = h.state().tracker_copy();
    assert_eq!(tracker.points.len(), 1, "one point added");
    let (u, v) = tracker.points[0].pixel;
    // The click lands at the middle of the image: the virtual rig's 640×400 camera.
    assert!(
        (u - 320.0).abs() <= 2.0 && (v - 200.0).abs() <= 2.0,
        "pixel {u},{v}"
    );
    step_until(
        &mut h,
        Duration::from_secs(120),
        "measured samples",
        |app| {
            app.tracker_copy().points[0]
                .samples
                .iter()
                .filter(|s| s.position_mm.is_some())
                .count()
                >= 3
        },
    );
    let z = h.state().tracker_copy().points[0]
        .latest_position_mm()
        .map(|p| p[2]);
    // The rig's hand lies 400–650 mm from the camera.
    assert!(
        z.is_some_and(|z| (350.0..700.0).contains(&z)),
        "depth {z:?}"
    );
    // Rename through the list: the name field is labelled by the point's number.
    h.get_by_label("#1").focus();
    h.run_steps(1);
    h.get_by_label("#1").type_text(" index tip");
    h.run_steps(2);
    assert_eq!(h.state().tracker_copy().points[0].name, "P1 index tip");
    h.get_by_label("Remove").click();
    h.run_steps(2);
    assert!(h.state().tracker_copy().points.is_empty());
    // A click on the cloud in the 3D view picks the surface point drawn there.
    h.get_by_label("3D view").click();
    h.run_steps(2);
    let tracker = h.state().tracker_copy();
    assert_eq!(tracker.points.len(), 1, "a point picked in 3D");
    step_until(
        &mut h,
        Duration::from_secs(120),
        "the picked point measured",
        |app| app.tracker_copy().points[0].latest_position_mm().is_some(),
    );
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn a_trial_is_recorded_stopped_by_hand_and_replayed() {
    let dir = scratch("record");
    let mut h = harness(settings(&dir));
    step_until(
        &mut h,
        Duration::from_secs(120),
        "the first cloud",
        has_cloud,
    );
    h.get_by_label("manual").click();
    h.run_steps(1);
    h.get_by_label_contains("Record trial").click();
    h.run_steps(2);
    step_until(&mut h, Duration::from_secs(60), "frames recorded", |app| {
        app.source
            .as_ref()
            .is_some_and(|s| s.pipeline.metrics().recorded >= 12)
    });
    h.get_by_label_contains("Stop recording").click();
    h.run_steps(1);
    // Stopping does not wait for the disk: the recorder reports when every frame is written.
    step_until(
        &mut h,
        Duration::from_secs(30),
        "the recording's outcome",
        |app| app.trial.last_outcome.is_some(),
    );
    let outcome = h.state().trial.last_outcome.clone().expect("an outcome");
    assert!(outcome.starts_with("saved "), "{outcome}");
    let session_dir = std::fs::read_dir(dir.join("sessions"))
        .expect("sessions folder")
        .next()
        .expect("one session")
        .expect("entry")
        .path();
    let session = tremorscan::session::Session::open(&session_dir).expect("the recording opens");
    assert!(session.frame_count() >= 12);
    assert!(
        outcome.contains(&format!("saved {} frames", session.frame_count())),
        "{outcome}"
    );

    // Replay it: paused at the start, three steps fill the first window.
    open_replay_via_toolbar(&mut h, &session_dir.display().to_string());
    assert!(h
        .state()
        .source
        .as_ref()
        .is_some_and(|s| s.playback.is_some()));
    for _ in 0..3 {
        h.get_by_label("Step").click();
        h.run_steps(1);
    }
    step_until(
        &mut h,
        Duration::from_secs(60),
        "the replayed cloud",
        has_cloud,
    );
    let shown = h
        .state()
        .source
        .as_ref()
        .and_then(|s| s.playback.as_ref())
        .and_then(|p| p.state().shown_frame);
    assert_eq!(shown, Some(2));
    h.get_by_label_contains("Play").click();
    step_until(
        &mut h,
        Duration::from_secs(60),
        "the replay to reach its end",
        |app| {
            app.source
                .as_ref()
                .and_then(|s| s.playback.as_ref())
                .is_some_and(|p| p.state().shown_frame == Some(session.frame_count() - 1))
        },
    );
    // Control points set in the replay are saved with the session.
    h.get_by_label("camera image").click();
    h.run_steps(2);
    h.get_by_label("Save control points to session").click();
    h.run_steps(2);
    let reopened = tremorscan::session::Session::open(&session_dir).expect("reopen");
    let saved = reopened.manifest.trial.expect("trial").control_points;
    assert_eq!(saved.len(), 1);
    assert_eq!(saved[0].name, "P1");
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn the_colour_wizard_captures_ten_colours_fits_and_saves() {
    let dir = scratch("colour");
    let mut h = harness(settings(&dir));
    h.get_by_label("Colour calibration…").click();
    h.run_steps(2);
    h.get_by_label("Next: capture colours").click();
    h.run_steps(2);
    // Live feedback before the captures: too much exposure clips the full-level colours.
    let live = |h: &Harness<'_, TremorApp>| {
        h.state()
            .colour_wizard
            .as_ref()
            .and_then(|w| w.live)
            .expect("live feedback")
    };
    // The feedback refreshes at most four times a second.
    std::thread::sleep(Duration::from_millis(300));
    h.state_mut()
        .colour_wizard
        .as_mut()
        .expect("wizard")
        .exposure = 2.0;
    h.run_steps(2);
    assert!(live(&h).full_level_saturated > 0.5, "{:?}", live(&h));
    std::thread::sleep(Duration::from_millis(300));
    h.state_mut()
        .colour_wizard
        .as_mut()
        .expect("wizard")
        .exposure = 0.8;
    h.run_steps(2);
    assert_eq!(live(&h).exposure, 0.8);
    assert!(live(&h).full_level_saturated < 0.01, "{:?}", live(&h));
    for _ in 0..10 {
        h.get_by_label("Capture colour").click();
        h.run_steps(2);
    }
    let wizard = h.state().colour_wizard.as_ref().expect("wizard open");
    let fit = wizard
        .result
        .as_ref()
        .expect("a fit")
        .as_ref()
        .expect("the fit succeeds");
    // The rig's own cross-talk is what the captures encode; noise leaves a fraction of a level.
    assert!(
        fit.residual_rms_gray < 3.0,
        "residual {}",
        fit.residual_rms_gray
    );
    h.get_by_label("Save colour calibration").click();
    h.run_steps(2);
    let saved = h
        .state()
        .settings
        .colour_file
        .clone()
        .expect("the app uses the saved file");
    assert!(saved.is_file());
    assert!(h.state().colour_wizard.is_none());
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn the_geometric_wizard_calibrates_from_poses_and_recomputes_without_a_dropped_view() {
    let dir = scratch("geometric");
    let mut h = harness(settings(&dir));
    h.get_by_label("Geometric calibration…").click();
    h.run_steps(2);
    h.get_by_label("Next: capture poses").click();
    h.run_steps(2);
    for _ in 0..6 {
        h.get_by_label("Capture pose").click();
        h.run_steps(2);
    }
    let w = h.state().geometric_wizard.as_ref().expect("wizard open");
    assert_eq!(w.views.len(), 6, "every pose found: {:?}", w.last_error);
    h.get_by_label("Calibrate").click();
    h.run_steps(2);
    let first = {
        let w = h.state().geometric_wizard.as_ref().expect("wizard open");
        let c = w
            .result
            .as_ref()
            .expect("result")
            .as_ref()
            .expect("calibrated");
        assert_eq!(c.views.len(), 6);
        c.camera_rms_px
    };
    h.state_mut()
        .geometric_wizard
        .as_mut()
        .expect("wizard")
        .dropped[0] = true;
    h.get_by_label("Recompute").click();
    h.run_steps(2);
    {
        let w = h.state().geometric_wizard.as_ref().expect("wizard open");
        let c = w
            .result
            .as_ref()
            .expect("result")
            .as_ref()
            .expect("calibrated");
        assert_eq!(c.views.len(), 5, "view 1 dropped");
        assert!(c.views.iter().all(|v| v.view != 0));
        assert!(
            c.camera_rms_px < 0.5 && first < 0.5,
            "RMS {first} then {}",
            c.camera_rms_px
        );
    }
    h.get_by_label("Save calibration").click();
    h.run_steps(2);
    let saved = h
        .state()
        .settings
        .calibration_file
        .clone()
        .expect("the app uses the saved file");
    assert!(tremorscan::calibrate::CalibrationFile::load(&saved).is_ok());
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn a_missing_session_is_a_message_not_a_crash_and_the_rig_comes_back() {
    let dir = scratch("missing");
    let mut h = harness(settings(&dir));
    open_replay_via_toolbar(&mut h, &dir.join("no-such-session").display().to_string());
    assert!(h.state().source.is_none());
    let (_, _, text) = h.state().messages.latest().expect("a message").clone();
    assert!(text.contains("no-such-session"), "{text}");
    h.get_by_label("Virtual rig").click();
    h.run_steps(2);
    step_until(&mut h, Duration::from_secs(120), "the rig again", has_cloud);
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn settings_apply_a_new_pattern_and_a_point_can_be_dragged() {
    let dir = scratch("settings");
    let mut h = harness(settings(&dir));
    h.get_by_label("Settings…").click();
    h.run_steps(2);
    h.get_by_label("rows").click();
    h.run_steps(1);
    h.get_by_label("per pixel (paper)").click();
    h.run_steps(1);
    h.get_by_label("CPU").click();
    h.run_steps(1);
    h.get_by_label("transported").click();
    h.run_steps(1);
    h.get_by_label("Apply").click();
    h.run_steps(2);
    assert!(!h.state().settings.code_columns);
    assert_eq!(h.state().settings.decoder, DecoderChoice::Cpu);
    // The coarse average chosen reaches the decode: the unit phasor carried along the fine
    // phase, at its wider decay.
    let params = h.state().settings.decode_params();
    assert!(params.smoothing.transport);
    assert_eq!(
        params.smoothing,
        tremorscan::decode::SmoothingParams::transported()
    );
    let decoder = h
        .state()
        .source
        .as_ref()
        .map(|s| s.pipeline.decoder_name().to_string());
    assert!(
        decoder.as_deref().is_some_and(|d| d.starts_with("CPU")),
        "{decoder:?}"
    );
    step_until(
        &mut h,
        Duration::from_secs(120),
        "a cloud coded along rows",
        has_cloud,
    );
    let valid = h
        .state()
        .source
        .as_ref()
        .and_then(|s| s.latest.as_ref())
        .map_or(0, |c| c.cloud.valid_count());
    assert!(
        valid > 10_000,
        "{valid} valid points decoded from row coding"
    );

    // Add a point at the image centre, then drag its marker 40 screen points to the right.
    h.get_by_label("camera image").click();
    h.run_steps(2);
    let rect = h.get_by_label("camera image").rect();
    let start = rect.center();
    drag_right(&mut h, start, 40.0);
    let points = h.state().tracker_copy().points;
    assert_eq!(
        points.len(),
        1,
        "the drag moved the point, it did not add one"
    );
    let scale = 640.0 / rect.width() as f64;
    let moved = points[0].pixel.0 - 320.0;
    assert!(
        (moved - 40.0 * scale).abs() <= 2.0,
        "moved {moved} px, expected {}",
        40.0 * scale
    );

    // In the 3D view: drag the point's marker 30 points right; it lands on the surface there.
    let before = points[0].pixel;
    step_until(
        &mut h,
        Duration::from_secs(60),
        "the moved point measured",
        |app| app.tracker_copy().points[0].latest_position_mm().is_some(),
    );
    let view = h.get_by_label("3D view").rect();
    let marker = {
        let app = h.state();
        let camera = app.cloud_view.camera.expect("a 3D camera");
        let m = camera.clip_from_world(view.width() / view.height());
        let q = app.tracker_copy().points[0]
            .latest_position_mm()
            .expect("measured");
        let (s, _) = project(
            &m,
            [q[0] as f32, q[1] as f32, q[2] as f32],
            [view.width(), view.height()],
        )
        .expect("the point is in view");
        view.min + egui::vec2(s[0], s[1])
    };
    drag_right(&mut h, marker, 30.0);
    let points = h.state().tracker_copy().points;
    assert_eq!(
        points.len(),
        1,
        "the 3D drag moved the point, it did not add one"
    );
    // The top view looks along the camera's axis: screen right is +u.
    assert!(
        points[0].pixel.0 > before.0 + 5.0,
        "{:?} -> {:?}",
        before,
        points[0].pixel
    );
    assert!(
        (points[0].pixel.1 - before.1).abs() < 5.0,
        "{:?} -> {:?}",
        before,
        points[0].pixel
    );
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn a_timed_trial_counts_down_records_its_duration_and_stops_by_itself() {
    let dir = scratch("timed");
    let mut h = harness(Settings {
        countdown_seconds: 1.0,
        ..settings(&dir)
    });
    h.get_by_label("5 s").click();
    h.run_steps(1);
    h.get_by_label("Record trial").click();
    h.run_steps(1);
    assert!(matches!(
        h.state().trial.state,
        TrialState::Countdown { .. }
    ));
    step_until(
        &mut h,
        Duration::from_secs(10),
        "the recording to start",
        |app| matches!(app.trial.state, TrialState::Recording { .. }),
    );
    let started = Instant::now();
    step_until(
        &mut h,
        Duration::from_secs(30),
        "the recording to stop",
        |app| app.trial.state == TrialState::Idle,
    );
    let took = started.elapsed().as_secs_f64();
    assert!((4.9..7.0).contains(&took), "recorded for {took:.1} s");
    let outcome = h.state().trial.last_outcome.clone().expect("an outcome");
    assert!(outcome.starts_with("saved "), "{outcome}");
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn a_folder_that_cannot_be_created_is_reported_and_nothing_records() {
    let dir = scratch("unwritable");
    // A regular file where the sessions folder should be.
    let blocker = dir.join("not-a-folder");
    std::fs::write(&blocker, b"x").expect("file");
    let mut h = harness(Settings {
        sessions_dir: blocker.join("sessions"),
        ..settings(&dir)
    });
    h.get_by_label("manual").click();
    h.run_steps(1);
    h.get_by_label("Record trial").click();
    h.run_steps(2);
    assert_eq!(h.state().trial.state, TrialState::Idle);
    let (_, _, text) = h.state().messages.latest().expect("a message").clone();
    assert!(text.contains("cannot create"), "{text}");
    assert!(!h
        .state()
        .source
        .as_ref()
        .is_some_and(|s| s.pipeline.is_recording()));
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn applied_settings_persist_to_the_settings_file() {
    let dir = scratch("persist");
    let path = dir.join("config").join("settings.json");
    let s = settings(&dir);
    let mut h = harness_persisting(s, Some(path));
    h.get_by_label("Settings…").click();
    h.run_steps(2);
    h.get_by_label("per pixel (paper)").click();
    h.run_steps(1);
    h.get_by_label("Apply").click();
    h.run_steps(2);
    let (saved, problem) =
        tremorscan_ui::gui::settings::load(&dir.join("config").join("settings.json"));
    assert_eq!(problem, None);
    assert_eq!(saved.unwrap, UnwrapChoice::PerPixel);
    assert_eq!(saved, h.state().settings);
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn the_camera_binning_is_a_setting() {
    let dir = scratch("binning");
    let mut h = harness(settings(&dir));
    h.get_by_label("Settings…").click();
    h.run_steps(2);
    h.get_by_label("GenICam camera with a second screen as projector")
        .click();
    h.run_steps(2);
    // A drag value labelled "Binning", starting at none (1×1): a click edits it as text.
    h.get_by_label("Binning").click();
    h.run_steps(2);
    h.get_by_label("Binning").type_text("2");
    h.run_steps(1);
    h.key_press(egui::Key::Enter);
    h.run_steps(2);
    h.get_by_label("Apply").click();
    h.run_steps(3);
    let device = h.state().settings.device.clone();
    assert!(
        matches!(device, DeviceChoice::Camera { binning: 2, .. }),
        "{device:?}"
    );
    let _ = std::fs::remove_dir_all(dir);
}
