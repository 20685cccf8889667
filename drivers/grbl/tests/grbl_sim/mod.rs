//! The real GRBL 1.1h firmware in its host simulator (grbl-sim) on a pseudo-terminal, for the
//! driver's tests and the stop study (examples/grbl_sim_study.rs).
//!
//! The sources and patches are in `../shared/firmware/grbl-1.1h` (its README: what was changed
//! and why); they are built once per source tree into `target/grbl-sim-<hash>/`, keyed by a
//! hash of every file, and never copied into the repository. Each [`GrblSim`] runs its own
//! simulator in its own directory (its settings persist in `EEPROM.DAT` there), behind
//! `socat`, which gives it a pty at `<dir>/ttyGRBL`.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::{Mutex, MutexGuard, OnceLock};
use std::time::{Duration, Instant};

/// Where the firmware sources are: `$FOOTSCAN_FIRMWARE`, else `../shared/firmware` beside the
/// repository.
pub fn source_dir() -> PathBuf {
    let base = std::env::var_os("FOOTSCAN_FIRMWARE")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/firmware"));
    base.join("grbl-1.1h")
}

/// `target/` (or `target/<triple>/`) of this build, from the running test or example.
fn target_dir() -> PathBuf {
    let exe = std::env::current_exe().expect("current exe");
    // target/debug/deps/NAME or target/debug/examples/NAME
    exe.ancestors()
        .nth(3)
        .expect("a test binary lives in target/<profile>/<dir>/")
        .to_path_buf()
}

/// FNV-1a over the relative paths and contents of every file under `dir`, in path order: the
/// cache key of a build (any change to a source or patch builds anew).
fn tree_hash(dir: &Path) -> std::io::Result<u64> {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) -> std::io::Result<()> {
        for e in std::fs::read_dir(dir)? {
            let p = e?.path();
            if p.is_dir() {
                walk(&p, out)?;
            } else {
                out.push(p);
            }
        }
        Ok(())
    }
    let mut files = Vec::new();
    walk(dir, &mut files)?;
    files.sort();
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut eat = |bytes: &[u8]| {
        for &b in bytes {
            h ^= b as u64;
            h = h.wrapping_mul(0x0100_0000_01b3);
        }
    };
    for f in files {
        let rel = f.strip_prefix(dir).unwrap_or(&f);
        eat(rel.to_string_lossy().as_bytes());
        eat(&[0]);
        eat(&std::fs::read(&f)?);
        eat(&[0]);
    }
    Ok(h)
}

fn have(tool: &str, arg: &str) -> bool {
    Command::new(tool)
        .arg(arg)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok()
}

fn copy_tree(from: &Path, to: &Path) -> std::io::Result<()> {
    std::fs::create_dir_all(to)?;
    for e in std::fs::read_dir(from)? {
        let e = e?;
        let (src, dst) = (e.path(), to.join(e.file_name()));
        if src.is_dir() {
            copy_tree(&src, &dst)?;
        } else {
            std::fs::copy(&src, &dst)?;
        }
    }
    Ok(())
}

