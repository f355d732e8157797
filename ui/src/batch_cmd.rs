//! `tremorscan batch`: a whole study in one command. Every session under the study folder is
//! tracked at its saved control points (`session.json`'s trial, plus `--point`) and analysed as
//! `analyze` does; each gets its outputs in `RESULTS/sessions/<its path>/` (`analysis.json`,
//! `report.png`, `trial.c3d`, `rows.csv`), and the study gets one table, `RESULTS/study.csv`.
//!
//! - **Workers.** Sessions run on `--jobs` named threads (`batch-N`) that take the next session
//!   from a shared counter and report over a bounded channel. Each decode spreads its rows over
//!   the cores through rayon, but a session also has serial parts (reading and unpacking frames,
//!   tracking, the analysis, the report), so one worker per core (at most 8, for memory: a
//!   decoder holds a few hundred MB at full resolution) keeps the cores busier than one session
//!   at a time: 8 sessions on 2 cores took 7 % less time with 2 workers than with 1
//!   (`docs/benchmarks.md`).
//! - **Resumable.** A session whose `rows.csv` (written last) is newer than every file of the
//!   session is skipped and its rows are read back, unless `--force`. With `--bids` its BIDS
//!   files must exist too.
//! - **Failures** (unreadable, corrupt, no control points) become the session's row in the
//!   table with the error; nothing else stops. The command then exits non-zero and says how
//!   many failed.
//! - **Shards.** `--shard I/N` does the I-th of N deterministic parts (`study::shard`) and writes
//!   `study-shard-I-of-N.csv`; `batch --merge RESULTS` joins them into `study.csv` (and with
//!   `--bids DIR` writes that dataset's top-level files). `docs/cluster.md` runs it under Slurm.
//! - **Ctrl-C** stops the sessions in progress between frames; they write nothing more and are
//!   not marked done, no study table is written, and every file already written is complete
//!   (atomic writes). The next run finishes the study.

use crate::batch_session::{process_session, SessionJob, SessionOutputs};
use crate::unwrap_args::UnwrapArgs;
use anyhow::{bail, Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc::sync_channel;
use tremorscan::study::{self, Shard, StudyRow};

#[derive(clap::Args, Debug, Clone)]
pub struct BatchArgs {
    /// Study folder: every session under it, recursively, is processed.
    #[arg(required_unless_present = "merge")]
    pub study: Option<PathBuf>,
    /// Results folder (created if missing).
    #[arg(long, required_unless_present = "merge")]
    pub out: Option<PathBuf>,
    /// Join the shard tables in this results folder into its study.csv, and stop.
    #[arg(long, conflicts_with_all = ["study", "out", "shard", "force", "jobs", "points"])]
    pub merge: Option<PathBuf>,
    /// Do the I-th of N deterministic parts of the study (for a cluster's array job).
    #[arg(long)]
    pub shard: Option<Shard>,
    /// Process every session again, even those whose outputs are up to date.
    #[arg(long)]
    pub force: bool,
    /// Sessions processed at once (default: one per core, at most 8).
    #[arg(long)]
    pub jobs: Option<usize>,
    /// Also write the trajectories as a Motion-BIDS dataset under this folder.
    #[arg(long)]
    pub bids: Option<PathBuf>,
    /// A control point `U,V` added to every session's saved ones (repeat for more).
    #[arg(long = "point", value_parser = crate::tremor_cmd::parse_point)]
    pub points: Vec<(f64, f64)>,
    #[command(flatten)]
    pub unwrap: UnwrapArgs,
    #[command(flatten)]
    pub mode: crate::session_tracking::PointModeArgs,
}

/// The software version written into every row and export.
pub fn software_version() -> String {
    format!("tremorscan {}", env!("CARGO_PKG_VERSION"))
}

/// The default worker count: one per core, at most 8 (module header).
pub fn default_jobs() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get().min(8))
}

