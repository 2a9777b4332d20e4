//! The command line: one module per command (`render`, `validate`,
//! `devices`, `generate`, `export`), the options they share, logging,
//! progress bars, the panic hook and the signal handler. `src/main.rs` only
//! parses arguments, calls [`run`] and exits with the code it gets.
//!
//! Exit codes: see `crate::error`.

pub mod bench;
pub mod chart;
pub mod devices;
pub mod export;
pub mod generate;
pub mod options;
pub mod profile;
pub mod reference;
pub mod render;
pub mod stability;
pub mod validate;

use crate::error::{exit_code, EXIT_INTERNAL, EXIT_INTERRUPTED};
use clap::{Parser, Subcommand};
use std::io::{IsTerminal, Write};
use std::time::{Duration, Instant};

/// A recursive (Whitted-style) ray tracer: a Vulkan compute shader with a
/// CPU mirror of the same algorithm on the same data.
///
/// Exit codes: 0 success, 1 validation over tolerance (or a bench case failed), 2 bad input or
/// usage (the message names the file, line and column), 3 internal error,
/// 4 the GPU failed (lost, out of memory, timed out, or its driver refused
/// the kernel),
/// 130 interrupted.
#[derive(Parser)]
#[command(name = "whitted", version, about, long_about)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
    /// More messages on stderr: -v adds whitted's debug messages (the time
    /// of each phase, choices made), -vv other crates' and Vulkan's too,
    /// -vvv everything. RUST_LOG, when set, overrides (e.g.
    /// RUST_LOG=gpu_allocator=debug).
    #[arg(short, long, action = clap::ArgAction::Count, global = true)]
    pub verbose: u8,
    /// Errors only: no progress bars, notes or summaries on stderr.
    #[arg(short, long, global = true, conflicts_with = "verbose")]
    pub quiet: bool,
}

#[derive(Subcommand)]
pub enum Command {
    /// Render a scene (.toml native format or .nff) to a PNG, EXR or HDR file.
    ///
    /// Example: whitted render scenes/showcase.toml -o showcase.png --spp 4
    Render(render::RenderArgs),
    /// Render a scene on both backends (CPU mirror and GPU) and compare.
    ///
    /// Prints max and mean absolute error, RMSE, PSNR, mean FLIP (on the
    /// 8-bit sRGB images), the fraction of pixels over the per-pixel
    /// tolerance, each ray count on both sides, and each side's work per
    /// kind of ray (tests and cells+nodes per eye, secondary and shadow
    /// ray; informational, docs/gpu.md "Work counters"). Exits 1 when the
    /// images or ray counts are over tolerance (see docs/gpu.md), 0 when
    /// they agree. Uses the device --backend gpu would (lavapipe too).
    ///
    /// Example: whitted validate scenes/showcase.toml --width 160 --height 120 --diff diff.png
    Validate(validate::ValidateArgs),
    /// List the Vulkan devices and say which one each backend picks.
    ///
    /// For each device: its index (for --device), name, type, driver,
    /// maxStorageBufferRange (the largest array a scene may have),
    /// maxComputeWorkGroupInvocations, subgroup size and whether it has
    /// timestamps (for device timings).
    Devices(devices::DevicesArgs),
    /// Write a procedural scene as NFF: one of the SPD's seven scenes at any
    /// size factor, random spheres, or a sphereflake.
    ///
    /// Examples: whitted generate teapot --size 12 -o teapot.nff;
    /// whitted generate --count 100000 -o spheres-100k.nff
    Generate(generate::GenerateArgs),
    /// Convert a scene to POV-Ray 3.7 (.pov) or NFF (.nff), e.g. to time
    /// POV-Ray on the same scene.
    Export(export::ExportArgs),
    /// Time a suite of scenes on every backend (and POV-Ray 3.7 with --vs
    /// povray): a warm-up, then N interleaved runs; median, min and max
    /// wall and render time, Mrays/s over every ray, peak memory; a table,
    /// CSV and plots (BENCHMARKS.md). A case that an engine cannot run
    /// (its render fails) is reported beneath the table (FAILED) and in the
    /// CSV's `failed` column, the other engines and cases go on, and the
    /// exit code is 1.
    ///
    /// Example: whitted bench --vs povray --runs 7 --csv bench.csv --plot bench.svg
    Bench(bench::BenchArgs),
    /// Render a scene's reference image (or fetch it from the cache): the
    /// CPU tracer in f64, 64 stratified samples per pixel, depth 16, no
    /// adaptive cut-off. Cached under a hash of the scene's content and
    /// the settings (docs/accuracy.md).
    ///
    /// Example: whitted reference scenes/showcase.toml --width 200 --height 150 -o ref.exr
    Reference(reference::ReferenceArgs),
    /// Chart speed against accuracy: sweep max depth, min weight, samples
    /// per pixel, sampling, precision, backend, grid density, acceleration
    /// structure and shadow method one at a time from the defaults; each point
    /// the median time of several runs after a warm-up and its error
    /// against the reference; the Pareto front ringed (docs/accuracy.md).
    ///
    /// Example: whitted chart scenes/showcase.toml --width 200 --height 150 -o chart.svg --csv chart.csv
    Chart(chart::ChartArgs),
    /// Measure where methods fail: the surface offset (acne against
    /// leaks), grazing and tangent rays, the critical angle, cell
    /// boundaries, watertightness, distance from the origin, scale, the
    /// quadratic solver, and f32 against f64 and CPU against GPU per scene;
    /// a Markdown report with tables and pictures (docs/stability.md).
    ///
    /// Example: whitted stability -o docs/stability.md --pictures docs/stability
    Stability(stability::StabilityArgs),
    /// Profile GPU dispatch shapes on one device: every workgroup shape ×
    /// tile size, a warm-up each, then interleaved rounds; median, min and
    /// max device time (timestamp queries), wall time and Mrays/s, sorted
    /// with the best marked; the phases of one render; CSV and a heat map;
    /// --save stores the best shape for `render` (docs/profiling.md).
    ///
    /// Example: whitted profile scenes/showcase.toml --width 320 --height 240 --plot shapes.svg
    Profile(profile::ProfileArgs),
}

