#!/usr/bin/env python3
"""Worst-case Thumb instructions per servo tick, by tick kind, under QEMU.

Two subcommands (`.ci/wcet.sh` drives both):

* `profiles TABLE --feedplan BIN --count K --chains C -o FILE`: computes
  override profiles with `feedplan override` for C chains of about K
  override points each, spread evenly along the path (chain c offset by
  c/C of the spacing), the levels cycling 50, 125, 30, 100 %; each profile
  starts after the previous one of its chain has merged. Writes the
  firmware's `MCU_OVERRIDES` file (format in `src/sweep.rs`).
* `measure NAME=ELF ... [--budget 4000] [--enforce]`: runs each image
  (built with `MCU_HOLDS` and/or `MCU_OVERRIDES`) under QEMU with the
  counting plugin (`bench_insn.py`), assigns every window its kind, pass,
  tick index and arc length from the `BENCH-PASS`, `BENCH-GROUP` and
  `BENCH-S` lines, and prints one JSON line: per kind the worst and mean
  count over all images and where the worst happened, per image the same,
  the calls that start a hold, a resume or an override, and the kinds over
  the budget. Exit 0, or 1 with `--enforce` when a kind is over the budget,
  2 on a measurement error. Each worst tick's `window` is its index among
  the image's windows, for `profile`.
* `profile ELF --window K [--top N]`: runs the image once more and prints
  window K's instructions by function (the block's function, inlined code
  counted where it was inlined): where a worst tick spends them.
"""
import argparse
import json
import os
import shutil
import struct
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import bench_insn  # noqa: E402

TICK_KINDS = ["normal", "start", "stop", "splice", "hold", "held", "resume"]
CALL_KINDS = ["hold-call", "resume-call", "offer-call"]
HOLD_KINDS = {"hold", "held", "resume", "resume-call"}
LEVEL_CYCLE = [50, 125, 30, 100]


def cmd_profiles(a):
    plan = json.loads(subprocess.run([a.feedplan, "plan", a.curve, "--override-levels", a.levels,
                                      "-o", a.table, "--json"], check=True, capture_output=True,
                                     text=True).stdout)
    length = plan["path_length_mm"]
    out = bytearray(b"OVR1") + struct.pack("<I", 0)
    n, seq, refused = 0, 0, 0
    tmp = tempfile.mkdtemp(prefix="wcet-prof-")
    try:
        for c in range(a.chains):
            spacing = length / a.count
            at, merged, frm, k = (0.5 + c / a.chains) * spacing, 0.0, 100, 0
            while at < length:
                at = max(at, merged + 1.0)
                to = LEVEL_CYCLE[k % len(LEVEL_CYCLE)]
                k += 1
                js = os.path.join(tmp, "p.json")
                r = subprocess.run([a.feedplan, "override", a.table, "--at", f"{at:.6f}", "--to", str(to),
                                    "--from", str(frm), "-o", js], capture_output=True, text=True)
                if r.returncode == 0:
                    p = json.load(open(js))
                    if len(p["ctrl"]) > a.window:
                        refused += 1
                    else:
                        seq += 1
                        out += struct.pack("<IIHHId", c, seq, p["level"], len(p["ctrl"]), p["first"], at)
                        out += struct.pack(f"<{len(p['ctrl'])}d", *p["ctrl"])
                        n += 1
                        merged, frm = p["merge_s_mm"], to
                else:
                    refused += 1
                at += spacing
    finally:
        shutil.rmtree(tmp)
    out[4:8] = struct.pack("<I", n)
    with open(a.output, "wb") as f:
        f.write(out)
    print(f"wcet: {n} override profiles in {a.chains} chains ({refused} override points without one), "
          f"L = {length:.3f} mm", file=sys.stderr)
    return 0


def measure(name, elf, a):
    nm = shutil.which("arm-none-eabi-nm") or "nm"
    begin = bench_insn.symbol_addr(elf, nm, "firmware_mcu::mark_begin")
    end = bench_insn.symbol_addr(elf, nm, "firmware_mcu::mark_end")
    ns = argparse.Namespace(cc=a.cc, qemu=a.qemu, elf=elf, profile=0, timeout=a.timeout)
    tmp = tempfile.mkdtemp(prefix="wcet-")
    try:
        p, result = bench_insn.run_plugin(ns, begin, end, tmp)
    finally:
        shutil.rmtree(tmp)
    if p is None:
        sys.exit(f"wcet: {name}: QEMU timed out after {a.timeout} s")
    if p.returncode != 0:
        sys.stderr.write(p.stdout[-4000:] + p.stderr)
        sys.exit(f"wcet: {name}: firmware exited {p.returncode}")
    w = result["windows"]
    kinds = {}
    info = {"holds": 0, "passes": 0, "profiles_accepted": 0, "profiles_refused": 0}
    i, base, pas, hold_at, group = 0, None, "", None, None
    for line in p.stdout.splitlines():
        if line.startswith("BENCH-PASS "):
            pas = line[len("BENCH-PASS "):]
            info["passes"] += pas.startswith("holds")
        elif line.startswith("BENCH-GROUP "):
            _, label, n = line.split()
            group = (label, int(n), i)
            i += int(n)
            if base is None:
                base = min(w[group[2]:i])  # the marker overhead (all equal)
            elif label not in TICK_KINDS and label not in CALL_KINDS:
                group = None  # the plain run's `tick` windows: not classified
        elif line.startswith("BENCH-S ") and group is not None:
            label, n, at = group
            f = line.split()
            first, ss = int(f[1]), f[2:]
            if len(ss) != n:
                sys.exit(f"wcet: {name}: group {label} of {n} windows with {len(ss)} arc lengths")
            k = kinds.setdefault(label, {"max": -1, "sum": 0, "n": 0, "where": "", "window": -1})
            for j in range(n):
                v = w[at + j] - base
                s_mm = int(ss[j]) / 1000
                if label == "hold-call":
                    hold_at = s_mm
                    info["holds"] += 1
                k["sum"] += v
                k["n"] += 1
                if v > k["max"]:
                    k["max"], k["window"] = v, at + j
                    where = f"{pas}, tick {first + j}, s = {s_mm:.3f} mm"
                    if label in HOLD_KINDS and hold_at is not None:
                        where += f" (hold pressed at {hold_at:.3f} mm)"
                    k["where"] = where
            group = None
        elif line.startswith("sweep: chain "):
            f = line.replace(",", "").split()
            info["profiles_accepted"] += int(f[5])
            info["profiles_refused"] += int(f[7])
        elif line.startswith("sweep: ") and "hold points" in line:
            info["holds_not_reached"] = int(line.split(",")[1].split()[0])
    if i != len(w) or result["errors"]:
        sys.exit(f"wcet: {name}: {len(w)} windows, {i} announced, errors {result['errors'][:3]}")
    out = {}
    for label, k in kinds.items():
        out[label] = {"max": k["max"], "mean": round(k["sum"] / k["n"], 1), "n": k["n"], "where": k["where"],
                      "window": k["window"]}
    return out, info


