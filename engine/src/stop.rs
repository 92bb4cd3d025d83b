//! A sweep stopped from outside. A scheduler pre-empts with SIGTERM and sends SIGKILL after a
//! grace period (Slurm's `KillWait`, 30 s by default); a user presses Ctrl-C. Either way the
//! sweep stops taking cells, gives back the leases of the cells in flight (their training
//! resumes from its last save), and exits, well inside the grace period: every result file is
//! written whole or not at all, so nothing it leaves is trusted half-written, and the
//! re-queued task continues where it stopped.

use std::sync::atomic::{AtomicI32, Ordering};

/// The signal that asked the sweep to stop, 0 before any.
static REQUESTED: AtomicI32 = AtomicI32::new(0);

extern "C" fn on_signal(signal: libc::c_int) {
    // Only an atomic store: nothing else is safe inside a signal handler.
    REQUESTED.store(signal, Ordering::SeqCst);
}

/// From now on SIGTERM and SIGINT ask the sweep to stop instead of killing the process.
pub fn catch_termination() {
    for signal in [libc::SIGTERM, libc::SIGINT] {
        // SAFETY: `on_signal` only stores to an atomic, which is async-signal-safe.
        unsafe {
            libc::signal(signal, on_signal as *const () as libc::sighandler_t);
        }
    }
}

/// From now on SIGTERM and SIGINT end the process with 128 + the signal once no save is in
/// progress (`store::save_set::exit_between_saves`), after `last_words` (given the signal's
/// name): for a command whose work since its last save is simply done again, such as
/// `harness train`.
pub fn exit_between_saves_when_asked(last_words: impl Fn(&str) + Send + 'static) {
    catch_termination();
    std::thread::spawn(move || {
        loop {
            if let Some(signal) = requested() {
                let name = signal_name(signal);
                store::save_set::exit_between_saves(128 + signal, || last_words(name));
            }
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
    });
}

/// The signal that asked for a stop, if one did.
pub(crate) fn requested() -> Option<i32> {
    match REQUESTED.load(Ordering::SeqCst) {
        0 => None,
        signal => Some(signal),
    }
}

/// The name of a signal, for the message a stopped sweep prints.
pub(crate) fn signal_name(signal: i32) -> &'static str {
    match signal {
        libc::SIGTERM => "SIGTERM",
        libc::SIGINT => "SIGINT",
        _ => "a signal",
    }
}
