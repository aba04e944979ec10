//! The `robocal` command; see `robocal --help`.

mod cli;

use clap::Parser;
use std::process::ExitCode;

/// Run the command line; exit 0 on success, 2 on a usage error (clap's, or flags that do not
/// fit together), 1 on any other error.
fn main() -> ExitCode {
    // Output piped into a reader that stops early (`robocal ... | head`) ends the process
    // quietly, as for other Unix tools, rather than in a panic of `println!`.
    #[cfg(unix)]
    // SAFETY: restoring the default action of one signal at start-up, before any thread exists.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
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
