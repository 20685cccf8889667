"""The centre-of-gravity detector of examples/plugins/cog-wasm/cog.c as a process stage, in
numpy: what the built-in `detect.cog` does with a fixed threshold, the ambiguity test off and
specular spikes not skipped, vectorised over the rows. Columns equal the built-in's within
1e-9 px (numpy sums the centre of gravity in another order); everything else bit for bit.

    [[pipeline.stages]]
    stage = "exec"
    command = ["target/venv-plugins/bin/python", "examples/plugins/python/cog_stage.py"]
    args = { threshold = 30 }
"""

import sys

import numpy as np

from footscan_stage import ROW, run_detector

NEAR_ROWS = 2


# Half the width of the window around each row's maximum that the line is measured in.
HALF_WINDOW = 48


def cog(frame, args):
    """The rows of `frame`: each row is measured in a window of 2*HALF_WINDOW+1 pixels around
    its first maximum (found on the whole row), and rows whose run above the threshold comes
    within 2 pixels of the window's edge (where it is not the frame's) are measured again on
    the whole row, so the result is the whole-row computation's."""
    h, w = frame.shape
    full = np.float32(255 if frame.dtype == np.uint8 else 65535)
    scale = np.float32(1 if frame.dtype == np.uint8 else 257)
    thr = np.float32(args["threshold"]) * scale
    max_sat = int(args.get("max_saturated_px", 12))
    pos = frame.argmax(axis=1)
    win = 2 * HALF_WINDOW + 1
    if w <= win:
        out, _, _ = measure(frame, pos, np.zeros(h, dtype=np.int64), thr, full, max_sat)
    else:
        start = np.clip(pos - HALF_WINDOW, 0, w - win)
        sub = np.take_along_axis(frame, start[:, None] + np.arange(win)[None, :], axis=1)
        out, lo, hi = measure(sub, pos - start, start, thr, full, max_sat)
        cut = (out["reject"] != 1) & (
            ((lo < 2) & (start > 0)) | ((hi > win - 3) & (start + win < w))
        )
        if cut.any():
            again, _, _ = measure(
                frame[cut], pos[cut], np.zeros(cut.sum(), dtype=np.int64), thr, full, max_sat
            )
            out[cut] = again
    isolate(out)
    return out


