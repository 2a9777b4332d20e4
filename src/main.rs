//! The `whitted` command line: parse the arguments, run the command
//! (`whitted::cli`), exit with its code (`whitted::error`).

use clap::Parser;
use std::process::ExitCode;
use whitted::cli::{self, Cli, Ui};

fn main() -> ExitCode {
    cli::install_panic_hook();
    let args = Cli::parse();
    cli::init_logging(Ui {
        quiet: args.quiet,
        verbose: args.verbose,
    });
    cli::install_signal_handler();
    ExitCode::from(cli::run(args))
}
