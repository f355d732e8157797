//! `tremorscan`: the desktop application's binary. Until the GUI lands it runs headless
//! subcommands over the same library: `demo` (the default) streams the virtual rig through the
//! sliding-window decoder, `sweep` tabulates unwrap robustness against camera noise, `snapshot`
//! writes one decoded window as PNG images.

mod demo;
mod snapshot;
mod sweep;

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
    /// Stream the virtual rig (a trembling hand) through the decoder and print live figures.
    Demo(demo::DemoArgs),
    /// Sweep camera noise and tabulate unwrap failures and RMS error for each unwrap method.
    Sweep(sweep::SweepArgs),
    /// Decode one window of the virtual rig and write it as PNG images.
    Snapshot(snapshot::SnapshotArgs),
}

fn main() -> Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Some(Command::Demo(args)) => demo::run(&args),
        Some(Command::Sweep(args)) => sweep::run(&args),
        Some(Command::Snapshot(args)) => snapshot::run(&args),
        None => demo::run(&demo::DemoArgs::default()),
    }
}
