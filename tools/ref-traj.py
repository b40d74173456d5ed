#!/usr/bin/env python3
"""Replay a feedsim CSV's arc length s(t) through an independent f64 evaluation
of the toolpath (shared/checks/nurbs.py): r(u(s)) for each tick.

    python3 tools/ref-traj.py SIM.csv CURVE.json OUT.csv

The output (t,x,y,z) checks the plan and the firmware's s(t) integration with
check_traj.py, apart from the firmware's own position evaluation: the
difference between check_traj on SIM.csv and on OUT.csv is what the firmware's
s -> position numerics add.
"""
import os
import sys

import numpy as np

here = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(here, "..", "..", "shared", "checks"))
from nurbs import Nurbs  # noqa: E402


def main():
    sim, curve, out = sys.argv[1:4]
    c = Nurbs.load(curve)
    data = np.genfromtxt(sim, delimiter=",", names=True)
    t, s = data["t"], data["s"]
    u = c.u_of_s(s)
    P = np.asarray(c.point(u)).reshape(-1, 3)
    with open(out, "w") as f:
        f.write("t,x,y,z\n")
        for ti, p in zip(t, P):
            f.write(f"{float(ti)!r},{float(p[0])!r},{float(p[1])!r},{float(p[2])!r}\n")


if __name__ == "__main__":
    main()
