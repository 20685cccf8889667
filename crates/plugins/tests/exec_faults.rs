//! A process stage's faults stay inside it: a process that exits, is killed, hangs, writes
//! garbage, breaks the row contract or raises is an error naming its command and what it did;
//! one that dies once is restarted and the frame answered. The processes are small Python
//! programs on the shipped helper (examples/plugins/python/footscan_stage.py) in the numpy
//! venv scripts/setup.sh makes (target/venv-plugins).

use footscan_plugins::exec::{ExecDetector, ExecLimits};
use footscan_plugins::rows::{Pixels, RowOut};
use footscan_plugins::PluginError;
use std::path::{Path, PathBuf};
use std::time::Duration;

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The venv's Python (FOOTSCAN_PLUGIN_PYTHON overrides it).
fn python() -> String {
    if let Ok(p) = std::env::var("FOOTSCAN_PLUGIN_PYTHON") {
        return p;
    }
    let p = repo().join("target/venv-plugins/bin/python");
    assert!(
        p.exists(),
        "{} is missing: run scripts/setup.sh (it makes the numpy venv the process stages use)",
        p.display()
    );
    p.display().to_string()
}

/// A stage script in `dir` whose `detect(frame, args)` body is `body`.
fn script(dir: &Path, name: &str, body: &str) -> Vec<String> {
    let helper = repo().join("examples/plugins/python");
    let text = format!(
        "import os, signal, sys, time\nsys.path.insert(0, {:?})\nimport numpy as np\n\
         from footscan_stage import ROW, run_detector, rows_from_columns\n\
         def detect(frame, args):\n{}\nsys.exit(run_detector(detect))\n",
        helper.display().to_string(),
        body.lines()
            .map(|l| format!("    {l}\n"))
            .collect::<String>()
    );
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    vec![python(), p.display().to_string()]
}

fn limits(restarts: u32) -> ExecLimits {
    ExecLimits {
        frame_timeout: Duration::from_millis(1500),
        start_timeout: Duration::from_secs(20),
        max_restarts: restarts,
    }
}

fn frames(d: &mut ExecDetector, n: usize) -> Result<Vec<RowOut>, PluginError> {
    let mut px = vec![5u8; 64 * 8];
    px[3 * 64 + 20] = 200;
    let mut out = vec![
        RowOut {
            col: 0.0,
            intensity: 0.0,
            width: 0.0,
            quality: 0.0,
            reject: 0
        };
        8
    ];
    for _ in 0..n {
        d.detect(64, 8, Pixels::Gray8(&px), &mut out)?;
    }
    Ok(out)
}

fn fault(cmd: &[String], restarts: u32) -> String {
    let mut d = ExecDetector::start(cmd, &[], limits(restarts)).expect("starts");
    let e = frames(&mut d, 3).expect_err("the process misbehaves");
    assert!(matches!(e, PluginError::Fault { .. }), "{e}");
    let t = e.to_string();
    assert!(t.contains(&cmd[1]), "names the command: {t}");
    t
}

const ARGMAX: &str =
    "cols = np.where(frame.max(axis=1) > args.get('t', 100), frame.argmax(axis=1), np.nan)\n\
                      return rows_from_columns(frame, cols)";

#[test]
fn frames_go_through_shared_memory_and_rows_come_back() {
    let dir = tempfile::tempdir().unwrap();
    let cmd = script(dir.path(), "argmax.py", ARGMAX);
    let mut d = ExecDetector::start(&cmd, &[("t".into(), 100.0)], limits(0)).unwrap();
    let out = frames(&mut d, 5).unwrap();
    assert_eq!(out[3].col, 20.0);
    assert_eq!(out[3].intensity, 200.0);
    assert_eq!(out[3].reject, 0);
    assert!(out
        .iter()
        .enumerate()
        .all(|(r, o)| r == 3 || (o.reject == 1 && o.col.is_nan())));
    // A new shape re-sizes the shared memory; Gray16 is little-endian.
    let mut rows = vec![out[0]; 4];
    let mut px = vec![7u16; 32 * 4];
    px[2 * 32 + 9] = 60000;
    d.detect(32, 4, Pixels::Gray16(&px), &mut rows).unwrap();
    assert_eq!(rows[2].col, 9.0);
    assert_eq!(rows[2].intensity, 60000.0);
    assert_eq!(d.restarts(), 0);
}

