#!/usr/bin/env python3
"""Read an IGES or STEP file back with OpenCASCADE (OCP) and print what it found as JSON.

usage: occt_readback.py FILE.igs|FILE.step [--unit] [--whole-curves] [U,V ...] [U ...]

Each U,V pair is evaluated on every face's surface, each single U on every free edge's
curve (an edge that bounds no face). With --unit the parameters are fractions of each
entity's own parameter domain (0 = start, 1 = end) instead of absolute values. With
--whole-curves an IGES B-spline curve is read as one edge even where it has C0 knots
(OpenCASCADE's default, which a CAD user sees, cuts it there).

The JSON has: the OCCT version, whether the file read, BRepCheck_Analyzer validity, counts
of faces, edges, free edges and shells, and per face ("surfaces") and per free edge
("curves"), in the order the reader returns them: the OCCT geometry type, degrees, pole
counts, rational and periodic flags, the parameter domain of the B-spline itself, the
face's or edge's own parameter range, and the evaluated points.

Test-time only: crates/geom/tests/export_occt.rs runs it in the venv scripts/setup.sh makes.
"""

import sys

from OCP.BRep import BRep_Tool
from OCP.BRepAdaptor import BRepAdaptor_Curve
from OCP.BRepTools import BRepTools
from OCP.Geom import Geom_BSplineCurve, Geom_BSplineSurface, Geom_RectangularTrimmedSurface, Geom_TrimmedCurve
from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE, TopAbs_SHELL
from OCP.TopoDS import TopoDS

from occt_common import edge_faces, explore, load, print_json


def xyz(p):
    return [p.X(), p.Y(), p.Z()]


def surface_info(face, pairs, unit):
    surf = BRep_Tool.Surface_s(face)
    if isinstance(surf, Geom_RectangularTrimmedSurface):
        surf = surf.BasisSurface()
    info = {"type": surf.DynamicType().Name()}
    u0, u1, v0, v1 = surf.Bounds()
    info["domain_u"], info["domain_v"] = [u0, u1], [v0, v1]
    info["face_uv_bounds"] = list(BRepTools.UVBounds_s(face))
    info["edges"] = len(explore(face, TopAbs_EDGE))
    if isinstance(surf, Geom_BSplineSurface):
        info.update(
            degree_u=surf.UDegree(), degree_v=surf.VDegree(),
            poles_u=surf.NbUPoles(), poles_v=surf.NbVPoles(),
            rational=bool(surf.IsURational() or surf.IsVRational()),
            periodic_u=bool(surf.IsUPeriodic()), periodic_v=bool(surf.IsVPeriodic()),
            closed_u=bool(surf.IsUClosed()), closed_v=bool(surf.IsVClosed()),
        )
    pts = []
    for u, v in pairs:
        if unit:
            u, v = u0 + u * (u1 - u0), v0 + v * (v1 - v0)
        pts.append({"u": u, "v": v, "p": xyz(surf.Value(u, v))})
    info["points"] = pts
    return info


def curve_info(edge, params, unit):
    adaptor = BRepAdaptor_Curve(edge)
    curve = BRep_Tool.Curve_s(edge, 0.0, 0.0)
    info = {"edge_range": [adaptor.FirstParameter(), adaptor.LastParameter()]}
    if curve is None:
        info["type"] = "none"
        return info
    if isinstance(curve, Geom_TrimmedCurve):
        curve = curve.BasisCurve()
    info["type"] = curve.DynamicType().Name()
    t0, t1 = curve.FirstParameter(), curve.LastParameter()
    info["domain"] = [t0, t1]
    if isinstance(curve, Geom_BSplineCurve):
        info.update(
            degree=curve.Degree(), poles=curve.NbPoles(), rational=bool(curve.IsRational()),
            periodic=bool(curve.IsPeriodic()), closed=bool(curve.IsClosed()),
        )
    pts = []
    for u in params:
        if unit:
            u = t0 + u * (t1 - t0)
        pts.append({"u": u, "p": xyz(curve.Value(u))})
    info["points"] = pts
    return info


def main(argv):
    if len(argv) < 2:
        print(__doc__, file=sys.stderr)
        return 2
    path, rest = argv[1], argv[2:]
    unit = "--unit" in rest
    whole = "--whole-curves" in rest
    pairs, params = [], []
    for a in rest:
        if a in ("--unit", "--whole-curves"):
            continue
        xs = [float(x) for x in a.split(",")]
        (pairs if len(xs) == 2 else params).append(tuple(xs) if len(xs) == 2 else xs[0])
    return print_json(path, lambda out: read(path, pairs, params, unit, whole, out))


def read(path, pairs, params, unit, whole, out):
    shape = load(path, out, whole_curves=whole)
    if shape is None:
        return 1
    faces = explore(shape, TopAbs_FACE)
    edges = explore(shape, TopAbs_EDGE)
    owners = edge_faces(shape)
    free = [e for e in edges if owners.FindFromKey(e).Size() == 0]
    out.update(faces=len(faces), edges=len(edges), free_edges=len(free), shells=len(explore(shape, TopAbs_SHELL)))
    out["surfaces"] = [surface_info(TopoDS.Face(f), pairs, unit) for f in faces]
    out["curves"] = [curve_info(TopoDS.Edge(e), params, unit) for e in free]
    return 0 if out["valid"] else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv))
