//! Measurements behind `footscan bench`: each module runs one benchmark and returns rows that
//! print as a table or serialise as JSON. Timings are measured here, never asserted in tests.

pub mod calibrate;
pub mod detect;
pub mod measure;
pub mod real;
pub mod render;
pub mod surface;

/// Run `f` on the calling thread pinned to one core where the OS allows, so "per core"
/// figures mean what they say.
pub fn on_one_core<R: Send>(f: impl FnOnce() -> R + Send) -> R {
    std::thread::scope(|s| {
        s.spawn(|| {
            pin_current_thread();
            f()
        })
        .join()
        .expect("benchmark thread panicked")
    })
}

fn pin_current_thread() {
    // SAFETY: a zeroed cpu_set_t is valid; CPU_SET and sched_setaffinity only touch that set.
    unsafe {
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        let mut current: libc::cpu_set_t = std::mem::zeroed();
        if libc::sched_getaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &mut current) != 0 {
            return;
        }
        // The first CPU this process may use.
        let Some(cpu) = (0..libc::CPU_SETSIZE as usize).find(|&c| libc::CPU_ISSET(c, &current))
        else {
            return;
        };
        libc::CPU_SET(cpu, &mut set);
        libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &set);
    }
}