#[test]
fn a_process_that_dies_once_is_restarted_and_the_frame_answered() {
    let dir = tempfile::tempdir().unwrap();
    let marker = dir.path().join("crashed");
    let body = format!(
        "if not os.path.exists({m:?}):\n    open({m:?}, 'w').close()\n    os._exit(7)\n{ARGMAX}",
        m = marker.display().to_string()
    );
    let cmd = script(dir.path(), "once.py", &body);
    let mut d = ExecDetector::start(&cmd, &[], limits(2)).unwrap();
    let out = frames(&mut d, 3).unwrap();
    assert_eq!(out[3].col, 20.0);
    assert_eq!(d.restarts(), 1);
}

#[test]
fn a_process_that_keeps_exiting_fails_after_its_restarts() {
    let dir = tempfile::tempdir().unwrap();
    let t = fault(&script(dir.path(), "exit.py", "os._exit(3)"), 2);
    assert!(t.contains("exited with status 3"), "{t}");
    assert!(t.contains("after 2 restarts"), "{t}");
}

#[test]
fn a_killed_process_is_reported_with_its_signal() {
    let dir = tempfile::tempdir().unwrap();
    let t = fault(
        &script(
            dir.path(),
            "kill.py",
            "os.kill(os.getpid(), signal.SIGKILL)",
        ),
        0,
    );
    assert!(t.contains("killed by signal 9"), "{t}");
}

#[test]
fn a_hung_process_is_killed_at_the_frame_timeout() {
    let dir = tempfile::tempdir().unwrap();
    let t = fault(&script(dir.path(), "hang.py", "time.sleep(600)"), 0);
    assert!(t.contains("did not answer within 1500 ms"), "{t}");
}

#[test]
fn garbage_and_broken_row_contracts_are_faults() {
    let dir = tempfile::tempdir().unwrap();
    let t = fault(
        &script(
            dir.path(),
            "garbage.py",
            "sys.__stdout__.buffer.write(b'\\xff\\xfe garbage\\n'); sys.__stdout__.flush()\nreturn rows_from_columns(frame, np.full(frame.shape[0], np.nan))",
        ),
        0,
    );
    assert!(
        t.contains("not text") || t.contains("not \"rows <n>\""),
        "{t}"
    );
    // A stream without a newline is not read without end: a fault at 4 KiB, the process
    // killed, its bytes shown.
    let t = fault(
        &script(
            dir.path(),
            "endless.py",
            "sys.__stdout__.buffer.write(b'x' * 100000); sys.__stdout__.flush(); time.sleep(30)",
        ),
        0,
    );
    assert!(t.contains("bytes without a newline: \"xxxx"), "{t}");
    let t = fault(
        &script(
            dir.path(),
            "few.py",
            "return rows_from_columns(frame[:-1], np.full(frame.shape[0] - 1, np.nan))",
        ),
        0,
    );
    assert!(t.contains("answered 7 rows for a frame of 8 rows"), "{t}");
    let t = fault(
        &script(dir.path(), "nan.py", "r = rows_from_columns(frame, np.full(frame.shape[0], np.nan))\nr['reject'][2] = 0\nreturn r"),
        0,
    );
    assert!(t.contains("returned column NaN for row 2"), "{t}");
    let t = fault(
        &script(dir.path(), "raise.py", "raise ValueError('no laser here')"),
        0,
    );
    assert!(
        t.contains("reported an error: ValueError: no laser here"),
        "{t}"
    );
}

#[test]
fn a_command_that_cannot_start_or_refuses_is_refused_at_start() {
    let e = ExecDetector::start(&["/nonexistent/stage".into()], &[], limits(0))
        .unwrap_err()
        .to_string();
    assert!(e.contains("cannot start /nonexistent/stage"), "{e}");
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("mute.py");
    std::fs::write(&p, "import sys\nsys.stdin.readline()\nprint('hi there')\n").unwrap();
    let e = ExecDetector::start(&[python(), p.display().to_string()], &[], limits(0)).unwrap_err();
    assert!(matches!(e, PluginError::Load { .. }), "{e}");
    assert!(
        e.to_string().contains("answered hello with \"hi there\""),
        "{e}"
    );
}
