//! Support for command-line programs built on tdpcr (the `tdpcr` binary and the
//! optimizer's `tdpcr-optim`), behind the `cli` feature: nothing here is numerics, and
//! library users who turn the feature off do not link `libc`.

/// Lets a command-line program end quietly, like other Unix tools, when the reader of its
/// standard output goes away (`tdpcr fk ... | head`), instead of panicking in `println!`:
/// restores the default action of SIGPIPE, which the Rust runtime sets to "ignore". Files
/// are not affected (they are written atomically). Any other failed write to standard
/// output ends the program with an error message and exit code 1 (`exit_on_stdout_errors`).
/// Call it first thing in `main`; the SIGPIPE part is a no-op on platforms without it.
pub fn end_quietly_on_broken_pipe() {
    exit_on_stdout_errors();
    #[cfg(unix)]
    // SAFETY: `signal` with SIG_DFL only resets a process-wide disposition; nothing else in
    // the process installs a SIGPIPE handler.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

/// Makes a failed write to standard output (a full disk, `> /dev/full`) end the program
/// with `error: cannot write to standard output: …` and exit code 1: `println!` panics
/// on a write error (exit code 101, "panicked at …"). Set by
/// [`end_quietly_on_broken_pipe`]; other panics keep the default report.
fn exit_on_stdout_errors() {
    let default = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let payload = info.payload();
        let message = payload
            .downcast_ref::<String>()
            .map(String::as_str)
            .or_else(|| payload.downcast_ref::<&str>().copied());
        if let Some(why) = message.and_then(|m| m.strip_prefix("failed printing to stdout: ")) {
            eprintln!("error: cannot write to standard output: {why}");
            std::process::exit(1);
        }
        default(info);
    }));
}
