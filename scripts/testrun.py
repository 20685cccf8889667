#!/usr/bin/env python3
"""Run the workspace's test binaries several at a time, as `cargo test` would run them one by one.

Most of the suite's time is real-time waiting (simulated scans paced by the GRBL emulator,
slider moves on grbl-sim, daemons polled over HTTP), not CPU: binaries run side by side
overlap their waits. Each binary still runs whole, in its package's directory with cargo's
environment, so the serialisation and shared fixtures inside a binary stay as written.

Binaries marked real-time (below) run at the normal priority; the others run niced, so a
CPU-bound binary beside a simulated scan does not starve its frame pipeline (dropped frames
are what such a scan's test checks). The GRBL firmware tests run first, with nothing beside
them (grbl-sim stalls under load). The longest binaries start first, in the order of the
last run's times (target/test-times.json), so the tail is short.

Usage: testrun.py [-j N] [--list] [cargo test options...] [-- test filters...]
It builds with `cargo test --no-run`, runs every binary (never stopping at the first failure),
prints each binary's outcome with its wall and CPU seconds, every failing binary's whole
output, and exits non-zero if any failed.
"""

import json
import re
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

# A binary whose last run kept the CPU busy for this share of its wall time is CPU-bound: it
# runs in the niced lane. The others (real-time scans, daemons, slider moves: mostly waiting)
# share the normal-priority lanes; a binary never timed counts as one of them.
CPU_BOUND = 0.5
# ... unless its source runs a simulated scan (it would run at the niced priority and lose
# frames to the lanes beside it).
SCANS = re.compile(
    r'default_scan\(|run_scan\(|sim_scan\(|"scan", "--config"|\.arg\("scan"\)|/api/scans"'
    r'|SimCamera|GrblEmulator|daemon_support|grbl_sim')
NICE = 10
# Binaries that run with nothing beside them: the GRBL firmware's host simulator (grbl-sim)
# stalls under load (docs/method.md 14.1), and with a CPU-bound binary in the niced lane it
# missed a status report after a stop in all three of a test's attempts (29 Nov 2026), where
# alone it passes in 6 s.
ALONE = re.compile(r'^mod grbl_sim;', re.M)


def build(cargo_args):
    whole = not any(a in ("-p", "--package") or a.startswith("--package=") for a in cargo_args)
    cmd = ["cargo", "test"] + (["--workspace"] if whole else []) + [
        "--all-targets", "--no-run", "--message-format=json-render-diagnostics"] + cargo_args
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True)
    bins = []
    for line in proc.stdout:
        try:
            msg = json.loads(line)
        except json.JSONDecodeError:
            sys.stdout.write(line)
            continue
        if msg.get("reason") == "compiler-message":
            sys.stdout.write(msg["message"].get("rendered") or "")
        if msg.get("reason") != "compiler-artifact" or not msg.get("executable"):
            continue
        if not msg["profile"].get("test") and msg["target"]["kind"] != ["bench"]:
            continue
        pkg_dir = Path(msg["manifest_path"]).parent
        kind = msg["target"]["kind"][0]
        pkg = msg["package_id"]
        bins.append({
            "name": msg["target"]["name"],
            "kind": kind,
            "exe": msg["executable"],
            "dir": str(pkg_dir),
            "key": f"{pkg_dir.name}/{kind}/{msg['target']['name']}",
            "pkg": pkg,
            "scans": bool(SCANS.search(Path(msg["target"]["src_path"]).read_text(errors="replace"))),
            "alone": bool(ALONE.search(Path(msg["target"]["src_path"]).read_text(errors="replace"))),
        })
    if proc.wait() != 0:
        sys.exit(proc.returncode)
    return bins


def cargo_env(b):
    env = dict(os.environ)
    env["CARGO_MANIFEST_DIR"] = b["dir"]
    return env


def run(b, filters, out_dir):
    log = out_dir / (b["key"].replace("/", "__") + ".log")
    realtime = not b["batch"]
    # As cargo test runs it: a bench target without --bench runs in its test mode.
    args = [b["exe"]] + filters
    t0 = time.monotonic()
    with open(log, "wb") as f:
        p = subprocess.Popen(args, cwd=b["dir"], env=cargo_env(b), stdout=f,
                             stderr=subprocess.STDOUT,
                             preexec_fn=None if realtime else (lambda: os.nice(NICE)))
        _, status, ru = os.wait4(p.pid, 0)
    b["wall"] = time.monotonic() - t0
    b["cpu"] = ru.ru_utime + ru.ru_stime
    b["rc"] = os.waitstatus_to_exitcode(status)
    b["log"] = str(log)
    b["realtime"] = realtime


