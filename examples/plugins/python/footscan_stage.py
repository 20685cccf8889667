"""The Python side of footscan's process stages (protocol 1, docs/plugins.md).

A researcher writes one function and hands it to `run_detector`:

    import numpy as np
    from footscan_stage import run_detector, rows_from_columns

    def detect(frame, args):            # frame: (height, width) uint8 or uint16 array
        cols = ...                      # float64 per row, NaN where no line
        return rows_from_columns(frame, cols)

    run_detector(detect)

Per-scan stages and sinks are one function too (`run_scan`, `run_sink`, below).

The frame is a view of the shared memory the host wrote it into (fd 3), not a copy; the
returned rows are written back into the same memory. Everything printed to stderr goes to
footscand's log; stdout belongs to the protocol (print() is redirected to stderr).
"""

import json
import mmap
import sys

import numpy as np

PROTOCOL = 1
FRAME_FD = 3
# One record per row: what the built-in detectors return (crates/plugins/src/rows.rs).
ROW = np.dtype(
    [("col", "<f8"), ("intensity", "<f4"), ("width", "<f4"), ("quality", "<f4"), ("reject", "<u4")]
)
# Reject codes (0 = a line was found).
ACCEPTED, BELOW_THRESHOLD, SATURATED, AMBIGUOUS, BORDER, ISOLATED = range(6)


def rows_from_columns(frame, cols):
    """Records from a column per row (NaN = no line): intensity is the row's maximum, width
    and quality are left 0."""
    cols = np.asarray(cols, dtype=np.float64)
    out = np.zeros(frame.shape[0], dtype=ROW)
    ok = np.isfinite(cols)
    out["col"] = np.where(ok, cols, np.nan)
    out["intensity"] = frame.max(axis=1)
    out["reject"] = np.where(ok, ACCEPTED, BELOW_THRESHOLD)
    return out


def _hello(role, proto_out, stdin):
    """Read `hello 1 <role> key=value ...`, answer `ready 1`; the args (numbers as floats,
    other words as strings), or None after an `error` answer."""
    hello = stdin.readline().split()
    if len(hello) < 3 or hello[0] != b"hello" or hello[2] != role.encode():
        proto_out.write(f"error expected 'hello 1 {role} ...'\n".encode())
        proto_out.flush()
        return None
    if int(hello[1]) != PROTOCOL:
        proto_out.write(b"error this helper speaks protocol 1\n")
        proto_out.flush()
        return None
    args = {}
    for kv in hello[3:]:
        k, _, v = kv.decode().partition("=")
        try:
            args[k] = float(v)
        except ValueError:
            args[k] = v
    proto_out.write(b"ready 1\n")
    proto_out.flush()
    return args


def _report_error(proto_out, e):
    msg = f"{type(e).__name__}: {e}".replace("\n", " ")
    proto_out.write(f"error {msg}\n".encode())
    proto_out.flush()


def _serve_once(role, handle):
    """The per-scan and sink loop: input bytes at offset 0 of the shared memory, a report
    (bytes or str) written after it."""
    proto_out = sys.stdout.buffer
    sys.stdout = sys.stderr
    stdin = sys.stdin.buffer
    args = _hello(role, proto_out, stdin)
    if args is None:
        return 1
    for line in stdin:
        words = line.rstrip(b"\n").split(b" ", 4)
        if len(words) < 4 or words[0] != role.encode():
            proto_out.write(b"error unknown message\n")
            proto_out.flush()
            return 1
        n, total = int(words[2]), int(words[3])
        rest = words[4].decode() if len(words) > 4 else None
        mm = mmap.mmap(FRAME_FD, total)
        try:
            data = bytes(mm[:n])
            try:
                report = handle(data, rest, args)
            except Exception as e:
                _report_error(proto_out, e)
                raise
            if isinstance(report, str):
                report = report.encode()
            off = (n + 7) // 8 * 8
            if off + len(report) > total:
                proto_out.write(b"error the report is larger than the space the host gave\n")
                proto_out.flush()
                return 1
            mm[off : off + len(report)] = report
        finally:
            mm.close()
        proto_out.write(b"report %d\n" % len(report))
        proto_out.flush()
    return 0


def run_scan(stage):
    """Serve a per-scan stage: `stage(points, args) -> {key: number}`, points an (n, 3)
    float64 array (x, y, z in mm). The values are added to scan.json."""

    def handle(data, _rest, args):
        pts = np.frombuffer(data, dtype="<f8").reshape(-1, 3)
        values = stage(pts, args)
        return "".join(f"{k} {float(v)!r}\n" for k, v in values.items())

    return _serve_once("scan", handle)


def run_sink(sink):
    """Serve a sink: `sink(summary, scan_dir, args) -> str`, summary the scan summary as a
    dict, scan_dir the scan directory's path. The returned text is the sink's report, a file
    in the scan directory."""

    def handle(data, rest, args):
        return sink(json.loads(data), rest, args)

    return _serve_once("sink", handle)


def run_detector(detect):
    """Serve frames to `detect(frame, args) -> rows` until the host closes stdin. `args` is
    the stage's `args` table as a dict of floats. A raised exception is reported to the host
    (the scan fails with its text) and ends the process."""
    proto_out = sys.stdout.buffer
    sys.stdout = sys.stderr  # a stray print() must not break the protocol
    stdin = sys.stdin.buffer
    args = _hello("detector", proto_out, stdin)
    if args is None:
        return 1
    mm, size = None, 0
    for line in stdin:
        words = line.split()
        if not words or words[0] != b"frame":
            proto_out.write(b"error unknown message\n")
            proto_out.flush()
            return 1
        _seq, w, h, bpp, total = (int(x) for x in words[1:6])
        if total != size:
            if mm is not None:
                mm.close()
            mm, size = mmap.mmap(FRAME_FD, total), total
        dtype = np.uint8 if bpp == 1 else np.dtype("<u2")
        frame = np.frombuffer(mm, dtype=dtype, count=w * h).reshape(h, w)
        out_off = (w * h * bpp + 7) // 8 * 8
        out = np.frombuffer(mm, dtype=ROW, count=h, offset=out_off)
        try:
            rows = detect(frame, args)
        except Exception as e:  # reported, then the process ends: the host fails the scan
            msg = f"{type(e).__name__}: {e}".replace("\n", " ")
            proto_out.write(f"error {msg}\n".encode())
            proto_out.flush()
            raise
        n = len(rows)
        out[: min(n, h)] = rows[: min(n, h)]
        del frame, out
        proto_out.write(b"rows %d\n" % n)
        proto_out.flush()
    return 0
