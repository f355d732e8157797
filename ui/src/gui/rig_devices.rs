//! Opening a real rig's devices from the settings: the GenICam camera (feature `genicam`), and
//! for a LightCrafter projector (feature `lightcrafter`) programming its CPS-RGB sequence, then
//! handing both to [`LiveRig`]. A build without a feature says so instead of opening.

use super::live_rig::{LiveRig, RigParts, ScreenPlan};
use super::settings::{DeviceChoice, ProjectorKind, Settings};
use anyhow::{anyhow, Result};
use tremorscan::device::Camera;

/// The LightCrafter's video input runs at up to 120 Hz: one CPS image per video frame.
const LIGHTCRAFTER_INPUT_HZ: f64 = 120.0;

/// Programs the LightCrafter for CPS-RGB at its input rate; returns the bit depth used.
#[cfg(feature = "lightcrafter")]
fn program_lightcrafter() -> Result<u8> {
    use tremorscan::device::lightcrafter::timing::{deepest_bit_depth, CpsTiming};
    let bits = deepest_bit_depth(LIGHTCRAFTER_INPUT_HZ)
        .ok_or_else(|| anyhow!("no bit depth fits {LIGHTCRAFTER_INPUT_HZ} Hz"))?;
    let timing = CpsTiming::new(LIGHTCRAFTER_INPUT_HZ, bits)?;
    let mut lightcrafter = tremorscan::device::lightcrafter::usb::open()?;
    lightcrafter.program_cps(&timing)?;
    Ok(bits)
}

/// Without the `lightcrafter` feature there is no LightCrafter to program.
#[cfg(not(feature = "lightcrafter"))]
fn program_lightcrafter() -> Result<u8> {
    let _ = LIGHTCRAFTER_INPUT_HZ;
    Err(anyhow!(
        "this build has no LightCrafter support: build with `--features lightcrafter` (the .deb has it)"
    ))
}

/// Opens the camera of `choice`.
#[cfg(feature = "genicam")]
pub fn open_camera(choice: &DeviceChoice) -> Result<Box<dyn Camera>> {
    use tremorscan::device::genicam::{
        list_cameras, GenicamCamera, GenicamSettings, TriggerChoice,
    };
    let DeviceChoice::Camera {
        camera_id,
        exposure_micros,
        projector,
        binning,
        ..
    } = choice
    else {
        return Err(anyhow!("not a camera device"));
    };
    let id = if camera_id.trim().is_empty() {
        list_cameras()
            .first()
            .map(|c| c.id.clone())
            .ok_or_else(|| anyhow!("no GenICam camera found: check its cable and power"))?
    } else {
        camera_id.trim().to_string()
    };
    let settings = GenicamSettings {
        exposure_micros: Some(*exposure_micros),
        binning: Some(*binning),
        // The LightCrafter's trigger out 1, wired to the camera's first input line.
        trigger: match projector {
            ProjectorKind::SecondScreen => TriggerChoice::FreeRun,
            ProjectorKind::LightCrafter => TriggerChoice::Hardware {
                line: "Line1".to_string(),
            },
        },
        ..GenicamSettings::default()
    };
    Ok(Box::new(GenicamCamera::open(&id, &settings)?))
}

/// Without the `genicam` feature there is no camera to open.
#[cfg(not(feature = "genicam"))]
pub fn open_camera(_choice: &DeviceChoice) -> Result<Box<dyn Camera>> {
    Err(anyhow!(
        "this build has no GenICam camera support: build with `--features genicam` (the .deb has it)"
    ))
}

/// Starts the rig of `settings` (a camera device).
pub fn begin_from_settings(settings: &Settings) -> Result<LiveRig> {
    let DeviceChoice::Camera {
        exposure_micros,
        monitor,
        hold_refreshes,
        projector,
        ..
    } = &settings.device
    else {
        return Err(anyhow!("the device is not a camera"));
    };
    let parts = RigParts::from_settings(settings, exposure_micros * 1e-6)?;
    let plan = match projector {
        ProjectorKind::SecondScreen => ScreenPlan::second_screen(*monitor, *hold_refreshes),
        ProjectorKind::LightCrafter => ScreenPlan::lightcrafter(*monitor, program_lightcrafter()?),
    };
    let camera = open_camera(&settings.device)?;
    if camera.size() != (parts.stereo.camera.width, parts.stereo.camera.height) {
        return Err(anyhow!(
            "the camera delivers {}×{} but the calibration is for {}×{}",
            camera.size().0,
            camera.size().1,
            parts.stereo.camera.width,
            parts.stereo.camera.height
        ));
    }
    LiveRig::begin(camera, parts, plan)
}
