//! `maglab`: the host toolkit for the magnetostrictive actuator.
//!
//! One module per command (`cmd_<name>.rs`), each with a clap `Args` struct and a
//! `run(&Args) -> anyhow::Result<()>`; shared pieces live in [`params_io`] (loading a parameter
//! file into the core's f32 types) and [`plot`] (PNG + SVG figures with an embedded font).
//!
//! To add a command: write `src/cmd_<name>.rs` with `Args` and `run`, declare the module below,
//! add a variant to [`Command`] and a match arm in [`main`].
//!
//! Exit codes: 0 success, 1 any other error, 2 an invalid parameter file (the message names the
//! file, the field and the reason).

mod cmd_diagnose;
mod cmd_excite;
mod cmd_hil_plant;
mod cmd_identify;
mod cmd_loops;
mod cmd_params;
mod cmd_preisach;
mod cmd_rig;
mod cmd_robustness;
mod cmd_simulate;
mod cmd_track;
mod params_io;
mod plot;
mod plot_bars;
mod plot_diagnose;
mod plot_identify;
mod plot_preisach;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

/// Host toolkit for the magnetostrictive (Terfenol-D) actuator after Tan & Baras.
#[derive(Debug, Parser)]
#[command(name = "maglab", version, about, propagate_version = true)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Trace the Preisach operator's initial curve, major loop and nested minor loops; print a
    /// table and write loops.png/.svg and displacement.png/.svg.
    Loops(cmd_loops::Args),
    /// Run the dynamic model (4)-(5) or the static model (6) on sines, a current file or a Van der
    /// Pol-shaped current; write CSVs, loops.png (displacement vs current) and traces.png.
    Simulate(cmd_simulate::Args),
    /// Run the dynamic and the static inverse controller against the reference plant on the
    /// Van der Pol trajectory; print RMS/max errors and write the paper's Figures 7/8 and a CSV.
    Track(cmd_track::Args),
    /// Write the default parameter file or check one.
    Params(cmd_params::Args),
    /// Write a quasi-static identification current (first-order reversal curves reaching every
    /// Preisach cell).
    Excite(cmd_excite::Args),
    /// Identify the Preisach masses from a dataset folder and write the full parameter JSON.
    Identify(cmd_identify::Args),
    /// Fit a Preisach model to two columns of any CSV file.
    PreisachFit(cmd_preisach::FitArgs),
    /// Predict with a fitted Preisach model on a CSV file and report the NRMSE.
    PreisachPredict(cmd_preisach::PredictArgs),
    /// Virtual test rig: datasets from the reference plant with unmodelled effects switched on.
    Rig(cmd_rig::Args),
    /// Where a dataset disagrees with the nominal model and which unmodelled effect explains it.
    Diagnose(cmd_diagnose::Args),
    /// The bench plant as a plant program of the virtual bench: lock-step frames on
    /// stdin/stdout (docs/hil.md); run by `cargo xtask hil`.
    HilPlant(cmd_hil_plant::Args),
    /// The closed loop against plants the model does not describe: open- vs closed-loop
    /// tracking per case (out/robustness/robustness.csv and a plot).
    Robustness(cmd_robustness::Args),
}

/// Exit code for an invalid parameter file.
const EXIT_INVALID_PARAMS: u8 = 2;

/// Writing to a closed pipe (`maglab params check FILE | head`) ends the process quietly, as it
/// does for every Unix tool: Rust ignores SIGPIPE by default, and `println!` then panics on the
/// broken pipe. The default action is restored before anything is written.
fn end_quietly_on_a_closed_pipe() {
    #[cfg(unix)]
    // SAFETY: `signal` with `SIG_DFL` only resets the disposition of SIGPIPE; it is called once,
    // before any thread is started.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

fn main() -> ExitCode {
    end_quietly_on_a_closed_pipe();
    let cli = Cli::parse();
    let result = match &cli.command {
        Command::Loops(args) => cmd_loops::run(args),
        Command::Simulate(args) => cmd_simulate::run(args),
        Command::Track(args) => cmd_track::run(args),
        Command::Params(args) => cmd_params::run(args),
        Command::Excite(args) => cmd_excite::run(args),
        Command::Identify(args) => cmd_identify::run(args),
        Command::PreisachFit(args) => cmd_preisach::run_fit(args),
        Command::PreisachPredict(args) => cmd_preisach::run_predict(args),
        Command::Rig(args) => cmd_rig::run(args),
        Command::Diagnose(args) => cmd_diagnose::run(args),
        Command::HilPlant(args) => cmd_hil_plant::run(args),
        Command::Robustness(args) => cmd_robustness::run(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("error: {err:#}");
            let invalid_params = err
                .chain()
                .any(|cause| cause.is::<actuator_params::ParamsError>());
            if invalid_params {
                ExitCode::from(EXIT_INVALID_PARAMS)
            } else {
                ExitCode::FAILURE
            }
        }
    }
}
