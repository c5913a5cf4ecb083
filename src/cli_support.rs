//! Support for command-line programs built on tdpcr (the `tdpcr` binary and the
//! optimizer's `tdpcr-optim`), behind the `cli` feature: nothing here is numerics, and
//! library users who turn the feature off do not link `libc`.

/// Lets a command-line program end quietly, like other Unix tools, when the reader of its
/// standard output goes away (`tdpcr fk ... | head`), instead of panicking in `println!`:
/// restores the default action of SIGPIPE, which the Rust runtime sets to "ignore". Files
/// are not affected (they are written atomically). Call it first thing in `main`; a no-op
/// on platforms without SIGPIPE.
pub fn end_quietly_on_broken_pipe() {
    #[cfg(unix)]
    // SAFETY: `signal` with SIG_DFL only resets a process-wide disposition; nothing else in
    // the process installs a SIGPIPE handler.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}
