#!/usr/bin/env python3
"""Compare feedplan's G-code reader with LinuxCNC's own interpreter, rs274.

Usage: python3 tools/rs274-compare.py [--feedplan PATH] [--rs274 PATH] [-v] PROGRAM.ngc ...

For each program, runs `rs274 -g PROGRAM < /dev/null` (LinuxCNC's stand-alone
interpreter, Debian package linuxcnc-uspace: it prints one canonical call per
line, numbers with 4 decimals in the program's units) and `feedplan parse
PROGRAM --json`, and compares the moves one by one:

- the same kinds and count (STRAIGHT_TRAVERSE = rapid, STRAIGHT_FEED = line,
  ARC_FEED = arc, NURBS_FEED / NURBS_G5_FEED / NURBS_G6_FEED = nurbs);
- end points and arc centres within 1e-4 mm (1e-4 in the program's units for
  mm programs; for inch programs the tolerance is rs274's print resolution,
  half of 0.0001 in = 1.27e-3 mm);
- the arc's turn count (rotation) and axis end point;
- the feed in force at each feed move (SET_FEED_RATE, in the units in force
  when it was set), to the same print resolution;
- for a NURBS, rs274's count of control entries (G5.2: the control points,
  the current point included; G6.2: control points + order, the knot-only
  lines included).

When both refuse a program, they must refuse the same line (rs274 prints its
text, feedplan its number). When only rs274 refuses, the moves it printed before the refusal are
still compared. A refusal that is a known limit of an older rs274 (G6.2 and
G5.2 outside G17 arrived in LinuxCNC in 2023, after the 2.9.0~pre1 of Debian
12) is reported as such and does not fail; any other refusal of a program
feedplan reads fails. Exits 0 when every program agrees, 1 on a mismatch
(printed with the program, move index and source line), 2 when a tool is
missing.

Standard library only.
"""
import argparse
import json
import math
import os
import re
import shutil
import subprocess
import sys

MM_PER_INCH = 25.4
TOL_MM = 1e-4
PRINT_HALF_UNIT = 0.5e-4

# rs274 messages that only mean "this rs274 is older than the feature"
OLD_RS274 = {
    "Unknown g code used": "G6.2 is newer than this rs274",
    "You must specify both X and Y coordinates for Control Points":
        "G5.2 outside the XY plane is newer than this rs274",
}

CALL = re.compile(r"^\s*\d+\s+N\S*\s+(?:saicanon\s+)?(\w+)\((.*)\)\s*$")


def nums(args):
    out = []
    for a in args.split(","):
        a = a.strip()
        try:
            out.append(float(a))
        except ValueError:
            pass
    return out


def run_rs274(rs274, path):
    """The canonical moves rs274 prints, and its refusal message (or None)."""
    p = subprocess.run([rs274, "-g", path], stdin=subprocess.DEVNULL,
                       capture_output=True, text=True, timeout=120)
    moves = []
    scale = 1.0  # mm per program unit
    plane = "XY"
    feed = 0.0   # mm/min
    for line in p.stdout.splitlines():
        m = CALL.match(line)
        if not m:
            continue
        name, args = m.group(1), m.group(2)
        if name == "USE_LENGTH_UNITS":
            scale = MM_PER_INCH if "INCHES" in args else 1.0
        elif name == "SELECT_PLANE":
            plane = args.replace("CANON_PLANE_", "").strip()
        elif name == "SET_FEED_RATE":
            feed = nums(args)[0] * scale
        elif name in ("STRAIGHT_TRAVERSE", "STRAIGHT_FEED"):
            v = nums(args)
            moves.append({"kind": "rapid" if name == "STRAIGHT_TRAVERSE" else "line",
                          "end": [x * scale for x in v[:3]], "feed": feed, "scale": scale})
        elif name == "ARC_FEED":
            fe, se, c1, c2, rot, ax = nums(args)[:6]
            if plane == "XY":
                end, center = [fe, se, ax], [c1, c2, None]
            elif plane == "YZ":
                end, center = [ax, fe, se], [None, c1, c2]
            else:  # XZ: first axis Z, second X
                end, center = [se, ax, fe], [c2, None, c1]
            moves.append({"kind": "arc", "end": [x * scale for x in end],
                          "center": [None if x is None else x * scale for x in center],
                          "turns": int(rot), "feed": feed, "scale": scale})
        elif name.startswith("NURBS"):
            moves.append({"kind": "nurbs", "count": int(nums(args)[0]) if nums(args) else None,
                          "feed": feed, "scale": scale})
    refusal, refused_text = None, None
    if p.returncode != 0:
        err = [l for l in p.stderr.splitlines() if l.strip() and l.strip() != "executing"]
        refusal = err[0] if err else f"exit status {p.returncode}"
        refused_text = err[1].strip() if len(err) > 1 else None
    return moves, refusal, refused_text