pub fn run_batch(args: &BatchArgs) -> Result<()> {
    if let Some(results) = &args.merge {
        return run_merge(results, args.bids.as_deref());
    }
    let (Some(study_dir), Some(out)) = (&args.study, &args.out) else {
        bail!("give the study folder and --out RESULTS, or --merge RESULTS");
    };
    let all = study::find_sessions(study_dir)
        .with_context(|| format!("looking for sessions under {}", study_dir.display()))?;
    if all.is_empty() {
        bail!(
            "no sessions (folders with session.json) under {}",
            study_dir.display()
        );
    }
    let runs = crate::batch_session::bids_runs(study_dir, &all);
    let mine = match args.shard {
        Some(s) => study::shard(&all, s),
        None => all.clone(),
    };
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let jobs = args
        .jobs
        .unwrap_or_else(default_jobs)
        .clamp(1, mine.len().max(1));
    println!(
        "{} sessions in {}{}; {jobs} at once",
        mine.len(),
        study_dir.display(),
        args.shard.map_or(String::new(), |s| format!(
            " (shard {s} of {} sessions)",
            all.len()
        ))
    );

    let bar = ProgressBar::new(mine.len() as u64);
    bar.set_style(
        ProgressStyle::with_template(
            "{bar:30} {pos}/{len} sessions, {elapsed_precise} elapsed, ETA {eta_precise} {msg}",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let version = software_version();
    let next = AtomicUsize::new(0);
    // Ctrl-C: the workers stop between frames, write nothing more and take no new session;
    // every file already written is complete (atomic writes). A second Ctrl-C ends at once.
    let stop: &'static AtomicBool = Box::leak(Box::new(AtomicBool::new(false)));
    let interrupt = ctrlc::set_handler(move || {
        if stop.swap(true, Ordering::Relaxed) {
            std::process::exit(130);
        }
        eprintln!("\ninterrupted: stopping the sessions in progress (Ctrl-C again to quit now)");
    });
    if let Err(e) = interrupt {
        eprintln!("warning: Ctrl-C will end the batch without cleaning up: {e}");
    }
    let (tx, rx) = sync_channel::<(usize, SessionOutputs)>(jobs);
    let mut outcomes: Vec<Option<SessionOutputs>> = vec![None; mine.len()];
    std::thread::scope(|scope| -> Result<()> {
        for w in 0..jobs {
            let tx = tx.clone();
            let (next, mine, runs, version) = (&next, &mine, &runs, &version);
            std::thread::Builder::new()
                .name(format!("batch-{w}"))
                .spawn_scoped(scope, move || loop {
                    if stop.load(Ordering::Relaxed) {
                        break;
                    }
                    let k = next.fetch_add(1, Ordering::Relaxed);
                    let Some(relative) = mine.get(k) else { break };
                    let job = SessionJob {
                        study: study_dir,
                        relative,
                        results: out,
                        extra_points: &args.points,
                        unwrap: &args.unwrap,
                        mode: args.mode.mode(),
                        bids: args.bids.as_deref(),
                        bids_run: runs.get(relative).copied(),
                        force: args.force,
                        software_version: version,
                        stop,
                    };
                    if tx.send((k, process_session(&job))).is_err() {
                        break;
                    }
                })
                .context("starting a batch worker")?;
        }
        drop(tx);
        for (k, outputs) in rx {
            if let (Some(error), false, false) = (
                &outputs.error,
                outputs.skipped,
                stop.load(Ordering::Relaxed),
            ) {
                bar.suspend(|| eprintln!("{}: {error}", mine[k].display()));
            }
            bar.inc(1);
            outcomes[k] = Some(outputs);
        }
        Ok(())
    })?;
    bar.finish_and_clear();
    if stop.load(Ordering::Relaxed) {
        let done = outcomes
            .iter()
            .flatten()
            .filter(|o| o.error.as_deref() != Some("interrupted"))
            .count();
        bail!(
            "interrupted after {done} of {} sessions; no study table was written (run the same command again to finish: finished sessions are skipped)",
            mine.len()
        );
    }

    let outcomes: Vec<SessionOutputs> = outcomes.into_iter().flatten().collect();
    let rows: Vec<StudyRow> = outcomes.iter().flat_map(|o| o.rows.clone()).collect();
    let table = match args.shard {
        Some(s) => out.join(study::table::shard_table_name(s.index, s.count)),
        None => out.join(study::TABLE_FILE),
    };
    study::write_table(&table, &rows)?;
    if let (Some(bids), None) = (&args.bids, args.shard) {
        write_bids_top_level(bids, &rows)?;
    }
    let skipped = outcomes.iter().filter(|o| o.skipped).count();
    let processed = outcomes.len() - skipped;
    let failed: Vec<&SessionOutputs> = outcomes.iter().filter(|o| o.error.is_some()).collect();
    let missing = rows
        .iter()
        .filter(|r| !r.point.is_empty() && !r.error.is_empty())
        .count();
    println!(
        "{} sessions: {processed} processed, {skipped} up to date (skipped), {} failed; {} rows, {missing} with figures missing; wrote {}",
        outcomes.len(),
        failed.len(),
        rows.len(),
        table.display()
    );
    if !failed.is_empty() {
        bail!(
            "{} of {} sessions failed (their errors are in {})",
            failed.len(),
            outcomes.len(),
            table.display()
        );
    }
    Ok(())
}

/// The BIDS dataset's top-level files, listing the subjects of `rows` that have figures.
fn write_bids_top_level(bids: &Path, rows: &[StudyRow]) -> Result<()> {
    let mut subjects: Vec<String> = rows
        .iter()
        .filter(|r| !r.point.is_empty())
        .map(|r| tremorscan::export::bids::bids_label(&r.subject))
        .filter(|s| !s.is_empty())
        .collect();
    subjects.sort();
    subjects.dedup();
    tremorscan::export::bids::write_dataset_files(bids, &subjects, &software_version())
        .with_context(|| format!("writing the BIDS dataset's files in {}", bids.display()))
}

fn run_merge(results: &Path, bids: Option<&Path>) -> Result<()> {
    let n = study::merge_tables(results)?;
    let table = results.join(study::TABLE_FILE);
    if let Some(bids) = bids {
        write_bids_top_level(bids, &study::read_table(&table)?)?;
    }
    println!("merged {n} rows into {}", table.display());
    Ok(())
}