/// Build grbl-sim from `src` into `target/grbl-sim-<hash>/`, or find it there. Concurrent
/// builders (a test binary and the study) each build in a scratch folder and rename it into
/// place; the first rename wins.
fn build(src: &Path) -> Result<PathBuf, String> {
    let hash = tree_hash(src).map_err(|e| format!("reading {}: {e}", src.display()))?;
    let target = target_dir();
    let done = target.join(format!("grbl-sim-{hash:016x}"));
    let exe = |root: &Path| root.join("grbl/grbl-sim/grbl_sim.exe");
    if exe(&done).is_file() {
        return Ok(exe(&done));
    }
    let scratch = target.join(format!("grbl-sim-build-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&scratch);
    copy_tree(src, &scratch).map_err(|e| format!("copying {}: {e}", src.display()))?;
    let t = Instant::now();
    let out = Command::new("make")
        .args(["new", "FLAGS=-g -O3 -fcommon"])
        .current_dir(scratch.join("grbl/grbl-sim"))
        .output()
        .map_err(|e| format!("running make: {e}"))?;
    if !out.status.success() || !exe(&scratch).is_file() {
        return Err(format!(
            "building grbl-sim failed ({}):\n{}\n{}",
            out.status,
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        ));
    }
    eprintln!(
        "built grbl-sim in {:?} into {}",
        t.elapsed(),
        done.display()
    );
    if std::fs::rename(&scratch, &done).is_err() {
        // Another builder got there first: use theirs.
        let _ = std::fs::remove_dir_all(&scratch);
    }
    if exe(&done).is_file() {
        Ok(exe(&done))
    } else {
        Err(format!("no grbl_sim.exe in {}", done.display()))
    }
}

/// The simulator executable, built once per run; `Err` carries why the firmware tests must be
/// skipped (gcc, make or socat missing) — a failed build with the tools present panics.
pub fn executable() -> Result<PathBuf, String> {
    static EXE: OnceLock<Result<PathBuf, String>> = OnceLock::new();
    EXE.get_or_init(|| {
        let missing: Vec<&str> = [("gcc", "--version"), ("make", "--version"), ("socat", "-V")]
            .into_iter()
            .filter(|(t, a)| !have(t, a))
            .map(|(t, _)| t)
            .collect();
        if !missing.is_empty() {
            return Err(format!(
                "SKIPPED: the GRBL firmware tests need {} (Debian packages; scripts/setup.sh installs them)",
                missing.join(", ")
            ));
        }
        let src = source_dir();
        assert!(
            src.join("grbl/grbl-sim/Makefile").is_file(),
            "the GRBL firmware sources are missing: expected {} (set FOOTSCAN_FIRMWARE to the folder holding grbl-1.1h)",
            src.display()
        );
        Ok(build(&src).unwrap_or_else(|e| panic!("{e}")))
    })
    .clone()
}

/// One running simulator behind socat. Dropping it ends both (their process group).
pub struct GrblSim {
    pub dir: PathBuf,
    pub port: PathBuf,
    socat: Option<Child>,
    /// One simulator at a time per process: two at once on a loaded 2-core machine left
    /// status queries unanswered for over 10 s. Released after the simulator has ended.
    _turn: MutexGuard<'static, ()>,
}

impl GrblSim {
    /// Start a fresh simulator (default settings) and wait for its pty; None (after printing
    /// why) where the tools are missing.
    pub fn start() -> Option<GrblSim> {
        let exe = match executable() {
            Ok(e) => e,
            Err(why) => {
                // Straight to the handle: the test harness captures eprintln! of passing tests.
                use std::io::Write;
                let _ = writeln!(std::io::stderr(), "{why}");
                return None;
            }
        };
        static TURN: Mutex<()> = Mutex::new(());
        // A test that failed while holding its turn poisons the lock; the turn is still free.
        let turn = TURN.lock().unwrap_or_else(|e| e.into_inner());
        static N: AtomicU32 = AtomicU32::new(0);
        let dir = target_dir().join(format!(
            "grbl-sim-run-{}-{}",
            std::process::id(),
            N.fetch_add(1, Ordering::Relaxed)
        ));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("simulator folder");
        let port = dir.join("ttyGRBL");
        let mut sim = GrblSim {
            dir: dir.clone(),
            port: port.clone(),
            socat: None,
            _turn: turn,
        };
        sim.spawn(&exe);
        Some(sim)
    }

    fn spawn(&mut self, exe: &Path) {
        use std::os::unix::process::CommandExt;
        // Steps and blocks are logged to /dev/null: step.out grows by every step.
        let exec = format!(
            "EXEC:'{} 1 -n -s /dev/null -b /dev/null',pty,raw,echo=0",
            exe.display()
        );
        let child = Command::new("socat")
            .arg(format!("PTY,raw,link={},echo=0", self.port.display()))
            .arg(exec)
            .current_dir(&self.dir)
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .process_group(0)
            .spawn()
            .expect("start socat");
        self.socat = Some(child);
        let t = Instant::now();
        while !self.port.exists() {
            assert!(
                t.elapsed() < Duration::from_secs(10),
                "socat made no pty at {}",
                self.port.display()
            );
            std::thread::sleep(Duration::from_millis(10));
        }
    }

    /// The simulator and socat end: the port vanishes as an unplugged adapter's does.
    pub fn kill(&mut self) {
        if let Some(mut c) = self.socat.take() {
            // The group holds socat and the simulator it started (and nothing else).
            let _ = Command::new("kill")
                .args(["-TERM", "--", &format!("-{}", c.id())])
                .status();
            let _ = c.wait();
        }
    }

    /// Stop and start again on the same folder and port path (its EEPROM settings kept):
    /// after an ALARM:3 grbl-sim does not move again until restarted.
    pub fn restart(&mut self) {
        self.kill();
        let exe = executable().expect("built before");
        let _ = std::fs::remove_file(&self.port);
        self.spawn(&exe);
    }

    pub fn port_str(&self) -> String {
        self.port.to_string_lossy().into_owned()
    }
}

impl Drop for GrblSim {
    fn drop(&mut self) {
        self.kill();
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}