/// Global output settings every command sees.
#[derive(Clone, Copy, Debug, Default)]
pub struct Ui {
    pub quiet: bool,
    pub verbose: u8,
}

/// Runs a parsed command line; returns the exit code (errors are printed).
pub fn run(cli: Cli) -> u8 {
    let ui = Ui {
        quiet: cli.quiet,
        verbose: cli.verbose,
    };
    // Test hook (docs/reliability.md): prove that a panic exits with 3.
    if std::env::var_os("WHITTED_TEST_PANIC").is_some() {
        panic!("WHITTED_TEST_PANIC is set");
    }
    let r = match cli.command {
        Command::Render(a) => render::run(a, ui),
        Command::Validate(a) => validate::run(a, ui),
        Command::Devices(a) => devices::run(a, ui),
        Command::Generate(a) => generate::run(a, ui),
        Command::Export(a) => export::run(a, ui),
        Command::Bench(a) => bench::run(a, ui),
        Command::Reference(a) => reference::run(a, ui),
        Command::Chart(a) => chart::run(a, ui),
        Command::Stability(a) => stability::run(a, ui),
        Command::Profile(a) => profile::run(a, ui),
    };
    match r {
        Ok(code) => code,
        Err(e) => {
            log::error!("{e:#}");
            exit_code(&e)
        }
    }
}

/// Sends `log` records to stderr: `error: …`, `warning: …`, `note: …` (info),
/// `debug: …`; the level from -q/-v unless RUST_LOG is set.
pub fn init_logging(ui: Ui) {
    let level = if ui.quiet {
        log::LevelFilter::Error
    } else {
        match ui.verbose {
            0 => log::LevelFilter::Info,
            1 => log::LevelFilter::Debug,
            _ => log::LevelFilter::Trace,
        }
    };
    let mut b = env_logger::Builder::new();
    // Other crates (gpu-allocator, ...) speak at warn by default, and only
    // at debug with -vv: their info is noise to a user.
    let others = match ui.verbose {
        0 | 1 => log::LevelFilter::Warn,
        2 => log::LevelFilter::Debug,
        _ => log::LevelFilter::Trace,
    };
    b.filter_level(if ui.quiet {
        log::LevelFilter::Error
    } else {
        others
    });
    b.filter_module("whitted", level);
    if let Ok(spec) = std::env::var("RUST_LOG") {
        b.parse_filters(&spec);
    }
    b.format(|f, r| {
        let tag = match r.level() {
            log::Level::Error => "error",
            log::Level::Warn => "warning",
            log::Level::Info => "note",
            log::Level::Debug => "debug",
            log::Level::Trace => "trace",
        };
        if r.target().starts_with("whitted") {
            writeln!(f, "{tag}: {}", r.args())
        } else {
            writeln!(f, "{tag}: {}: {}", r.target(), r.args())
        }
    });
    b.write_style(env_logger::WriteStyle::Never);
    let _ = b.try_init();
}

