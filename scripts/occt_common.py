"""Shared by the OpenCASCADE (OCP) read-back scripts occt_readback.py and occt_solid.py:
the map templates under both bindings' names, the distinct sub-shapes of one kind, reading a
STEP or IGES file into one shape, and printing the result as one JSON line on a stdout that
OCCT's messenger does not write into.

Test-time only, in the venv scripts/setup.sh makes (target/venv-occt).
"""

import json
import os
import sys
from importlib import metadata

from OCP.BRepCheck import BRepCheck_Analyzer
from OCP.IFSelect import IFSelect_RetDone
from OCP.IGESControl import IGESControl_Reader
from OCP.Interface import Interface_Static
from OCP.STEPControl import STEPControl_Reader
from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE
from OCP.TopExp import TopExp

try:  # OCCT 8 bindings name the map templates by their parameters
    from OCP.collections import IndexedDataMap_TopoDS_Shape_List_TopoDS_Shape_TopTools_ShapeMapHasher as ShapeAncestors
    from OCP.collections import IndexedMap_TopoDS_Shape_TopTools_ShapeMapHasher as ShapeMap
except ImportError:  # OCCT 7 bindings
    from OCP.TopTools import TopTools_IndexedDataMapOfShapeListOfShape as ShapeAncestors
    from OCP.TopTools import TopTools_IndexedMapOfShape as ShapeMap


def explore(shape, kind):
    """Distinct sub-shapes of one kind (a seam edge counts once), in the reader's order."""
    m = ShapeMap()
    TopExp.MapShapes_s(shape, kind, m)
    return [m.FindKey(i) for i in range(1, m.Extent() + 1)]


def edge_faces(shape):
    """Each edge's faces (FindFromKey(edge).Size() is how many faces it bounds)."""
    owners = ShapeAncestors()
    TopExp.MapShapesAndAncestors_s(shape, TopAbs_EDGE, TopAbs_FACE, owners)
    return owners


def load(path, out, whole_curves=False):
    """The file's shape, or None when it does not read. Records in `out`: format, read,
    roots, transferred, valid (BRepCheck_Analyzer). `whole_curves`: IGES B-spline curves
    are taken whole, as written; OpenCASCADE's default (read.iges.bspline.continuity = 1),
    which a CAD user gets, cuts them at every C0 knot into separate edges (a frame curve
    with knots of multiplicity 3 at the flat bottom's corners reads as four or five)."""
    is_step = path.lower().endswith((".step", ".stp"))
    reader = STEPControl_Reader() if is_step else IGESControl_Reader()
    out["format"] = "STEP" if is_step else "IGES"
    if not is_step and whole_curves:
        # Set after the reader exists: creating one resets the IGES statics.
        Interface_Static.SetIVal_s("read.iges.bspline.continuity", 0)
        out["iges_bspline_continuity"] = 0
    if reader.ReadFile(path) != IFSelect_RetDone:
        out["read"] = False
        return None
    out["read"] = True
    out["roots"] = reader.NbRootsForTransfer()
    out["transferred"] = reader.TransferRoots()
    shape = reader.OneShape()
    out["valid"] = bool(BRepCheck_Analyzer(shape).IsValid())
    return shape


def print_json(path, work):
    """Run work(out) with stdout sent to stderr (OCCT's messenger writes progress there),
    then print `out` as one JSON line on the real stdout; work's exit code."""
    out = {"file": path, "occt": metadata.version("cadquery-ocp-novtk")}
    json_out = os.fdopen(os.dup(1), "w")
    os.dup2(2, 1)
    try:
        code = work(out)
    finally:
        sys.stdout.flush()
    json_out.write(json.dumps(out) + "\n")
    json_out.flush()
    return code
