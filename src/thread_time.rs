//! The calling thread's own CPU time (`CLOCK_THREAD_CPUTIME_ID`): host
//! work without the time the thread slept or was off the CPU — what the
//! viewer and the worked host report as `record`'s and a frame's host
//! cost, where lavapipe executes the device's work on threads of its own.

/// CPU seconds this thread has run; NaN where the clock cannot be read
/// (and on systems other than Linux).
#[cfg(target_os = "linux")]
pub fn thread_cpu_seconds() -> f64 {
    let mut t = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `t` is a valid timespec to write; the clock id is a constant.
    let ok = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut t) } == 0;
    match ok {
        true => t.tv_sec as f64 + t.tv_nsec as f64 * 1e-9,
        false => f64::NAN,
    }
}

/// CPU seconds this thread has run: not measured here (NaN).
#[cfg(not(target_os = "linux"))]
pub fn thread_cpu_seconds() -> f64 {
    f64::NAN
}
