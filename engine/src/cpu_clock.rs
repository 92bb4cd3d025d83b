//! CPU time of the calling thread or the process, for benchmarks and for the training CPU a
//! test curve records.
//!
//! On a machine shared with builds or other runs, wall time measures the scheduler as much as
//! the code; the thread's own CPU time does not. On an idle machine the two agree.

use std::time::Duration;

/// CPU time this thread has used so far.
pub fn thread_cpu_time() -> Duration {
    cpu_time(libc::CLOCK_THREAD_CPUTIME_ID)
}

/// CPU time all threads of this process have used so far: over a parallel section, divided by
/// its wall time, it tells how many cores the section actually got.
pub fn process_cpu_time() -> Duration {
    cpu_time(libc::CLOCK_PROCESS_CPUTIME_ID)
}

fn cpu_time(clock: libc::clockid_t) -> Duration {
    let mut now = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `now` is a valid, writable timespec, and both CPU-time clocks are always
    // supported on Linux.
    let status = unsafe { libc::clock_gettime(clock, &mut now) };
    assert_eq!(status, 0, "clock_gettime({clock}) failed");
    Duration::new(now.tv_sec as u64, now.tv_nsec as u32)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn advances_while_the_thread_computes() {
        let start = thread_cpu_time();
        let mut x = 0u64;
        while thread_cpu_time() - start < Duration::from_millis(5) {
            x = std::hint::black_box(x.wrapping_mul(31).wrapping_add(7));
        }
        assert!(thread_cpu_time() - start >= Duration::from_millis(5));
    }
}
