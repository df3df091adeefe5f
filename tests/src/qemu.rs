//! Runs the emulated-board firmware (ARM MPS2 AN386) in qemu-system-arm with
//! UART0 on a loopback TCP port, and guarantees the emulator is gone when the
//! guard is dropped (also when a test fails).

use std::fmt;
use std::fs::File;
use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

/// Env var naming the firmware ELF to boot.
pub const ELF_ENV: &str = "FIRMWARE_QEMU_ELF";

/// How to make the ELF, for error messages.
pub const BUILD_HINT: &str =
    "build it with `scripts/build-firmware` or `cargo build -p firmware --profile firmware \
     --target thumbv7em-none-eabihf --no-default-features --features board-qemu` \
     (install QEMU with `apt-get install -y qemu-system-arm`)";

/// Highest address of the AN386's code memory; the STM32F407's flash starts at
/// 0x0800_0000, so an entry point above this is the wrong board's image.
const AN386_CODE_END: u32 = 0x0040_0000;

/// Why the emulator could not be started.
#[derive(Debug)]
pub enum QemuError {
    ElfMissing {
        path: PathBuf,
    },
    WrongBoard {
        path: PathBuf,
        entry: u32,
    },
    /// The image runs its control loop in the other mode (lock step or free
    /// running) than the test asked for.
    WrongMode {
        path: PathBuf,
        free_running: bool,
    },
    NotElf {
        path: PathBuf,
        detail: String,
    },
    QemuMissing,
    Spawn(std::io::Error),
    ExitedEarly {
        status: ExitStatus,
        stderr: String,
    },
}

impl fmt::Display for QemuError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            QemuError::ElfMissing { path } => write!(
                f,
                "firmware ELF {} not found (set {ELF_ENV} to override): {BUILD_HINT}",
                path.display()
            ),
            QemuError::WrongBoard { path, entry } => write!(
                f,
                "{} has its entry point at {entry:#010x}, outside the mps2-an386 code memory: \
                 it was built for another board (the STM32F407 build overwrites the same path); {BUILD_HINT}",
                path.display()
            ),
            QemuError::WrongMode { path, free_running } => {
                let (is, wanted) = if *free_running {
                    ("the free-running board (`--features board-qemu,free-run`)", "lock step")
                } else {
                    ("the lock-step board", "running free (`--features board-qemu,free-run`)")
                };
                write!(
                    f,
                    "{} is {is}, but this test needs the board {wanted}: {BUILD_HINT} \
                     (scripts/build-firmware builds both: target/firmware/qemu.elf, qemu-free-run.elf)",
                    path.display()
                )
            }
            QemuError::NotElf { path, detail } => {
                write!(f, "{} is not a usable ARM ELF ({detail}): {BUILD_HINT}", path.display())
            }
            QemuError::QemuMissing => write!(
                f,
                "qemu-system-arm not found on PATH: install it with `apt-get install -y qemu-system-arm`"
            ),
            QemuError::Spawn(e) => write!(f, "cannot start qemu-system-arm: {e}"),
            QemuError::ExitedEarly { status, stderr } => {
                write!(f, "qemu-system-arm exited early ({status}): {stderr}")
            }
        }
    }
}

impl std::error::Error for QemuError {}

/// The firmware ELF: `$FIRMWARE_QEMU_ELF`, else the qemu board's `firmware`-profile build
/// under the workspace's target directory.
pub fn firmware_elf_path() -> PathBuf {
    if let Some(path) = std::env::var_os(ELF_ENV) {
        return PathBuf::from(path);
    }
    target_dir().join("thumbv7em-none-eabihf/firmware/firmware")
}

/// Env var naming the free-running firmware ELF (the emulated board built
/// with `--features board-qemu,free-run`).
pub const FREE_RUN_ELF_ENV: &str = "FIRMWARE_QEMU_FREE_RUN_ELF";

