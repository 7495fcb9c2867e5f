//! SIGINT, SIGTERM and SIGHUP as one request to stop. `timeout`, CI runners and container
//! engines stop a process with SIGTERM, and a closed terminal sends SIGHUP: a command that keeps
//! its work on Ctrl-C keeps it on those too, then exits 128 + the signal's number, as a shell
//! reports a process the signal ended (130 for SIGINT, 143 for SIGTERM, 129 for SIGHUP).
//!
//! The handler itself only writes the signal's number to a pipe (async-signal-safe); a thread
//! of its own reads it and runs the command's callback, which may lock, print and exit.

use std::sync::atomic::{AtomicBool, Ordering};

/// The signals handled.
#[cfg(unix)]
pub const SIGNALS: [i32; 3] = [libc::SIGINT, libc::SIGTERM, libc::SIGHUP];

/// The exit status of a process that stopped because of `signal`: 128 + its number.
pub fn exit_status(signal: i32) -> i32 {
    128 + signal
}

/// The signal's name (`SIGTERM`), for messages.
pub fn name(signal: i32) -> String {
    #[cfg(unix)]
    match signal {
        libc::SIGINT => return "SIGINT (Ctrl-C)".into(),
        libc::SIGTERM => return "SIGTERM".into(),
        libc::SIGHUP => return "SIGHUP".into(),
        _ => {}
    }
    format!("signal {signal}")
}

/// Ends the process at once with [`exit_status`]`(signal)`, from any thread: no destructor,
/// no atexit handler (the driver's, mid-work on another thread, would not survive them).
pub fn exit_now(signal: i32) -> ! {
    #[cfg(unix)]
    // SAFETY: `_exit` ends the process; it touches no Rust state.
    unsafe {
        libc::_exit(exit_status(signal))
    }
    #[cfg(not(unix))]
    std::process::exit(exit_status(signal))
}

static INSTALLED: AtomicBool = AtomicBool::new(false);

/// Calls `f` with the signal's number, on a thread of its own, each time SIGINT, SIGTERM or
/// SIGHUP arrives from now on. Once per process.
pub fn on_stop(f: impl FnMut(i32) + Send + 'static) -> Result<(), String> {
    if INSTALLED.swap(true, Ordering::SeqCst) {
        return Err("a stop handler is already installed".into());
    }
    install(f)
}

#[cfg(unix)]
mod unix {
    use std::sync::atomic::{AtomicI32, Ordering};

    /// The pipe's write end, for the handler.
    pub static PIPE: AtomicI32 = AtomicI32::new(-1);

    pub extern "C" fn on_signal(signal: libc::c_int) {
        // Async-signal-safe: an atomic load and one write(2). The write end does not block; a
        // full pipe (hundreds of signals unread) drops the byte, and errno is saved around it.
        let errno = std::io::Error::last_os_error().raw_os_error();
        let byte = signal as u8;
        // SAFETY: writes one byte from a live local to a descriptor this process owns.
        unsafe { libc::write(PIPE.load(Ordering::Relaxed), (&byte as *const u8).cast(), 1) };
        if let Some(e) = errno {
            set_errno(e);
        }
    }

    #[cfg(any(target_os = "linux", target_os = "android"))]
    fn set_errno(e: i32) {
        // SAFETY: the calling thread's errno, as it was.
        unsafe { *libc::__errno_location() = e };
    }

    #[cfg(not(any(target_os = "linux", target_os = "android")))]
    fn set_errno(_: i32) {}
}

#[cfg(unix)]
fn install(mut f: impl FnMut(i32) + Send + 'static) -> Result<(), String> {
    let os = |what: &str| format!("{what}: {}", std::io::Error::last_os_error());
    let mut fds = [0; 2];
    // SAFETY: `pipe` fills the two descriptors of the array it is given.
    if unsafe { libc::pipe(fds.as_mut_ptr()) } != 0 {
        return Err(os("pipe"));
    }
    let [read_end, write_end] = fds;
    // SAFETY: sets flags on descriptors just made. Close-on-exec: the commands a run starts
    // (bench per LP_NUM_THREADS, the driver statistics) do not inherit them.
    unsafe {
        if libc::fcntl(read_end, libc::F_SETFD, libc::FD_CLOEXEC) != 0
            || libc::fcntl(write_end, libc::F_SETFD, libc::FD_CLOEXEC) != 0
            || libc::fcntl(write_end, libc::F_SETFL, libc::O_NONBLOCK) != 0
        {
            return Err(os("fcntl"));
        }
    }
    unix::PIPE.store(write_end, Ordering::SeqCst);
    std::thread::Builder::new()
        .name("stop-signals".into())
        .spawn(move || loop {
            let mut byte = 0u8;
            // SAFETY: reads one byte into a live local from the pipe's read end.
            match unsafe { libc::read(read_end, (&mut byte as *mut u8).cast(), 1) } {
                1 => f(i32::from(byte)),
                n if n < 0 && std::io::Error::last_os_error().kind() == std::io::ErrorKind::Interrupted => {}
                _ => return,
            }
        })
        .map_err(|e| format!("cannot start the signal thread: {e}"))?;
    for signal in SIGNALS {
        // SAFETY: a zeroed `sigaction` is valid (empty mask, no flags); the handler is an
        // `extern "C" fn(c_int)` that only does async-signal-safe work.
        unsafe {
            let mut action: libc::sigaction = std::mem::zeroed();
            action.sa_sigaction = unix::on_signal as extern "C" fn(libc::c_int) as libc::sighandler_t;
            action.sa_flags = libc::SA_RESTART;
            libc::sigemptyset(&mut action.sa_mask);
            if libc::sigaction(signal, &action, std::ptr::null_mut()) != 0 {
                return Err(os("sigaction"));
            }
        }
    }
    Ok(())
}

#[cfg(not(unix))]
fn install(mut f: impl FnMut(i32) + Send + 'static) -> Result<(), String> {
    // Ctrl-C (and Ctrl-Break) only; reported as SIGINT.
    ctrlc::set_handler(move || f(2)).map_err(|e| e.to_string())
}
