#!/usr/bin/env python3
"""Build OpenCASCADE 8's GeomFill_Gordon on a curve network we wrote and measure how far our
Gordon surface on the same network is from it.

usage: occt_gordon_compare.py network.json [n]

network.json (footscan-last's join::output::network_json_of): closed sections as periodic
cubic B-splines, open cubic guides, the crossing parameters (u_cross on the sections, v_cross
on the guides), our Gordon surface and our build time. The sections go to OCCT as periodic
Geom_BSplineCurve; if OCCT does not build on those, as the same curves made non-periodic
(closed, seam at u = 0) with the first guide repeated on the far side of the seam. OCCT finds
the crossings itself. Prints one JSON line: which form OCCT built, its build time and report,
our build time, and distances (mm):
  same_param_max / _rms: |ours(u, v) - occt(u, v)| on a 4n x (n + 1) grid, OCCT's domain
    mapped linearly onto ours: an upper bound of the distance from our surface to OCCT's
    (and zero only if both also agree on the parametrisation);
  by_cell: its largest value in each cell between consecutive guides;
  projected_max_25_points: 25 of our points projected onto OCCT's surface (a check of the
    bound; projection on OCCT's degree-9 surface is slow);
  network_to_occt_max: the input curves against OCCT's surface at their own parameters.
"""
import json
import sys
import time

import numpy as np
from OCP.Geom import Geom_BSplineCurve
from OCP.GeomAPI import GeomAPI_ProjectPointOnSurf
from OCP.GeomFill import GeomFill_Gordon
from OCP.gp import gp_Pnt
from OCP.collections import Array1_Geom_Curve
from OCP.collections import Array1_double, Array1_gp_Pnt, Array1_int


def knots_and_mults(knots, tol=1e-12):
    values, mults = [], []
    for k in knots:
        if values and abs(k - values[-1]) <= tol:
            mults[-1] += 1
        else:
            values.append(k)
            mults.append(1)
    return values, mults


def occt_curve(c, periodic):
    """Our curve as an OCCT B-spline. Periodic curves are stored with their first `degree`
    poles repeated and the full unclamped knot vector; OCCT wants the unique poles and one
    period of knots. Non-periodic form of a periodic curve: the same curve clamped at its
    domain ends by knot insertion in OCCT."""
    p = c["degree"]
    poles, knots = c["poles"], c["knots"]
    if c["periodic"]:
        n = len(poles) - p
        values, mults = knots_and_mults(knots[p:p + n + 1])
        poles = poles[:n]
    else:
        values, mults = knots_and_mults(knots)
    P = Array1_gp_Pnt(1, len(poles))
    for i, q in enumerate(poles):
        P.SetValue(i + 1, gp_Pnt(*map(float, q)))
    K = Array1_double(1, len(values))
    M = Array1_int(1, len(mults))
    for i, (k, m) in enumerate(zip(values, mults)):
        K.SetValue(i + 1, float(k))
        M.SetValue(i + 1, int(m))
    curve = Geom_BSplineCurve(P, K, M, p, bool(c["periodic"]))
    if c["periodic"] and not periodic:
        curve.SetNotPeriodic()
    return curve


def array_of(curves):
    a = Array1_Geom_Curve(1, len(curves))
    for i, c in enumerate(curves):
        a.SetValue(i + 1, c)
    return a


def build(profiles, guides, tol):
    g = GeomFill_Gordon()
    g.Init(array_of(profiles), array_of(guides), tol)
    t = time.perf_counter()
    g.Perform()
    ms = (time.perf_counter() - t) * 1e3
    return g, ms


def basis(knots, p, t):
    """Span index and the p + 1 non-zero basis values at t (Cox-de Boor)."""
    n = len(knots) - p - 1
    span = p
    while span < n - 1 and knots[span + 1] <= t:
        span += 1
    N = [1.0] + [0.0] * p
    left = [0.0] * (p + 1)
    right = [0.0] * (p + 1)
    for j in range(1, p + 1):
        left[j] = t - knots[span + 1 - j]
        right[j] = knots[span + j] - t
        saved = 0.0
        for r in range(j):
            tmp = N[r] / (right[r + 1] + left[j - r])
            N[r] = saved + right[r + 1] * tmp
            saved = left[j - r] * tmp
        N[j] = saved
    return span, N


def our_surface(s):
    """Evaluator of our (non-rational) surface from its JSON, independent of the Rust code."""
    P = np.array(s["poles"]).reshape(s["nu"], s["nv"], 3)
    pu, pv = s["degree_u"], s["degree_v"]
    ku, kv = s["knots_u"], s["knots_v"]
    u0, u1 = ku[pu], ku[s["nu"]]
    v0, v1 = kv[pv], kv[s["nv"]]

    def point(a, b):  # a, b in [0, 1] over the domain
        u = u0 + a * (u1 - u0)
        v = v0 + b * (v1 - v0)
        su, Nu = basis(ku, pu, min(u, u1 - 1e-15) if s["periodic_u"] else u)
        sv, Nv = basis(kv, pv, v)
        acc = np.zeros(3)
        for i in range(pu + 1):
            for j in range(pv + 1):
                acc += Nu[i] * Nv[j] * P[su - pu + i, sv - pv + j]
        return acc

    return point


