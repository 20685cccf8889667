#!/usr/bin/env python3
"""Read a 3MF file back with lib3mf (3MF Consortium's reference library) and print one JSON line.

usage: threemf_lib3mf.py FILE.3mf

JSON: the lib3mf version, the model's unit, the mesh objects and build items, and per object its
vertex and triangle counts, the volume (divergence theorem), the bounding box, the number of
edges not shared by exactly two triangles and whether every shared edge runs both ways (closed
and consistently oriented). Exit 0 when it read with one mesh object in millimetres.

Test-time only: tests/insole.rs runs it in the venv scripts/setup.sh makes (target/venv-3mf).
"""

import json
import sys
from collections import Counter

import lib3mf


def main(path):
    wrapper = lib3mf.get_wrapper()
    model = wrapper.CreateModel()
    reader = model.QueryReader("3mf")
    reader.ReadFromFile(path)
    out = {
        "file": path,
        "lib3mf": "%d.%d.%d" % wrapper.GetLibraryVersion()[:3],
        "unit": "millimeter" if model.GetUnit() == lib3mf.ModelUnit.MilliMeter else str(model.GetUnit()),
        "warnings": reader.GetWarningCount(),
        "objects": [],
    }
    items = model.GetBuildItems()
    n_items = 0
    while items.MoveNext():
        n_items += 1
    out["build_items"] = n_items
    it = model.GetMeshObjects()
    while it.MoveNext():
        obj = it.GetCurrentMeshObject()
        v = [(p.Coordinates[0], p.Coordinates[1], p.Coordinates[2]) for p in obj.GetVertices()]
        t = [tuple(tr.Indices) for tr in obj.GetTriangleIndices()]
        directed = Counter()
        for a, b, c in t:
            for e in ((a, b), (b, c), (c, a)):
                directed[e] += 1
        undirected = Counter()
        for (a, b), n in directed.items():
            undirected[(min(a, b), max(a, b))] += n
        open_edges = sum(1 for n in undirected.values() if n != 2)
        oriented = all(n == 1 for n in directed.values())
        vol = 0.0
        for a, b, c in t:
            (ax, ay, az), (bx, by, bz), (cx, cy, cz) = v[a], v[b], v[c]
            vol += ax * (by * cz - bz * cy) - ay * (bx * cz - bz * cx) + az * (bx * cy - by * cx)
        lo = [min(p[k] for p in v) for k in range(3)]
        hi = [max(p[k] for p in v) for k in range(3)]
        out["objects"].append({
            "vertices": len(v), "triangles": len(t), "volume": vol / 6.0,
            "edges_not_in_two": open_edges, "oriented": oriented, "bbox": [lo, hi],
        })
    print(json.dumps(out))
    ok = len(out["objects"]) == 1 and out["unit"] == "millimeter"
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
