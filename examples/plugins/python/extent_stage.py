"""A per-scan process stage: the extent of the scan's point set, added to scan.json. The
same figures as examples/plugins/extent-wasm/extent.c, in numpy.

    [[pipeline.stages]]
    stage = "exec"
    place = "scan"
    command = ["target/venv-plugins/bin/python", "examples/plugins/python/extent_stage.py"]
"""

import sys

from footscan_stage import run_scan


def extent(pts, _args):
    out = {"points": len(pts)}
    if len(pts):
        x, y, z = pts[:, 0], pts[:, 1], pts[:, 2]
        out.update(
            x_min_mm=x.min(),
            x_max_mm=x.max(),
            length_mm=x.max() - x.min(),
            width_mm=y.max() - y.min(),
            z_max_mm=z.max(),
        )
    return out


if __name__ == "__main__":
    sys.exit(run_scan(extent))