/// A panic is a bug: say so, ask for a report, remove temporary files and
/// exit with code 3 (never Rust's 101).
pub fn install_panic_hook() {
    std::panic::set_hook(Box::new(|info| {
        let msg = info
            .payload()
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| info.payload().downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "unknown panic".into());
        let at = info
            .location()
            .map(|l| format!(" at {}:{}", l.file(), l.line()))
            .unwrap_or_default();
        crate::files::remove_temporaries();
        let _ = writeln!(
            std::io::stderr(),
            "internal error: {msg}{at}\nThis is a bug in whitted {}; please report it with the \
             command line and the scene that caused it.",
            env!("CARGO_PKG_VERSION")
        );
        std::process::exit(EXIT_INTERNAL as i32);
    }));
}

/// SIGINT, SIGTERM and SIGHUP: remove temporary files, exit with 130.
pub fn install_signal_handler() {
    let _ = ctrlc::set_handler(|| {
        crate::files::remove_temporaries();
        let _ = writeln!(std::io::stderr(), "interrupted");
        std::process::exit(EXIT_INTERRUPTED as i32);
    });
}

/// Loads a scene with a progress bar (bytes read) that appears only when
/// loading takes more than about a second, on a terminal.
pub fn load_scene(ui: Ui, path: &std::path::Path) -> anyhow::Result<crate::scene::Scene> {
    let bar = Bar::new(ui, "loading");
    let r = crate::scene::load_with_progress(path, &|d, t| bar.set(d, t));
    bar.finish();
    r.map_err(crate::error::user)
}

/// A progress bar on stderr that appears only after about a second, only
/// on a terminal, and never with -q.
pub struct Bar {
    bar: indicatif::ProgressBar,
    started: Instant,
    enabled: bool,
}

impl Bar {
    pub fn new(ui: Ui, what: &str) -> Bar {
        let bar = indicatif::ProgressBar::hidden();
        let template =
            format!("{{spinner}} {what} [{{bar:40}}] {{percent}}% {{elapsed}}/{{duration}}");
        if let Ok(style) = indicatif::ProgressStyle::with_template(&template) {
            bar.set_style(style.progress_chars("=> "));
        }
        Bar {
            bar,
            started: Instant::now(),
            enabled: !ui.quiet && std::io::stderr().is_terminal(),
        }
    }

    /// Reports `done` of `total`.
    pub fn set(&self, done: u64, total: u64) {
        if self.enabled && self.bar.is_hidden() && self.started.elapsed() > Duration::from_secs(1) {
            self.bar
                .set_draw_target(indicatif::ProgressDrawTarget::stderr());
        }
        self.bar.set_length(total);
        self.bar.set_position(done);
    }

    /// Names the current stage.
    pub fn stage(&self, what: &str) {
        if self.bar.message() != what {
            self.bar.set_message(what.to_string());
        }
    }

    /// Reports pack's grid stages (`pack::Stage`).
    pub fn pack_stage(&self, stage: crate::pack::Stage, done: u64, total: u64) {
        self.stage(match stage {
            crate::pack::Stage::Sort => "ordering primitives",
            crate::pack::Stage::Count => "counting grid references",
            crate::pack::Stage::File => "filing the grid",
            crate::pack::Stage::Bvh => "building the BVH",
        });
        self.set(done, total);
    }

    pub fn finish(&self) {
        self.bar.finish_and_clear();
    }
}
