//! The `whitted` command line: parse the arguments, run the command
//! (`whitted::cli`), exit with its code (`whitted::error`).

use clap::Parser;
use std::process::ExitCode;
use whitted::cli::{self, Cli, Ui};

/// jemalloc, configured in .cargo/config.toml to put its mappings on
/// transparent huge pages: a large scene's arrays then fault 2 MiB at a
/// time, not 4 KiB (docs/architecture.md, "Memory").
#[global_allocator]
static ALLOC: tikv_jemallocator::Jemalloc = tikv_jemallocator::Jemalloc;

fn main() -> ExitCode {
    whitted::pack::pages::allocator_gives_huge_pages();
    cli::install_panic_hook();
    let args = Cli::parse();
    cli::init_logging(Ui {
        quiet: args.quiet,
        verbose: args.verbose,
    });
    cli::install_signal_handler();
    ExitCode::from(cli::run(args))
}