def curve_points(c, n):
    p = c["degree"]
    P = np.array(c["poles"])
    k = c["knots"]
    lo, hi = k[p], k[len(P)]
    out = []
    for i in range(n + 1):
        t = lo + (hi - lo) * i / n
        if c["periodic"]:
            t = min(t, hi - 1e-15)
        span, N = basis(k, p, t)
        out.append(sum(N[r] * P[span - p + r] for r in range(p + 1)))
    return out


def main():
    net = json.load(open(sys.argv[1]))
    n = int(sys.argv[2]) if len(sys.argv) > 2 else 60
    tol = 1e-4
    out = {"sections": len(net["sections"]), "guides": len(net["guides"]),
           "ours_ms": net["build_ms"], "tolerance": tol, "attempts": []}
    # First as given: periodic sections.
    profiles = [occt_curve(c, True) for c in net["sections"]]
    guides = [occt_curve(c, False) for c in net["guides"]]
    g, ms = build(profiles, guides, tol)
    out["attempts"].append({"form": "periodic sections", "done": bool(g.IsDone()), "ms": ms,
                            "status": str(g.Status())})
    if not g.IsDone():
        profiles = [occt_curve(c, False) for c in net["sections"]]
        guides = guides + [occt_curve(net["guides"][0], False)]
        g, ms = build(profiles, guides, tol)
        out["attempts"].append({"form": "closed non-periodic sections, first guide repeated",
                                "done": bool(g.IsDone()), "ms": ms, "status": str(g.Status())})
    out["occt_done"] = bool(g.IsDone())
    out["occt_ms"] = ms
    if not g.IsDone():
        print(json.dumps(out))
        return
    s = g.Surface()
    out["occt_surface"] = {
        "poles": [s.NbUPoles(), s.NbVPoles()], "degrees": [s.UDegree(), s.VDegree()],
        "u_periodic": bool(s.IsUPeriodic()), "v_periodic": bool(s.IsVPeriodic()),
        "u_closed": bool(s.IsUClosed()),
        # The build report's structure has no Python binding; its flag has.
        "approximate": bool(g.IsApproximate()),
    }
    ours = our_surface(net["gordon"])
    # OCCT's u runs along its profiles (our sections), v across them, as ours.
    U0, U1, V0, V1 = s.Bounds()

    def project(q):
        pr = GeomAPI_ProjectPointOnSurf(gp_Pnt(*map(float, q)), s)
        return pr.LowerDistance() if pr.NbPoints() > 0 else float("nan")

    # Same-parameter distance on a dense grid: an upper bound of the distance from each of
    # our points to OCCT's surface, and cheap. Cells between consecutive guides are tracked
    # to show where any difference lives.
    u_cross = net["u_cross"]
    nu, nv = 4 * n, n
    cells = [0.0] * len(u_cross)
    d_all = []
    for i in range(nu):
        a = i / nu
        k = max(k for k in range(len(u_cross)) if u_cross[k] <= a) if a >= u_cross[0] else len(u_cross) - 1
        for jv in range(nv + 1):
            b = jv / nv
            q = ours(a, b)
            o = s.Value(U0 + a * (U1 - U0), V0 + b * (V1 - V0))
            d = float(np.linalg.norm(q - np.array([o.X(), o.Y(), o.Z()])))
            d_all.append(d)
            cells[k] = max(cells[k], d)
    d_all = np.array(d_all)
    out["same_param_max"] = float(d_all.max())
    out["same_param_rms"] = float(np.sqrt(np.mean(d_all ** 2)))
    out["same_param_grid"] = [nu, nv + 1]
    out["by_cell"] = cells
    # A few true projections (slow on OCCT's degree-9 surface) to confirm.
    proj = 0.0
    for i in range(5):
        for jv in range(5):
            proj = max(proj, project(ours((i + 0.37) / 5, (jv + 0.5) / 5)))
    out["projected_max_25_points"] = proj
    # The input curves against OCCT's surface at their own parameters.
    net_d = 0.0
    for k, c in enumerate(net["sections"]):
        for t, q in zip(np.linspace(0, 1, 201), curve_points(c, 200)):
            o = s.Value(U0 + min(t, 1 - 1e-15) * (U1 - U0), V0 + net["v_cross"][k] * (V1 - V0))
            net_d = max(net_d, float(np.linalg.norm(q - np.array([o.X(), o.Y(), o.Z()]))))
    for k, c in enumerate(net["guides"]):
        for t, q in zip(np.linspace(0, 1, 41), curve_points(c, 40)):
            o = s.Value(U0 + u_cross[k] * (U1 - U0), V0 + t * (V1 - V0))
            net_d = max(net_d, float(np.linalg.norm(q - np.array([o.X(), o.Y(), o.Z()]))))
    out["network_to_occt_max"] = net_d
    print(json.dumps(out))


main()