def main():
    argv = sys.argv[1:]
    jobs = int(os.environ.get("FOOTSCAN_TEST_JOBS", "1"))
    if argv[:1] == ["-j"]:
        jobs, argv = int(argv[1]), argv[2:]
    list_only = "--list" in argv
    argv = [a for a in argv if a != "--list"]
    filters = []
    if "--" in argv:
        i = argv.index("--")
        argv, filters = argv[:i], argv[i + 1:]
    # cargo's own flag for running on after a failure: always so here.
    argv = [a for a in argv if a != "--no-fail-fast"]
    root = Path(__file__).resolve().parent.parent
    target = Path(os.environ.get("CARGO_TARGET_DIR", root / "target"))
    bins = build(argv)
    times_file = target / "test-times.json"
    last = {}
    # The last run's times here, else the snapshot kept with this script (a fresh clone).
    for f in (times_file, Path(__file__).with_name("test-times.json")):
        try:
            last = json.loads(f.read_text())
            break
        except (OSError, ValueError):
            continue
    for b in bins:
        wall, cpu = last.get(b["key"], [1.0, 0.0])
        b["expect"] = wall
        b["batch"] = cpu >= CPU_BOUND * wall > 0.5 and not b["scans"]
    bins.sort(key=lambda b: -b["expect"])
    if list_only:
        for b in bins:
            lane = "alone" if b["alone"] else "cpu" if b["batch"] else "wait"
            print(f'{b["expect"]:7.1f}  {lane}  {b["key"]}')
        return 0
    out_dir = target / "test-logs"
    out_dir.mkdir(parents=True, exist_ok=True)
    t0 = time.monotonic()
    # Lanes: `jobs` at the normal priority for the waiting binaries, one niced for the
    # CPU-bound ones; a normal lane whose queue is empty helps the niced one (never the other
    # way: three waiting binaries at once lost frames on two cores).
    alone = [b for b in bins if b["alone"]]
    rest = [b for b in bins if not b["alone"]]
    queues = {False: [b for b in rest if not b["batch"]], True: [b for b in rest if b["batch"]]}
    lock = threading.Lock()

    def report(b):
        state = "ok" if b["rc"] == 0 else f"FAILED (exit {b['rc']})"
        print(f'{b["wall"]:7.1f} s wall {b["cpu"]:7.1f} s cpu  {b["key"]}  {state}', flush=True)

    for b in alone:
        b["batch"] = False
        run(b, filters, out_dir)
        report(b)

    def worker(batch):
        while True:
            with lock:
                q = queues[True] if batch else (queues[False] or queues[True])
                if not q:
                    return
                b = q.pop(0)
            run(b, filters, out_dir)
            with lock:
                report(b)

    threads = [threading.Thread(target=worker, args=(False,)) for _ in range(max(1, jobs))]
    threads.append(threading.Thread(target=worker, args=(True,)))
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    wall = time.monotonic() - t0
    failed = [b for b in bins if b["rc"] != 0]
    for b in failed:
        print(f"\n===== {b['key']} failed (exit {b['rc']}): {b['log']} =====")
        sys.stdout.write(Path(b["log"]).read_text(errors="replace"))
    if not filters:
        times = dict(last)
        times.update({b["key"]: [round(b["wall"], 1), round(b["cpu"], 1)] for b in bins})
        tmp = times_file.with_suffix(".tmp")
        tmp.write_text(json.dumps(times, indent=1, sort_keys=True))
        tmp.replace(times_file)
    passed = sum(
        int(line.split()[3]) for b in bins for line in Path(b["log"]).read_text(
            errors="replace").splitlines() if line.startswith("test result:"))
    print(f"\n{len(bins)} test binaries, {passed} tests passed, {len(failed)} binaries failed; "
          f"{wall:.0f} s wall, {sum(b['wall'] for b in bins):.0f} s of binaries' wall, "
          f"{sum(b['cpu'] for b in bins):.0f} s CPU, {jobs} + 1 lanes")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
