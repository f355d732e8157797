//! The tremorscan application crate: the desktop GUI ([`gui`], with its wgpu renderers in
//! [`render`]) and the headless subcommands of the `tremorscan` binary, all over the core
//! library `tremorscan`. A library so that the UI tests (`ui/tests`) can drive the app.

pub mod batch_cmd;
pub mod batch_session;
pub mod bench_cmd;
pub mod calibrate_cmd;
pub mod demo;
pub mod devices_cmd;
pub mod export_cmd;
pub mod gpu_decode;
pub mod gui;
pub mod pipeline_cmd;
pub mod point_analysis;
pub mod progress;
pub mod render;
pub mod report_png;
pub mod session_cmd;
pub mod session_tracking;
pub mod simulate_calibration;
pub mod snapshot;
pub mod sweep;
pub mod sweep_motion;
pub mod tremor_cmd;
pub mod unwrap_args;
