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

import sys

from OCP.Bnd import Bnd_Box
from OCP.BRep import BRep_Tool
from OCP.BRepBndLib import BRepBndLib
from OCP.BRepGProp import BRepGProp
from OCP.GProp import GProp_GProps
from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE, TopAbs_SHELL, TopAbs_SOLID

from occt_common import edge_faces, explore, load, print_json


def read(path, out):
    shape = load(path, out)
    if shape is None:
        return 1
    solids, shells = explore(shape, TopAbs_SOLID), explore(shape, TopAbs_SHELL)
    faces, edges = explore(shape, TopAbs_FACE), explore(shape, TopAbs_EDGE)
    owners = edge_faces(shape)
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
    return print_json(argv[1], lambda out: read(argv[1], out))


if __name__ == "__main__":
    sys.exit(main(sys.argv))