def run_feedplan(feedplan, path):
    p = subprocess.run([feedplan, "parse", path, "--json"], capture_output=True, text=True,
                       timeout=120)
    if p.returncode != 0:
        return None, p.stderr.strip()
    return json.loads(p.stdout), None


KINDS = {"rapid": 0, "line": 0, "arc": 0, "nurbs": 0}


def compare(path, feedplan, rs274, verbose):
    """(ok, moves compared, worst end/centre difference mm in mm and in inch output,
    worst feed difference mm/min, notes)"""
    theirs, refusal, refused_text = run_rs274(rs274, path)
    ours, our_err = run_feedplan(feedplan, path)
    notes = []
    if ours is None:
        if refusal is not None:
            # the same line? rs274 prints the refused line's text, feedplan its number
            m = re.search(r"LINE (\d+):", our_err)
            with open(path, encoding="utf-8", errors="replace") as f:
                lines = f.read().split("\n")
            ours_text = lines[int(m.group(1)) - 1].strip() if m and int(m.group(1)) <= len(lines) else None
            same = refused_text is None or ours_text == refused_text
            note = f"both refuse{' the same line' if same else ''} (rs274: {refusal}; {our_err})"
            if not same:
                note += f"; rs274 refuses '{refused_text}', feedplan '{ours_text}'"
            return same, 0, [0.0, 0.0], 0.0, [note]
        return False, 0, [0.0, 0.0], 0.0, [f"feedplan refuses a program rs274 reads: {our_err}"]
    mine = ours["moves"]
    worst, worst_feed = [0.0, 0.0], 0.0  # mm output, inch output
    ok = True
    n = min(len(mine), len(theirs))
    if refusal is None and len(mine) != len(theirs):
        ok = False
        notes.append(f"{len(mine)} moves here, {len(theirs)} from rs274")
    if refusal is not None and len(theirs) > len(mine):
        ok = False
        notes.append(f"rs274 printed {len(theirs)} moves before refusing, feedplan has {len(mine)}")
    for i in range(n):
        a, b = mine[i], theirs[i]
        KINDS[b["kind"]] = KINDS.get(b["kind"], 0) + 1
        where = f"move {i} (line {a['line']})"
        if a["kind"] != b["kind"]:
            ok = False
            notes.append(f"{where}: {a['kind']} here, {b['kind']} from rs274")
            break
        tol = max(TOL_MM, PRINT_HALF_UNIT * b["scale"] * (1 + 1e-9) + 1e-12)
        pairs = []
        if b["kind"] != "nurbs":
            pairs += [("end " + "XYZ"[k], a["end"][k], b["end"][k]) for k in range(3)]
        if b["kind"] == "arc":
            pairs += [("centre " + "XYZ"[k], a["arc"]["center"][k], b["center"][k])
                      for k in range(3) if b["center"][k] is not None]
            if a["arc"]["turns"] != b["turns"]:
                ok = False
                notes.append(f"{where}: turns {a['arc']['turns']} here, {b['turns']} from rs274")
        if b["kind"] == "nurbs":
            nb = a["nurbs"]
            want = len(nb["knots"]) if nb["form"] == "G6.2" else len(nb["control_points"])
            if b["count"] is not None and b["count"] != want:
                ok = False
                notes.append(f"{where}: {want} NURBS entries here, {b['count']} from rs274")
        for what, x, y in pairs:
            d = abs(x - y)
            inch = int(b["scale"] != 1.0)
            worst[inch] = max(worst[inch], d)
            if d > tol:
                ok = False
                notes.append(f"{where}: {what} {x:.6f} here, {y:.6f} from rs274 (|d| = {d:.2e} mm)")
        if a["kind"] != "rapid":
            f_ours = a["feed_mm_s"] * 60.0
            d = abs(f_ours - b["feed"])
            worst_feed = max(worst_feed, d)
            if d > max(1e-6 * f_ours, PRINT_HALF_UNIT * b["scale"] * 1.000001):
                ok = False
                notes.append(f"{where}: feed {f_ours:.4f} mm/min here, {b['feed']:.4f} from rs274")
        if verbose and not ok:
            break
    if refusal is not None:
        known = next((why for msg, why in OLD_RS274.items() if refusal.startswith(msg)), None)
        if known is None:
            ok = False
            notes.append(f"rs274 refuses the program: {refusal}")
        else:
            notes.append(f"rs274 stops after {len(theirs)} moves: '{refusal}' ({known}); "
                         f"that prefix compared, {len(mine) - len(theirs)} moves not compared")
    return ok, n, worst, worst_feed, notes


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("programs", nargs="+")
    ap.add_argument("--feedplan", default=None, help="feedplan binary (default: target/debug, then PATH)")
    ap.add_argument("--rs274", default=None, help="rs274 binary (default: PATH, /usr/bin)")
    ap.add_argument("-v", "--verbose", action="store_true")
    args = ap.parse_args()
    here = os.path.dirname(os.path.abspath(__file__))
    root = os.path.dirname(here)
    feedplan = args.feedplan
    if feedplan is None:
        for cand in (os.path.join(root, "target", "debug", "feedplan"),
                     os.path.join(root, "target", "release", "feedplan")):
            if os.path.exists(cand):
                feedplan = cand
                break
        feedplan = feedplan or shutil.which("feedplan")
    rs274 = args.rs274 or shutil.which("rs274") or next(
        (p for p in ("/usr/bin/rs274", "/usr/lib/linuxcnc/rs274") if os.path.exists(p)), None)
    if not feedplan or not rs274:
        print(f"rs274-compare: missing tool (feedplan: {feedplan}, rs274: {rs274})", file=sys.stderr)
        return 2
    total_moves, worst, worst_feed, bad, partial, both_refuse = 0, [0.0, 0.0], 0.0, 0, 0, 0
    for path in args.programs:
        ok, n, w, wf, notes = compare(path, feedplan, rs274, args.verbose)
        total_moves += n
        worst = [max(worst[0], w[0]), max(worst[1], w[1])]
        worst_feed = max(worst_feed, wf)
        partial += any("stops after" in x for x in notes)
        both_refuse += ok and any(x.startswith("both refuse the same line") for x in notes)
        status = "ok" if ok else "MISMATCH"
        print(f"{status:8} {path}: {n} moves compared, largest end/centre difference "
              f"{max(w):.2e} mm, feed {wf:.2e} mm/min")
        for x in notes[:20]:
            print(f"         {x}")
        if len(notes) > 20:
            print(f"         … {len(notes) - 20} more")
        bad += not ok
    print(f"{len(args.programs)} programs ({both_refuse} refused by both on the same line, "
          f"{partial} compared only up to an older rs274's limit), "
          f"{total_moves} moves compared ({', '.join(f'{k} {v}' for k, v in KINDS.items())}); largest end/centre difference {worst[0]:.2e} mm where "
          f"rs274 prints mm, {worst[1]:.2e} mm where it prints inches (its 4 decimals: "
          f"{PRINT_HALF_UNIT * MM_PER_INCH:.2e} mm); largest feed difference {worst_feed:.2e} mm/min; "
          f"{bad} mismatching")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
