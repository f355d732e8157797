//! `tremorscan`: the desktop application's binary. Without a command (or with `gui`) it opens
//! the window ([`gui`]); its subcommands run the same work headless: `demo` streams the virtual
//! rig through the sliding-window decoder, `sweep` tabulates unwrap robustness against camera noise, `snapshot`
//! writes one decoded window as PNG images; `simulate-calibration`, `calibrate-color`,
//! `calibrate-geometric` and `import-calibration` calibrate a rig from recorded sessions;
//! `devices` lists real cameras and projectors, `lightcrafter` programs a LightCrafter 4500;
//! `bench` tells whether this PC keeps up with the camera; `batch` processes a whole study, and
//! `export-bids`, `export-c3d` and `export` write a session in the field's formats.

use tremorscan_ui::{
    batch_cmd, bench_cmd, calibrate_cmd, demo, devices_cmd, export_cmd, gui, pipeline_cmd,
    session_cmd, simulate_calibration, snapshot, sweep, tremor_cmd,
};

use anyhow::Result;
use clap::{Parser, Subcommand};

#[derive(Parser, Debug)]
#[command(
    name = "tremorscan",
    version,
    about = "Chebyshev Phase Shifting hand tremor scanner"
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Open the desktop application (the default when no command is given).
    Gui(gui::GuiArgs),
    /// Stream the virtual rig (a trembling hand) through the decoder and print live figures.
    Demo(demo::DemoArgs),
    /// Sweep camera noise and tabulate unwrap failures and RMS error for each unwrap method.
    Sweep(sweep::SweepArgs),
    /// Decode one window of the virtual rig and write it as PNG images.
    Snapshot(snapshot::SnapshotArgs),
    /// Write a measurement session (cps-session/1) of the trembling hand from the virtual rig.
    Simulate(session_cmd::SimulateArgs),
    /// Decode and triangulate the window ending at one frame of a session; export PLY/TIFF/PNG.
    Decode(session_cmd::DecodeArgs),
    /// Summarise a session and check every frame.
    Info(session_cmd::InfoArgs),
    /// Track control points (camera pixels) through a session; write their 3D track as CSV.
    Track(tremor_cmd::TrackArgs),
    /// Track control points and write their tremor figures (frequency, amplitude, spectrum) as JSON.
    Analyze(tremor_cmd::AnalyzeArgs),
    /// Record a trial from the virtual rig through the live pipeline (frames.cpsr container).
    Record(pipeline_cmd::RecordArgs),
    /// Play a session through the pipeline (capture, decode, triangulate) and print metrics.
    Replay(pipeline_cmd::ReplayArgs),
    /// Write colour and chessboard calibration sessions from the virtual rig.
    SimulateCalibration(simulate_calibration::SimulateCalibrationArgs),
    /// Fit the colour cross-talk (A, b) from a session of the ten Table 1 captures.
    CalibrateColor(calibrate_cmd::CalibrateColorArgs),
    /// Calibrate camera, projector and extrinsics from chessboard sessions (one per pose).
    CalibrateGeometric(calibrate_cmd::CalibrateGeometricArgs),
    /// Convert an OpenCV FileStorage calibration (YAML or XML) into a tremorscan calibration file.
    ImportCalibration(calibrate_cmd::ImportCalibrationArgs),
    /// List the cameras and projectors this build can drive.
    Devices,
    /// Program the CPS-RGB sequence into a DLP LightCrafter 4500 (or print its timing).
    Lightcrafter(devices_cmd::LightcrafterArgs),
    /// Measure per-stage decode times at the camera's size: does this PC keep up?
    Bench(bench_cmd::BenchArgs),
    /// Analyse every session of a study into one table (study.csv), per-session reports, C3D
    /// and optionally Motion-BIDS; `--shard I/N` and `--merge` for a cluster.
    Batch(batch_cmd::BatchArgs),
    /// Write a session's control-point trajectories into a Motion-BIDS dataset.
    ExportBids(export_cmd::ExportBidsArgs),
    /// Write a session's control points as C3D markers (mm, table frame).
    ExportC3d(export_cmd::ExportC3dArgs),
    /// Write a session's windows as a PLY point-cloud sequence and/or float depth TIFFs.
    Export(export_cmd::ExportArgs),
}

/// Runs the command; a failure prints one line, `error: ` and its causes, and exits with 1.
fn main() -> std::process::ExitCode {
    match run() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

fn run() -> Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Some(Command::Gui(args)) => gui::run(&args),
        None => gui::run(&gui::GuiArgs::default()),
        Some(Command::Demo(args)) => demo::run(&args),
        Some(Command::Sweep(args)) => sweep::run(&args),
        Some(Command::Snapshot(args)) => snapshot::run(&args),
        Some(Command::Simulate(args)) => session_cmd::run_simulate(&args),
        Some(Command::Decode(args)) => session_cmd::run_decode(&args),
        Some(Command::Info(args)) => session_cmd::run_info(&args),
        Some(Command::Track(args)) => tremor_cmd::run_track(&args),
        Some(Command::Analyze(args)) => tremor_cmd::run_analyze(&args),
        Some(Command::Record(args)) => pipeline_cmd::run_record(&args),
        Some(Command::Replay(args)) => pipeline_cmd::run_replay(&args),
        Some(Command::SimulateCalibration(args)) => simulate_calibration::run(&args),
        Some(Command::CalibrateColor(args)) => calibrate_cmd::run_color(&args),
        Some(Command::Devices) => devices_cmd::run_devices(),
        Some(Command::Lightcrafter(args)) => devices_cmd::run_lightcrafter(&args),
        Some(Command::Bench(args)) => bench_cmd::run_bench(&args),
        Some(Command::CalibrateGeometric(args)) => calibrate_cmd::run_geometric(&args),
        Some(Command::ImportCalibration(args)) => calibrate_cmd::run_import(&args),
        Some(Command::Batch(args)) => batch_cmd::run_batch(&args),
        Some(Command::ExportBids(args)) => export_cmd::run_export_bids(&args),
        Some(Command::ExportC3d(args)) => export_cmd::run_export_c3d(&args),
        Some(Command::Export(args)) => export_cmd::run_export(&args),
    }
}
