//! Lowering a thread's CPU priority relative to its process's, so work that can wait (web
//! answers, pushing to the fleet, a scan's CAD files) slows down before the scan pipeline
//! drops frames or the results wait.

/// Set the calling thread's nice value `by` levels above its current one (at most 19). Linux
/// nice values are per thread and lowering one's own priority needs no privilege; relative,
/// because the process itself may already run niced (a service unit, a test runner), where an
/// absolute 10 would put this thread level with the scan. A new thread inherits its
/// creator's value. Elsewhere than Linux: nothing.
pub fn lower_this_thread(by: i32) -> std::io::Result<()> {
    #[cfg(target_os = "linux")]
    // SAFETY: gettid, getpriority and setpriority on the calling thread only.
    unsafe {
        let tid = libc::syscall(libc::SYS_gettid) as libc::id_t;
        *libc::__errno_location() = 0;
        let own = libc::getpriority(libc::PRIO_PROCESS, tid);
        let own = if own == -1 && *libc::__errno_location() != 0 {
            0
        } else {
            own
        };
        if libc::setpriority(libc::PRIO_PROCESS, tid, (own + by).min(19)) != 0 {
            return Err(std::io::Error::last_os_error());
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = by;
    Ok(())
}
