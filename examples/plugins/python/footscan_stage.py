"""The Python side of footscan's process stages (protocol 1, docs/plugins.md).

A researcher writes one function and hands it to `run_detector`:

    import numpy as np
    from footscan_stage import run_detector, rows_from_columns

    def detect(frame, args):            # frame: (height, width) uint8 or uint16 array
        cols = ...                      # float64 per row, NaN where no line
        return rows_from_columns(frame, cols)

    run_detector(detect)

The frame is a view of the shared memory the host wrote it into (fd 3), not a copy; the
returned rows are written back into the same memory. Everything printed to stderr goes to
footscand's log; stdout belongs to the protocol (print() is redirected to stderr).
"""

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


def run_detector(detect):
    """Serve frames to `detect(frame, args) -> rows` until the host closes stdin. `args` is
    the stage's `args` table as a dict of floats. A raised exception is reported to the host
    (the scan fails with its text) and ends the process."""
    proto_out = sys.stdout.buffer
    sys.stdout = sys.stderr  # a stray print() must not break the protocol
    stdin = sys.stdin.buffer
    hello = stdin.readline().split()
    if len(hello) < 3 or hello[0] != b"hello" or hello[2] != b"detector":
        proto_out.write(b"error expected 'hello 1 detector ...'\n")
        proto_out.flush()
        return 1
    if int(hello[1]) != PROTOCOL:
        proto_out.write(b"error this helper speaks protocol 1\n")
        proto_out.flush()
        return 1
    args = {}
    for kv in hello[3:]:
        k, _, v = kv.decode().partition("=")
        args[k] = float(v)
    proto_out.write(b"ready 1\n")
    proto_out.flush()
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
