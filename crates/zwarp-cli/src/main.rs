//! `zwarp`: the command-line front end of zwarp (image-based depth warping for real-time
//! rendering). One file per command under `commands/`; the commands that measure go through the
//! evaluation harness in `harness/` (frames, timing, comparisons).

mod args;
mod commands;
mod device;
mod harness;
mod output;

use clap::{Parser, Subcommand};

/// zwarp: predict depth (and colour) buffers of new views by warping buffers already rendered.
#[derive(Parser)]
#[command(name = "zwarp", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run the main job on an embedded procedural scene and show the key figures.
    Demo(commands::demo::DemoArgs),
    /// Render the buffers of one frame (depth, items, motion, layers, colour) as PNG + EXR.
    Render(commands::render::RenderArgs),
    /// Warp frame k to frame k+1 and compare with a direct render (paper 000, Sec. 4).
    Eval(commands::eval::EvalArgs),
    /// Occlusion culling by depth warping (WOC/AWOC) vs its baselines along a camera path.
    Cull(commands::cull::CullArgs),
    /// Soft shadows from warped shadow maps vs the reference and PCSS (paper 000, Sec. 6).
    Shadows(commands::shadows::ShadowsArgs),
    /// Frame-rate upsampling by colour warping vs rendering the in-between frames (seed 001).
    Upsample(commands::upsample::UpsampleArgs),
    /// Stereo views from one centre view or the previous frame's other eye (seed 001).
    Stereo(commands::stereo::StereoArgs),
    /// Both eyes of a stereo / VR frame by hybrid image warping vs rendering each eye (seed 003).
    Vr(commands::vr::VrArgs),
    /// Motion and defocus blur by accumulating warped views vs rendered ones (seed 001).
    Blur(commands::blur::BlurArgs),
    /// Run the protocol of every table and figure zwarp reproduces; write an HTML page, JSON and markdown.
    Report(commands::report::ReportArgs),
    /// List the compute devices (GPU adapters) zwarp can use.
    Info(commands::info::InfoArgs),
}

fn main() {
    // A closed stdout (`zwarp cull ... | head`) ends the process quietly, as it does other Unix
    // tools, instead of a panic inside `println!` (Rust ignores SIGPIPE by default).
    #[cfg(unix)]
    // SAFETY: restoring the default disposition of one signal before any thread is started.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    private_runtime_dir();
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Demo(a) => commands::demo::run(a),
        Command::Render(a) => commands::render::run(a),
        Command::Eval(a) => commands::eval::run(a),
        Command::Info(a) => commands::info::run(a),
        Command::Cull(a) => commands::cull::run(a),
        Command::Shadows(a) => commands::shadows::run(a),
        Command::Upsample(a) => commands::upsample::run(a),
        Command::Stereo(a) => commands::stereo::run(a),
        Command::Blur(a) => commands::blur::run(a),
        Command::Report(a) => commands::report::run(a),
        Command::Vr(a) => commands::vr::run(a),
    };
    if let Err(e) = result {
        // One line: the error and its causes, joined.
        let msg = e.chain().map(|c| c.to_string()).collect::<Vec<_>>().join(": ");
        eprintln!("error: {msg}");
        std::process::exit(1);
    }
}

/// Mesa's Vulkan loader prints two lines starting with "error:" when `XDG_RUNTIME_DIR` is unset
/// (common in containers and CI), which read as zwarp failing. Without one, give the process a
/// private runtime directory (mode 0700 under the temp dir) before any GPU or thread starts.
fn private_runtime_dir() {
    #[cfg(unix)]
    if std::env::var_os("XDG_RUNTIME_DIR").is_none() {
        use std::os::unix::fs::{DirBuilderExt, MetadataExt};
        // SAFETY: getuid has no preconditions.
        let uid = unsafe { libc::getuid() };
        let dir = std::env::temp_dir().join(format!("zwarp-runtime-{uid}"));
        let _ = std::fs::DirBuilder::new().mode(0o700).create(&dir);
        // Only a directory this user owns (another user may have created the name first).
        if std::fs::metadata(&dir).is_ok_and(|m| m.is_dir() && m.uid() == uid) {
            // First thing in main, before any other thread exists (set_var is not thread-safe).
            std::env::set_var("XDG_RUNTIME_DIR", &dir);
        }
    }
}