/// The free-running firmware ELF: `$FIRMWARE_QEMU_FREE_RUN_ELF`, else
/// `firmware/qemu-free-run.elf` under the target directory, where
/// `scripts/build-firmware` (or `scripts/qemu-free-run`) leaves it.
pub fn free_run_elf_path() -> PathBuf {
    if let Some(path) = std::env::var_os(FREE_RUN_ELF_ENV) {
        return PathBuf::from(path);
    }
    target_dir().join("firmware/qemu-free-run.elf")
}

/// The workspace's cargo target directory: `$CARGO_TARGET_DIR` (relative to
/// the workspace when relative), else `target/` beside the workspace root.
pub fn target_dir() -> PathBuf {
    let workspace = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let target = std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| workspace.join("target"));
    if target.is_absolute() {
        target
    } else {
        workspace.join(target)
    }
}

/// Checks that `path` is a 32-bit little-endian ARM ELF whose entry point
/// lies in the AN386's code memory.
pub fn check_elf(path: &Path) -> Result<(), QemuError> {
    let bytes = std::fs::read(path).map_err(|_| QemuError::ElfMissing {
        path: path.to_path_buf(),
    })?;
    let not_elf = |detail: &str| QemuError::NotElf {
        path: path.to_path_buf(),
        detail: detail.to_string(),
    };
    let header = bytes
        .get(..28)
        .ok_or_else(|| not_elf("shorter than an ELF header"))?;
    if header.get(..4) != Some(b"\x7fELF".as_slice()) {
        return Err(not_elf("no ELF magic"));
    }
    // EI_CLASS = 1 (32 bit), EI_DATA = 1 (little endian), e_machine = 40 (ARM).
    if header.get(4) != Some(&1) || header.get(5) != Some(&1) {
        return Err(not_elf("not a 32-bit little-endian ELF"));
    }
    if header.get(18..20) != Some([40u8, 0].as_slice()) {
        return Err(not_elf("not an ARM ELF"));
    }
    let entry = header
        .get(24..28)
        .and_then(|b| <[u8; 4]>::try_from(b).ok())
        .map(u32::from_le_bytes)
        .ok_or_else(|| not_elf("no entry point"))?;
    if entry >= AN386_CODE_END {
        return Err(QemuError::WrongBoard {
            path: path.to_path_buf(),
            entry,
        });
    }
    Ok(())
}

/// The name the free-running image reports in `HelloAck` (its
/// `BOARD_NAME`): in the image's read-only data, and nowhere in a lock-step
/// image.
const FREE_RUN_BOARD_NAME: &[u8] = b"mps2-an386-free-run";

/// Whether the image at `path` is the free-running board.
fn is_free_running(path: &Path) -> Result<bool, QemuError> {
    let bytes = std::fs::read(path).map_err(|_| QemuError::ElfMissing {
        path: path.to_path_buf(),
    })?;
    Ok(bytes
        .windows(FREE_RUN_BOARD_NAME.len())
        .any(|window| window == FREE_RUN_BOARD_NAME))
}

/// Checks that the image at `path` runs in the mode the test wants.
fn check_mode(path: &Path, free_running: bool) -> Result<(), QemuError> {
    let is = is_free_running(path)?;
    if is != free_running {
        return Err(QemuError::WrongMode {
            path: path.to_path_buf(),
            free_running: is,
        });
    }
    Ok(())
}

/// A running emulator; dropping it kills it and waits for it (bounded).
pub struct QemuBoard {
    child: Option<Child>,
    port: u16,
    stderr_path: PathBuf,
    log_path: PathBuf,
}

impl QemuBoard {
    /// Boots `elf` with UART0 served on a free loopback port. QEMU holds the
    /// CPU until a client connects (`wait=on`), so nothing the firmware sends
    /// is lost.
    pub fn start(elf: &Path) -> Result<Self, QemuError> {
        check_elf(elf)?;
        check_mode(elf, false)?;
        Self::start_with(elf, &[])
    }

