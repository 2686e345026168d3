//! Shared plumbing of the workspace's command-line programs.

use std::process::ExitCode;

/// Sets up logging to stderr (warnings of the builder and the I/O thread),
/// runs `body`, and turns an error into a message and exit code 2.
pub fn main_with(body: impl FnOnce() -> anyhow::Result<()>) -> ExitCode {
    tracing_subscriber::fmt()
        .with_writer(std::io::stderr)
        .with_target(false)
        .without_time()
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .init();
    match body() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(2)
        }
    }
}
