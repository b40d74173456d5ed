#!/usr/bin/env python3
"""A part program made of one part N times over, for the streaming measurements of a long program.

Takes a G-code program, drops its closing words (M5, M2, M30, '%', ';' and blank lines at its end),
writes its body N times, and closes once with M5 M2. LinuxCNC's g5-butterfly-xy.ngc (F300 mm/min)
1,270 times over is 600.7 m in 31,751 paths, every one shorter than a window: a program of 30
hours' machining.

    python3 tools/make-repeated.py planner-host/programs/linuxcnc/g5-butterfly-xy.ngc 1270 > rep1270.ngc
"""
import sys

if len(sys.argv) != 3 or not sys.argv[2].isdigit() or int(sys.argv[2]) < 1:
    sys.exit("usage: make-repeated.py PROGRAM.ngc N   (N >= 1)")
lines = open(sys.argv[1]).read().split("\n")
while lines and lines[-1].strip().upper() in ("", ";", "%", "M2", "M5", "M30"):
    lines.pop()
body = "\n".join(lines) + "\n"
sys.stdout.write(body * int(sys.argv[2]) + "M5\nM2\n")