    /// [`QemuBoard::start`] for the free-running board: no `-icount`, so
    /// QEMU's virtual clock, the firmware's time and its ticker, follows the
    /// host's clock, as the free-running plant on the host does.
    pub fn start_free_running(elf: &Path) -> Result<Self, QemuError> {
        check_elf(elf)?;
        check_mode(elf, true)?;
        Self::start_with(elf, &[])
    }

    /// [`QemuBoard::start`] with one emulated nanosecond per instruction
    /// (`-icount shift=0`), so the firmware's TIMER0 counts instructions
    /// (one count per 40) and its `RuntimeReport` gives instruction counts.
    pub fn start_counting_instructions(elf: &Path) -> Result<Self, QemuError> {
        check_elf(elf)?;
        check_mode(elf, false)?;
        Self::start_with(elf, &["-icount", "shift=0"])
    }

    fn start_with(elf: &Path, extra_args: &[&str]) -> Result<Self, QemuError> {
        check_elf(elf)?;
        if Command::new("qemu-system-arm")
            .arg("--version")
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .is_err()
        {
            return Err(QemuError::QemuMissing);
        }
        // Ask the OS for a free port, release it, and give it to QEMU.
        let port = TcpListener::bind("127.0.0.1:0")
            .and_then(|l| l.local_addr())
            .map_err(QemuError::Spawn)?
            .port();
        let dir = std::env::temp_dir();
        let tag = format!("qemu-an386-{}-{port}", std::process::id());
        let stderr_path = dir.join(format!("{tag}.stderr"));
        let log_path = dir.join(format!("{tag}.defmt"));
        let stderr = File::create(&stderr_path).map_err(QemuError::Spawn)?;
        let log = File::create(&log_path).map_err(QemuError::Spawn)?;
        let child = Command::new("qemu-system-arm")
            .args([
                "-machine",
                "mps2-an386",
                "-display",
                "none",
                "-monitor",
                "none",
            ])
            .args(extra_args)
            .args(["-semihosting-config", "enable=on,target=native"])
            .arg("-chardev")
            .arg(format!(
                "socket,id=u0,host=127.0.0.1,port={port},server=on,wait=on,nodelay=on"
            ))
            .args(["-serial", "chardev:u0", "-kernel"])
            .arg(elf)
            .stdin(Stdio::null())
            // defmt frames (binary) over semihosting; decode with `defmt-print -e ELF`.
            .stdout(log)
            .stderr(stderr)
            .spawn()
            .map_err(QemuError::Spawn)?;
        Ok(QemuBoard {
            child: Some(child),
            port,
            stderr_path,
            log_path,
        })
    }

    /// The UART0 socket address.
    pub fn uart_addr(&self) -> String {
        format!("127.0.0.1:{}", self.port)
    }

    /// Where the defmt log (raw frames) goes.
    pub fn defmt_log_path(&self) -> &Path {
        &self.log_path
    }

    /// Fails if QEMU has already exited (e.g. the firmware panicked and
    /// exited through semihosting, or the port was taken).
    pub fn check_running(&mut self) -> Result<(), QemuError> {
        let Some(child) = self.child.as_mut() else {
            return Ok(());
        };
        match child.try_wait() {
            Ok(Some(status)) => Err(QemuError::ExitedEarly {
                status,
                stderr: std::fs::read_to_string(&self.stderr_path).unwrap_or_default(),
            }),
            Ok(None) => Ok(()),
            Err(e) => Err(QemuError::Spawn(e)),
        }
    }

    /// Connects to UART0, for a test: panics with QEMU's own reason when it
    /// already exited (e.g. the port was taken after it was picked), else
    /// with the connection's error.
    pub fn connect_uart(&mut self) -> host_sim::link::TcpLink {
        match host_sim::link::TcpLink::connect(&self.uart_addr(), Duration::from_secs(10)) {
            Ok(link) => link,
            Err(e) => {
                self.check_running().unwrap_or_else(|q| panic!("{q}"));
                panic!("{e}");
            }
        }
    }

