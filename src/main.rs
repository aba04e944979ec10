//! The `robocal` command; see `robocal --help`.

mod cli;

use clap::Parser;
use std::process::ExitCode;

/// Run the command line; exit 0 on success, 2 on a usage error (clap's, or flags that do not
/// fit together), 1 on any other error.
fn main() -> ExitCode {
    match cli::run(cli::Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("error: {error:#}");
            if error.is::<cli::UsageError>() {
                eprintln!("\nFor more information, try '--help'.");
                return ExitCode::from(2);
            }
            ExitCode::FAILURE
        }
    }
}
