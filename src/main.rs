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
    #[cfg(unix)]
    stop_cleanly_on_signals();
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

/// On SIGINT or SIGTERM, remove the temporary files and folders of the outputs being written
/// ([`robocal::io::abandon_pending_outputs`]) and exit 130 or 143 (128 + the signal), as a
/// shell does. The signals are blocked in every thread (the threads started later inherit the
/// mask) and taken by one thread with `sigwait`, so that the clean-up runs as ordinary code,
/// not in a signal handler.
#[cfg(unix)]
fn stop_cleanly_on_signals() {
    // SAFETY: a zeroed sigset_t is a valid argument for sigemptyset, which initialises it;
    // the calls get valid pointers and run before any other thread exists.
    let set = unsafe {
        let mut set: libc::sigset_t = std::mem::zeroed();
        libc::sigemptyset(&mut set);
        libc::sigaddset(&mut set, libc::SIGINT);
        libc::sigaddset(&mut set, libc::SIGTERM);
        libc::pthread_sigmask(libc::SIG_BLOCK, &set, std::ptr::null_mut());
        set
    };
    std::thread::spawn(move || {
        let mut signal = 0;
        // SAFETY: `set` is initialised above and `signal` is a valid place for the result.
        if unsafe { libc::sigwait(&set, &mut signal) } != 0 {
            return;
        }
        robocal::io::abandon_pending_outputs();
        std::process::exit(128 + signal);
    });
}