    /// Kills the emulator and waits up to `limit` for it to go. Returns
    /// whether it is gone.
    pub fn shutdown(&mut self, limit: Duration) -> bool {
        let Some(mut child) = self.child.take() else {
            return true;
        };
        let _ = child.kill();
        let deadline = Instant::now() + limit;
        loop {
            match child.try_wait() {
                Ok(Some(_)) => return true,
                Ok(None) if Instant::now() < deadline => {
                    std::thread::sleep(Duration::from_millis(10))
                }
                _ => {
                    // Put it back so the caller can see it is still there.
                    self.child = Some(child);
                    return false;
                }
            }
        }
    }
}

impl Drop for QemuBoard {
    fn drop(&mut self) {
        if !self.shutdown(Duration::from_secs(5)) {
            eprintln!(
                "warning: qemu-system-arm (pid {:?}) did not exit within 5 s of SIGKILL",
                self.child.as_ref().map(Child::id)
            );
        }
        if std::thread::panicking() {
            // Keep the evidence of a failing test.
            eprintln!(
                "qemu stderr kept in {}, defmt log (decode with `defmt-print -e ELF < FILE`) in {}",
                self.stderr_path.display(),
                self.log_path.display()
            );
        } else {
            let _ = std::fs::remove_file(&self.stderr_path);
            let _ = std::fs::remove_file(&self.log_path);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A minimal 32-bit little-endian ARM ELF header with entry point `entry`.
    fn elf_header(entry: u32) -> Vec<u8> {
        let mut h = vec![0u8; 52];
        h[..4].copy_from_slice(b"\x7fELF");
        h[4] = 1; // 32 bit
        h[5] = 1; // little endian
        h[18..20].copy_from_slice(&40u16.to_le_bytes()); // EM_ARM
        h[24..28].copy_from_slice(&entry.to_le_bytes());
        h
    }

    fn check_bytes(name: &str, bytes: &[u8]) -> Result<(), QemuError> {
        let path = std::env::temp_dir().join(format!("{name}-{}.elf", std::process::id()));
        std::fs::write(&path, bytes).expect("write temp ELF");
        let result = check_elf(&path);
        let _ = std::fs::remove_file(&path);
        result
    }

    #[test]
    fn a_free_running_image_is_told_from_a_lock_step_one() {
        let path = std::env::temp_dir().join(format!("mode-{}.elf", std::process::id()));
        let mut bytes = elf_header(0x401);
        std::fs::write(&path, &bytes).expect("write temp ELF");
        assert!(check_mode(&path, false).is_ok());
        let err = check_mode(&path, true).expect_err("lock step is not free running");
        assert!(err.to_string().contains("free-run"), "{err}");
        bytes.extend_from_slice(b"..mps2-an386-free-run..");
        std::fs::write(&path, &bytes).expect("write temp ELF");
        assert!(check_mode(&path, true).is_ok());
        assert!(matches!(
            check_mode(&path, false),
            Err(QemuError::WrongMode {
                free_running: true,
                ..
            })
        ));
        let _ = std::fs::remove_file(&path);
    }

    #[test]
    fn an386_entry_point_is_accepted() {
        assert!(check_bytes("an386", &elf_header(0x0000_0401)).is_ok());
    }

    #[test]
    fn stm32_image_is_refused_as_the_wrong_board() {
        let err = check_bytes("stm32", &elf_header(0x0800_0189)).expect_err("wrong board");
        assert!(matches!(
            err,
            QemuError::WrongBoard {
                entry: 0x0800_0189,
                ..
            }
        ));
        assert!(err.to_string().contains("--features board-qemu"));
    }

    #[test]
    fn non_elf_and_non_arm_files_are_refused() {
        assert!(matches!(
            check_bytes(
                "text",
                b"not an elf at all, but long enough to hold a header"
            ),
            Err(QemuError::NotElf { .. })
        ));
        let mut x86 = elf_header(0x401);
        x86[18] = 3; // EM_386
        assert!(matches!(
            check_bytes("x86", &x86),
            Err(QemuError::NotElf { .. })
        ));
    }
}
