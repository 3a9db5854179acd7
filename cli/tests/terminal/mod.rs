//! Running the `hdrcodec` binary with stderr on a pseudo-terminal, for the tests of its
//! progress bars (shared by `batch.rs` and `video.rs`).

use std::process::{Command, Stdio};

/// Runs `hdrcodec ARGS` with stderr on a pseudo-terminal of 120 columns and stdout on a pipe;
/// returns what reached the terminal and what reached stdout.
pub fn run_on_terminal(args: &[&dyn AsRef<std::ffi::OsStr>]) -> (String, String) {
    use rustix::pty::{grantpt, ioctl_tiocgptpeer, openpt, unlockpt, OpenptFlags};
    use std::io::Read;
    let master = openpt(OpenptFlags::RDWR | OpenptFlags::NOCTTY | OpenptFlags::CLOEXEC).unwrap();
    grantpt(&master).unwrap();
    unlockpt(&master).unwrap();
    let terminal = ioctl_tiocgptpeer(&master, OpenptFlags::RDWR | OpenptFlags::NOCTTY).unwrap();
    let size = rustix::termios::Winsize { ws_row: 24, ws_col: 120, ws_xpixel: 0, ws_ypixel: 0 };
    rustix::termios::tcsetwinsize(&terminal, size).unwrap();
    let child = Command::new(env!("CARGO_BIN_EXE_hdrcodec"))
        .args(args.iter().map(|a| a.as_ref()))
        .env("TERM", "xterm-256color")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::from(terminal))
        .spawn()
        .unwrap();
    // Read while it runs (a full terminal buffer would block it); the read fails (EIO) once
    // the child, the terminal's last user, has closed it.
    let mut master = std::fs::File::from(master);
    let screen = std::thread::spawn(move || {
        let mut all = Vec::new();
        let mut chunk = [0u8; 4096];
        while let Ok(n @ 1..) = master.read(&mut chunk) {
            all.extend_from_slice(&chunk[..n]);
        }
        all
    });
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success(), "{:?}", out.status);
    let screen = String::from_utf8_lossy(&screen.join().unwrap()).into_owned();
    (screen, String::from_utf8_lossy(&out.stdout).into_owned())
}
