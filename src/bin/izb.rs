//! The `izb` command line: parses the arguments and dispatches to
//! [`izb::cli`], where every command lives.

use clap::{Parser, Subcommand};
use izb::cli::bench::{run_bench, BenchArgs};
use izb::cli::reference::{run_compare, run_reference, CompareArgs, ReferenceArgs};
use izb::cli::render::{run_render, RenderArgs};
use izb::cli::tools::{run_devices, run_info, run_lut, run_report, InfoArgs, LutArgs, ReportArgs};
use izb::cli::view::{run_view_command, ViewArgs};

#[derive(Parser)]
#[command(
    name = "izb",
    version,
    about = "Analytic antialiased hard shadows with a compute irregular z-buffer"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render the shadow mask: 32-sample analytic IZB (or 1 spp).
    Render(RenderArgs),
    /// Ground truth and every method side by side: error table, JSON, heat maps.
    Compare(CompareArgs),
    /// Regenerate the two 32-sample tables, the µQuad edge LUT and the light-sample LUT (the code build.rs runs), with pictures.
    Lut(LutArgs),
    /// Supersampled ray-traced ground truth: lit fraction per pixel.
    Reference(ReferenceArgs),
    /// Run time against error: IZB, ray-traced samples and shadow maps against one ground truth; JSON.
    Bench(BenchArgs),
    /// Pareto charts (PNG, SVG), crops at a shadow edge and an index.html from a bench JSON.
    Report(ReportArgs),
    /// Print a scene's triangle counts, bounds, camera and light.
    Info(InfoArgs),
    /// List the Vulkan devices `--device` can pick, best first.
    Devices,
    /// Interactive window: orbit, turn the light, compare methods side by side, live pass times and error.
    View(ViewArgs),
}

fn main() {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Render(a) => run_render(a),
        Command::Compare(a) => run_compare(a),
        Command::Lut(a) => run_lut(a),
        Command::Reference(a) => run_reference(a),
        Command::Bench(a) => run_bench(a),
        Command::Report(a) => run_report(a),
        Command::Info(a) => run_info(a),
        Command::Devices => run_devices(),
        Command::View(a) => run_view_command(a),
    };
    if let Err(e) = result {
        // Nobody reads a closed stdout's message: exit quietly.
        if e.downcast_ref::<izb::cli::console::StreamClosed>()
            .is_some()
        {
            std::process::exit(izb::cli::console::STREAM_CLOSED_STATUS);
        }
        izb::note!("error: {e:#}");
        std::process::exit(1);
    }
}
