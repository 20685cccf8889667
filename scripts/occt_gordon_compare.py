#!/usr/bin/env python3
"""Rebuild a join's Gordon surface with OpenCASCADE 8's GeomFill_Gordon on the same curve
network and compare it with ours.

usage: occt_gordon_compare.py network.json [grid]

network.json is written by footscan-last's join writer: the sections (periodic cubic
B-splines), the guides (open cubic B-splines), their common crossing parameters, and our
Gordon surface. The sections are handed to OCCT as periodic Geom_BSplineCurve, the guides as
open ones; OCCT makes the network compatible itself and builds its surface. Prints one JSON
line: OCCT build time, our build time, and the distance between the two surfaces: our
surface sampled on a grid x grid net, each point projected onto OCCT's surface.
"""
import json, sys, time
from OCP.gp import gp_Pnt
from OCP.Geom import Geom_BSplineCurve, Geom_BSplineSurface
from OCP.GeomAPI import GeomAPI_ProjectPointOnSurf
from OCP.GeomFill import GeomFill_Gordon
from OCP.collections import Array1_gp_Pnt as TColgp_Array1OfPnt
from OCP.collections import Array1_double as TColStd_Array1OfReal, Array1_int as TColStd_Array1OfInteger
from OCP.collections import Array1_Geom_Curve


def knots_mults(knots):
    ks, ms = [], []
    for k in knots:
        if ks and abs(k - ks[-1]) < 1e-12:
            ms[-1] += 1
        else:
            ks.append(k); ms.append(1)
    return ks, ms


def arr_real(v):
    a = TColStd_Array1OfReal(1, len(v))
    for i, x in enumerate(v): a.SetValue(i + 1, float(x))
    return a


def arr_int(v):
    a = TColStd_Array1OfInteger(1, len(v))
    for i, x in enumerate(v): a.SetValue(i + 1, int(x))
    return a


def curve(c):
    p, poles, knots = c["degree"], c["poles"], c["knots"]
    if c["periodic"]:
        n = len(poles) - p  # unique poles
        poles = poles[:n]
        # One period of knots: knots[p] .. knots[p + n], all multiplicity 1 for our data.
        ks, ms = knots_mults(knots[p:p + n + 1])
    else:
        ks, ms = knots_mults(knots)
    a = TColgp_Array1OfPnt(1, len(poles))
    for i, q in enumerate(poles): a.SetValue(i + 1, gp_Pnt(*q))
    return Geom_BSplineCurve(a, arr_real(ks), arr_int(ms), p, bool(c["periodic"]))


def ours(s):
    # Evaluate our surface directly (de Boor on each direction).
    import numpy as np
    P = np.array(s["poles"]).reshape(s["nu"], s["nv"], 3)
    def basis(knots, p, n, t):
        knots = np.array(knots)
        lo, hi = knots[p], knots[n]
        t = min(max(t, lo), hi)
        span = p
        while span < n - 1 and knots[span + 1] <= t: span += 1
        N = [1.0] + [0.0] * p; left = [0.0] * (p + 1); right = [0.0] * (p + 1)
        for j in range(1, p + 1):
            left[j] = t - knots[span + 1 - j]; right[j] = knots[span + j] - t; saved = 0.0
            for r in range(j):
                tmp = N[r] / (right[r + 1] + left[j - r]); N[r] = saved + right[r + 1] * tmp; saved = left[j - r] * tmp
            N[j] = saved
        return span, N
    def point(u, v):
        su, Nu = basis(s["knots_u"], s["degree_u"], s["nu"], u)
        sv, Nv = basis(s["knots_v"], s["degree_v"], s["nv"], v)
        acc = np.zeros(3)
        for a in range(s["degree_u"] + 1):
            for b in range(s["degree_v"] + 1):
                acc += Nu[a] * Nv[b] * P[su - s["degree_u"] + a, sv - s["degree_v"] + b]
        return acc
    return point


def main():
    net = json.load(open(sys.argv[1]))
    n = int(sys.argv[2]) if len(sys.argv) > 2 else 40
    profiles = [curve(c) for c in net["sections"]]
    guides = [curve(c) for c in net["guides"]]
    P = Array1_Geom_Curve(1, len(profiles)); G = Array1_Geom_Curve(1, len(guides))
    for i, c in enumerate(profiles): P.SetValue(i + 1, c)
    for i, c in enumerate(guides): G.SetValue(i + 1, c)
    t = time.perf_counter()
    g = GeomFill_Gordon(); g.Init(P, G, 1e-6); g.Perform()
    occt_ms = (time.perf_counter() - t) * 1e3
    out = {"occt_done": bool(g.IsDone()), "occt_ms": occt_ms, "ours_ms": net["build_ms"],
           "sections": len(profiles), "guides": len(guides), "profiles": "periodic"}
    if not g.IsDone():
        # Fall back to the form OCCT's own example uses: closed, non-periodic profiles (same
        # geometry, seam at u = 0) and the first guide repeated at the seam's other side.
        out["periodic_failed_ms"] = occt_ms
        for c in profiles: c.SetNotPeriodic()
        g0 = curve(net["guides"][0])
        P = Array1_Geom_Curve(1, len(profiles)); G = Array1_Geom_Curve(1, len(guides) + 1)
        for i, c in enumerate(profiles): P.SetValue(i + 1, c)
        for i, c in enumerate(guides + [g0]): G.SetValue(i + 1, c)
        t = time.perf_counter()
        g = GeomFill_Gordon(); g.Init(P, G, 1e-6); g.Perform()
        occt_ms = (time.perf_counter() - t) * 1e3
        out.update({"occt_done": bool(g.IsDone()), "occt_ms": occt_ms, "profiles": "closed, not periodic"})
    if g.IsDone():
        s = g.Surface()
        out["occt_poles"] = [s.NbUPoles(), s.NbVPoles()]; out["occt_degrees"] = [s.UDegree(), s.VDegree()]
        pt = ours(net["gordon"])
        dmax, at = 0.0, None
        for i in range(n):
            for j in range(n + 1):
                u, v = i / n, j / n
                q = pt(u, v)
                pr = GeomAPI_ProjectPointOnSurf(gp_Pnt(*map(float, q)), s)
                if pr.NbPoints() == 0: continue
                d = pr.LowerDistance()
                if d > dmax: dmax, at = d, [u, v]
        out["max_distance_mm"] = dmax; out["worst_at_uv"] = at
    print(json.dumps(out))


main()
