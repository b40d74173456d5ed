#!/usr/bin/env python3
"""Replay a feedsim CSV's arc length s(t) through an independent f64 evaluation
of the toolpath, the external checker's `nurbs.py`: r(u(s)) for each tick.

    python3 tools/ref-traj.py CHECKS_DIR SIM.csv CURVE.json OUT.csv

CHECKS_DIR is the folder of the external reference checker (`check_traj.py`,
`nurbs.py`); the project does not ship it.

The output (t,x,y,z) checks the plan and the firmware's s(t) integration with
check_traj.py, apart from the firmware's own position evaluation: the
difference between check_traj on SIM.csv and on OUT.csv is what the firmware's
s -> position numerics add.
"""
import os
import sys

import numpy as np

if len(sys.argv) != 5:
    sys.exit(__doc__)
sys.path.insert(0, os.path.abspath(sys.argv[1]))
from nurbs import Nurbs  # noqa: E402


def main():
    sim, curve, out = sys.argv[2:5]
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