def cmd_measure(a):
    per, infos = {}, {}
    for spec in a.images:
        name, elf = spec.split("=", 1)
        per[name], infos[name] = measure(name, elf, a)
    kinds, calls = {}, {}
    for name, ks in per.items():
        for label, k in ks.items():
            dst = kinds if label in TICK_KINDS else calls
            cur = dst.get(label)
            if cur is None:
                dst[label] = cur = {"max": -1, "mean": 0.0, "n": 0, "curve": "", "where": ""}
            tot = cur["mean"] * cur["n"] + k["mean"] * k["n"]
            cur["n"] += k["n"]
            cur["mean"] = round(tot / cur["n"], 1)
            if k["max"] > cur["max"]:
                cur.update(max=k["max"], curve=name, where=k["where"], window=k["window"])
    order = lambda d, keys: {x: d[x] for x in keys if x in d}
    kinds = order(kinds, TICK_KINDS)
    over = [x for x, k in kinds.items() if k["max"] > a.budget]
    doc = {
        "schema_version": 1,
        "kinds": kinds,
        "budget": a.budget,
        "over_budget": over,
        "not_measured": [x for x in TICK_KINDS if x not in kinds],
        "calls": order(calls, CALL_KINDS),
        "curves": {n: {"kinds": order(k, TICK_KINDS), "calls": order(k, CALL_KINDS), "sweep": infos[n]}
                   for n, k in per.items()},
    }
    print(json.dumps(doc, separators=(",", ":")))
    return 1 if a.enforce and over else 0


def cmd_profile(a):
    nm = shutil.which("arm-none-eabi-nm") or "nm"
    begin = bench_insn.symbol_addr(a.elf, nm, "firmware_mcu::mark_begin")
    end = bench_insn.symbol_addr(a.elf, nm, "firmware_mcu::mark_end")
    ns = argparse.Namespace(cc=a.cc, qemu=a.qemu, elf=a.elf, profile=a.top, window=a.window, timeout=a.timeout)
    tmp = tempfile.mkdtemp(prefix="wcet-")
    try:
        p, result = bench_insn.run_plugin(ns, begin, end, tmp)
    finally:
        shutil.rmtree(tmp)
    if p is None or p.returncode != 0:
        sys.exit(f"wcet: {a.elf}: QEMU timed out or the firmware failed")
    if not 0 <= a.window < len(result["windows"]):
        sys.exit(f"wcet: window {a.window} of {len(result['windows'])}")
    print(f"window {a.window}: {result['windows'][a.window]} instructions (the marker overhead included)")
    bench_insn.print_profile(a.elf, nm, result["prof"], a.top)
    return 0


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    pr = sub.add_parser("profiles", help="plan a table with override levels and make override profiles")
    pr.add_argument("curve")
    pr.add_argument("--table", required=True, help="the table to write (planned with the levels)")
    pr.add_argument("--levels", default="30,50,125")
    pr.add_argument("--feedplan", required=True)
    pr.add_argument("--count", type=int, default=8, help="override points per chain")
    pr.add_argument("--chains", type=int, default=1)
    pr.add_argument("--window", type=int, default=64, help="most control points a profile may have")
    pr.add_argument("-o", "--output", required=True)
    me = sub.add_parser("measure", help="run images under QEMU and print the JSON line")
    me.add_argument("images", nargs="+", metavar="NAME=ELF")
    me.add_argument("--budget", type=int, default=4000)
    me.add_argument("--enforce", action="store_true", help="exit 1 when a tick kind is over the budget")
    me.add_argument("--cc", default=os.environ.get("CC", "cc"))
    me.add_argument("--qemu", default="qemu-system-arm")
    me.add_argument("--timeout", type=float, default=7200)
    pf = sub.add_parser("profile", help="one window's instructions by function (a worst tick's `window`)")
    pf.add_argument("elf")
    pf.add_argument("--window", type=int, required=True)
    pf.add_argument("--top", type=int, default=25, help="functions listed")
    pf.add_argument("--cc", default=os.environ.get("CC", "cc"))
    pf.add_argument("--qemu", default="qemu-system-arm")
    pf.add_argument("--timeout", type=float, default=7200)
    a = ap.parse_args()
    return {"profiles": cmd_profiles, "measure": cmd_measure, "profile": cmd_profile}[a.cmd](a)


if __name__ == "__main__":
    sys.exit(main())
