"""A sink process stage: posts the scan summary as JSON to the HTTP endpoint the config gives
(a practice system's intake, say), and reports what the endpoint answered. Standard library
only (no numpy).

    [[pipeline.stages]]            # after sink.summary
    stage = "exec"
    place = "sink"
    command = ["python3", "examples/plugins/python/post_summary.py"]
    args = { url = "http://127.0.0.1:8080/scans", timeout_s = 5 }
    required = false               # an endpoint that is down does not fail the scan

What is posted: {"scan_dir", "status", "points", "frames", "dropped_frames", "x_range_mm",
"truth_rms_mm", "plugins"} (docs/plugins.md). A refused or failed post raises, so the host
fails the stage with the reason (or skips it when required = false).
"""

import json
import os
import sys
import urllib.request

from footscan_stage import run_sink


def post(summary, scan_dir, args):
    url = args["url"]
    if not str(url).startswith(("http://127.0.0.1", "http://localhost", "http://[::1]")):
        raise ValueError(f"url {url!r}: this example posts only to a local endpoint")
    body = {
        "scan_dir": os.path.basename(scan_dir or ""),
        "status": summary.get("status"),
        "points": summary.get("points"),
        "frames": summary.get("frames"),
        "dropped_frames": summary.get("dropped_frames"),
        "x_range_mm": summary.get("x_range_mm"),
        "truth_rms_mm": (summary.get("truth") or {}).get("rms_mm"),
        "plugins": summary.get("plugins", []),
    }
    data = json.dumps(body).encode()
    req = urllib.request.Request(
        url, data=data, method="POST", headers={"Content-Type": "application/json"}
    )
    with urllib.request.urlopen(req, timeout=float(args.get("timeout_s", 5))) as r:
        answer = r.read(200).decode(errors="replace")
        return f"posted {len(data)} bytes to {url}: HTTP {r.status} {answer}\n"


if __name__ == "__main__":
    sys.exit(run_sink(post))
