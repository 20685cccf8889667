#!/usr/bin/env python3
"""Read a STEP or IGES solid back with OpenCASCADE (OCP) and print what it is as one JSON line.

usage: occt_solid.py FILE.step|FILE.igs

JSON: the OCCT version, whether the file read, BRepCheck_Analyzer validity, counts of solids,
shells, faces and edges, the edges bounded by other than exactly two faces (0 for a closed
shell), whether every shell is closed (BRep_Tool.IsClosed), the volume (BRepGProp) and the
bounding box. Exit 0 when it read, is valid, has one solid and one closed shell.

Test-time only: tests/model_cad.rs runs it in the venv scripts/setup.sh makes
(target/venv-occt).
"""

import json
import os
import sys
from importlib import metadata

from OCP.Bnd import Bnd_Box
from OCP.BRep import BRep_Tool
from OCP.BRepBndLib import BRepBndLib
from OCP.BRepCheck import BRepCheck_Analyzer
from OCP.BRepGProp import BRepGProp
from OCP.GProp import GProp_GProps
from OCP.IFSelect import IFSelect_RetDone
from OCP.IGESControl import IGESControl_Reader
from OCP.STEPControl import STEPControl_Reader
from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE, TopAbs_SHELL, TopAbs_SOLID
from OCP.TopExp import TopExp

try:  # OCCT 8 bindings name the map templates by their parameters
    from OCP.collections import IndexedDataMap_TopoDS_Shape_List_TopoDS_Shape_TopTools_ShapeMapHasher as ShapeAncestors
    from OCP.collections import IndexedMap_TopoDS_Shape_TopTools_ShapeMapHasher as ShapeMap
except ImportError:  # OCCT 7 bindings
    from OCP.TopTools import TopTools_IndexedDataMapOfShapeListOfShape as ShapeAncestors
    from OCP.TopTools import TopTools_IndexedMapOfShape as ShapeMap


def explore(shape, kind):
    m = ShapeMap()
    TopExp.MapShapes_s(shape, kind, m)
    return [m.FindKey(i) for i in range(1, m.Extent() + 1)]


def read(path, out):
    is_step = path.lower().endswith((".step", ".stp"))
    reader = STEPControl_Reader() if is_step else IGESControl_Reader()
    out["format"] = "STEP" if is_step else "IGES"
    if reader.ReadFile(path) != IFSelect_RetDone:
        out["read"] = False
        return 1
    out["read"] = True
    reader.TransferRoots()
    shape = reader.OneShape()
    out["valid"] = bool(BRepCheck_Analyzer(shape).IsValid())
    solids, shells = explore(shape, TopAbs_SOLID), explore(shape, TopAbs_SHELL)
    faces, edges = explore(shape, TopAbs_FACE), explore(shape, TopAbs_EDGE)
    owners = ShapeAncestors()
    TopExp.MapShapesAndAncestors_s(shape, TopAbs_EDGE, TopAbs_FACE, owners)
    not_two = sum(1 for i in range(1, owners.Extent() + 1) if owners.FindFromIndex(i).Size() != 2)
    out.update(
        solids=len(solids), shells=len(shells), faces=len(faces), edges=len(edges),
        edges_not_in_two_faces=not_two,
        shells_closed=all(BRep_Tool.IsClosed_s(s) for s in shells),
    )
    props = GProp_GProps()
    BRepGProp.VolumeProperties_s(shape, props)
    out["volume"] = props.Mass()
    box = Bnd_Box()
    BRepBndLib.Add_s(shape, box)
    lo, hi = box.CornerMin(), box.CornerMax()
    out["box"] = [[lo.X(), lo.Y(), lo.Z()], [hi.X(), hi.Y(), hi.Z()]]
    ok = out["valid"] and len(solids) == 1 and len(shells) == 1 and out["shells_closed"] and not_two == 0
    return 0 if ok else 1


def main(argv):
    if len(argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    out = {"file": argv[1], "occt": metadata.version("cadquery-ocp-novtk")}
    # OCCT's messenger writes progress to stdout; keep stdout for the JSON alone.
    json_out = os.fdopen(os.dup(1), "w")
    os.dup2(2, 1)
    try:
        code = read(argv[1], out)
    finally:
        sys.stdout.flush()
    json_out.write(json.dumps(out) + "\n")
    json_out.flush()
    return code


if __name__ == "__main__":
    sys.exit(main(sys.argv))
