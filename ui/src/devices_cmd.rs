//! `tremorscan devices` lists the real devices this build can drive, and `tremorscan
//! lightcrafter` programs the CPS-RGB sequence into a LightCrafter 4500 and prints its timing.
//! Both say plainly when the build lacks a device's feature or the device is not there.

use anyhow::{anyhow, Result};
use std::io::Write;
use tremorscan::device::lightcrafter::timing::{deepest_bit_depth, CpsTiming};

/// Options of `tremorscan lightcrafter`.
#[derive(clap::Args, Debug, Clone)]
pub struct LightcrafterArgs {
    /// Images per second (each image is 3 colour patterns).
    #[arg(long, default_value_t = 121.0)]
    pub fps: f64,
    /// Bit depth per colour pattern (default: the deepest that reaches --fps).
    #[arg(long)]
    pub bits: Option<u8>,
    /// Only print the timing plan; do not touch the device.
    #[arg(long)]
    pub dry_run: bool,
}

/// Lists cameras (GenICam) and projectors (LightCrafter 4500).
pub fn run_devices() -> Result<()> {
    // Written, not printed: a closed pipe (`| head`) is an error message, not a panic.
    let mut out = std::io::stdout().lock();
    writeln!(out, "cameras (GenICam: USB3 Vision, GigE Vision):")?;
    for line in camera_lines() {
        writeln!(out, "  {line}")?;
    }
    writeln!(out, "projectors:")?;
    writeln!(out, "  {}", lightcrafter_line())?;
    writeln!(
        out,
        "  second screen: any monitor; choose it in Settings (device \"GenICam camera with a second screen\")"
    )?;
    Ok(())
}

#[cfg(feature = "genicam")]
fn camera_lines() -> Vec<String> {
    let cameras = tremorscan::device::genicam::list_cameras();
    if cameras.is_empty() {
        return vec![
            "none found (check the cable, power and, for GigE Vision, the network)".into(),
        ];
    }
    cameras
        .iter()
        .map(|c| {
            format!(
                "{}  ({} {}, {} at {})",
                c.id, c.vendor, c.model, c.protocol, c.address
            )
        })
        .collect()
}

#[cfg(not(feature = "genicam"))]
fn camera_lines() -> Vec<String> {
    vec!["this build has no GenICam support (build with --features genicam)".into()]
}

#[cfg(feature = "lightcrafter")]
fn lightcrafter_line() -> String {
    match tremorscan::device::lightcrafter::usb::open() {
        Ok(_) => "DLP LightCrafter 4500: connected".into(),
        Err(e) => format!("DLP LightCrafter 4500: {e}"),
    }
}

#[cfg(not(feature = "lightcrafter"))]
fn lightcrafter_line() -> String {
    "DLP LightCrafter 4500: this build has no support (build with --features lightcrafter)".into()
}

/// Plans (and unless `--dry-run`, programs) the CPS-RGB sequence.
pub fn run_lightcrafter(args: &LightcrafterArgs) -> Result<()> {
    let bits = match args.bits {
        Some(b) => b,
        None => deepest_bit_depth(args.fps)
            .ok_or_else(|| anyhow!("{} FPS is too fast for any bit depth", args.fps))?,
    };
    let timing = CpsTiming::new(args.fps, bits)?;
    println!(
        "CPS-RGB at {} FPS: {}-bit patterns of {} µs, {} µs of light per image, {} µs per image",
        args.fps,
        timing.bit_depth,
        timing.pattern_exposure_micros,
        timing.image_exposure_micros(),
        timing.image_period_micros
    );
    if args.dry_run {
        return Ok(());
    }
    program(&timing)
}

#[cfg(feature = "lightcrafter")]
fn program(timing: &CpsTiming) -> Result<()> {
    let mut lc = tremorscan::device::lightcrafter::usb::open()?;
    lc.program_cps(timing)?;
    for warning in &lc.warnings {
        println!("warning: {warning}");
    }
    println!("programmed and started; feed the video input one CPS image per frame");
    Ok(())
}

#[cfg(not(feature = "lightcrafter"))]
fn program(_timing: &CpsTiming) -> Result<()> {
    Err(anyhow!(
        "this build has no LightCrafter support: build with --features lightcrafter (the .deb has it), or use --dry-run"
    ))
}