def measure(frame, pos, offset, thr, full, max_sat):
    """Per row: the record (isolation not yet applied) and the run above the threshold, for
    rows whose pixel 0 is column `offset` of the frame (positions are computed in the frame's
    columns, so the float arithmetic is the whole row's)."""
    h, w = frame.shape
    out = np.zeros(h, dtype=ROW)
    out["col"] = np.nan
    rows = np.arange(h)
    idx = np.arange(w)[None, :]
    f = frame.astype(np.float32)
    top = f[rows, pos]
    out["intensity"] = top
    reject = np.where(top <= thr, 1, 0).astype(np.uint32)

    def run_around(mask, at):
        """First and last index of the run of `mask` holding column `at`, per row."""
        left = np.where(~mask & (idx < at[:, None]), idx, -1).max(axis=1) + 1
        right = np.where(~mask & (idx > at[:, None]), idx, w).min(axis=1) - 1
        return left, right

    a, b = run_around(frame == frame[rows, pos][:, None], pos)
    saturated = np.where(top >= full, b - a + 1, 0)
    lo, hi = run_around(f > thr, pos)
    reject = np.where((reject == 0) & ((lo == 0) | (hi + 1 == w)), 4, reject)
    ok = reject == 0
    lo_, hi_ = np.where(ok, lo, 2), np.where(ok, hi, w - 3)  # safe indices on rejected rows
    bg = np.minimum(f[rows, lo_ - 1], f[rows, hi_ + 1])
    bg = np.where(lo_ >= 2, np.minimum(bg, f[rows, np.maximum(lo_ - 2, 0)]), bg)
    bg = np.where(hi_ + 2 < w, np.minimum(bg, f[rows, np.minimum(hi_ + 2, w - 1)]), bg)
    half = bg + np.float32(0.5) * (top - bg)
    below = f < half[:, None]
    l = np.maximum(lo_, np.where(below & (idx < a[:, None]), idx, -1).max(axis=1) + 1)
    l = np.where(ok, np.maximum(l, 1), 1)
    r = np.minimum(hi_, np.where(below & (idx > b[:, None]), idx, w).min(axis=1) - 1)
    r = np.where(ok, np.minimum(r, w - 2), 0)
    # Speckle on a wide line: a dip under half height is crossed when the line is back at
    # half height within the width found so far (inside the run). Few rows have one, so
    # those are walked one by one.
    reach = r + 1 - l
    back = (~below & (idx >= np.maximum(l - reach, lo_)[:, None]) & (idx < l[:, None])).any(axis=1)
    back |= (~below & (idx > r[:, None]) & (idx <= np.minimum(r + reach, hi_)[:, None])).any(axis=1)
    for i in np.nonzero(ok & back)[0]:
        l[i], r[i] = cross_dips(f[i], half[i], lo_[i], hi_[i], int(l[i]), int(r[i]))
    v0, v1 = f[rows, l - 1], f[rows, l]
    xl = (l - 1 + offset).astype(np.float32) + np.clip((half - v0) / np.maximum(v1 - v0, np.float32(1e-6)), 0, 1)
    v0, v1 = f[rows, r], f[rows, r + 1]
    xr = (r + offset).astype(np.float32) + np.clip((v0 - half) / np.maximum(v0 - v1, np.float32(1e-6)), 0, 1)
    width = np.maximum(xr - xl, np.float32(0.5)).astype(np.float32)
    # The run crosses a dip under the threshold when the line is back above it within its
    # width: the other half of a speckled wide line is not a second peak.
    reach = width.astype(np.int64)
    above = f > thr
    more = (above & (idx >= np.maximum(lo_ - reach, 1)[:, None]) & (idx <= (lo_ - 2)[:, None])).any(axis=1)
    more |= (above & (idx >= (hi_ + 2)[:, None]) & (idx <= np.minimum(hi_ + reach, w - 2)[:, None])).any(axis=1)
    lo_, hi_ = lo_.copy(), hi_.copy()
    for i in np.nonzero(ok & more)[0]:
        lo_[i], hi_[i] = cross_run(f[i], thr, int(lo_[i]), int(hi_[i]), int(reach[i]), w)
    lo, hi = np.where(ok, lo_, lo), np.where(ok, hi_, hi)
    # Over-exposed: clipped over more than max_sat pixels and over half the width.
    reject = np.where(ok & (saturated > max_sat) & (saturated > np.float32(0.5) * width), 2, reject)
    ok = reject == 0
    inside = (idx >= lo_[:, None]) & (idx <= hi_[:, None])
    wgt = np.where(inside, (f - thr).astype(np.float64), 0.0)
    s = wgt.sum(axis=1)
    sx = (wgt * (np.arange(w)[None, :] + offset[:, None]).astype(np.float64)).sum(axis=1)
    reject = np.where(ok & (s <= 0.0), 1, reject)
    ok = reject == 0
    sig = np.clip((top - thr) / np.maximum(np.float32(0.5) * full - thr, np.float32(1)), 0, 1)
    quality = (sig * np.float32(1) * np.where(saturated > 0, np.float32(0.5), np.float32(1))).astype(np.float32)
    out["col"] = np.where(ok, sx / np.where(ok, s, 1.0), np.nan)
    out["width"] = np.where(ok, width, 0)
    out["quality"] = np.where(ok, quality, 0)
    out["reject"] = reject
    # How far the run's search looked beyond it: a row whose search reached the window's edge
    # is measured again on the whole row.
    return out, lo - reach, hi + reach


def cross_dips(row, half, lo, hi, l, r):
    """The half-height crossings (l, r) of one row after crossing speckle dips."""
    while True:
        reach, l0, r0 = r + 1 - l, l, r
        for j in range(l - 1, max(l - reach, lo) - 1, -1):
            if row[j] >= half:
                l = j + 1
                while l > lo and row[l - 1] >= half:
                    l -= 1
                break
        for j in range(r + 1, min(r + reach, hi) + 1):
            if row[j] >= half:
                r = j
                while r + 1 <= hi and row[r + 1] >= half:
                    r += 1
                break
        if (l, r) == (l0, r0):
            return l, r


def cross_run(row, thr, lo, hi, reach, w):
    """The run above the threshold (lo, hi) of one row after crossing dips under it."""
    while True:
        lo0, hi0 = lo, hi
        for j in range(lo - 2, max(lo - reach, 1) - 1, -1):
            if row[j] > thr:
                nl = j + 1
                while nl > 0 and row[nl - 1] > thr:
                    nl -= 1
                if nl > 0:
                    lo = nl
                break
        for j in range(hi + 2, min(hi + reach, w - 2) + 1):
            if row[j] > thr:
                nh = j
                while nh + 1 < w and row[nh + 1] > thr:
                    nh += 1
                if nh + 1 < w:
                    hi = nh
                break
        if (lo, hi) == (lo0, hi0):
            return lo, hi


def isolate(out):
    """A row with no other line within NEAR_ROWS rows is a speck, not the line."""
    h = len(out)
    ok = out["reject"] == 0
    reject = out["reject"].copy()
    near = np.zeros(h, dtype=bool)
    for k in range(1, NEAR_ROWS + 1):
        near[k:] |= ok[:-k]
        near[:-k] |= ok[k:]
    reject = np.where(ok & ~near, 5, reject)
    out["reject"] = reject
    gone = reject != 0
    out["col"][gone] = np.nan
    out["width"][gone] = 0
    out["quality"][gone] = 0
    return out


if __name__ == "__main__":
    sys.exit(run_detector(cog))
