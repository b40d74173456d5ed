#!/usr/bin/env python3
"""The limits table of docs/benchmarks.md: plan, simulate and check every curve x sampling x density.

For each case it runs, from the repository root (release binaries must be built:
`cargo build --release -p planner-host -p sim-harness`):

    target/release/feedplan plan CURVE --sampling S --density P [EXTRA...] -o T.bin --json
    target/release/feedsim run T.bin --csv T.csv --json
    target/release/feedsim check T.csv --curve CURVE --pad-rest 50 --json

and prints one Markdown row: predicted and simulated machining time, the largest
ratio to each limit on the plan's dense re-evaluation (feedplan's `dense_check`),
the project's checker's verdict with --pad-rest 50 (the limits it fails, with their ratios),
and the planning time. Every figure is measured; nothing is copied.

    python3 tools/limits-table.py [--curves a.json butterfly ...] [--samplings par len ada]
                                  [--densities 0.5 1 2] [-- EXTRA feedplan args]
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CURVES = os.path.join(ROOT, "planner-host", "curves")
LIMITS = ["vel", "acc", "jerk", "feed", "tacc", "tjerk"]


def run(cmd):
    p = subprocess.run(cmd, capture_output=True, text=True)
    return p.returncode, p.stdout, p.stderr


def one(curve, sampling, density, extra, tmp):
    table = os.path.join(tmp, "t.bin")
    csv = os.path.join(tmp, "t.csv")
    name = os.path.splitext(os.path.basename(curve))[0]
    head = f"| {name} | {sampling.upper()} | {density:g} |"
    rc, out, err = run([os.path.join(ROOT, "target/release/feedplan"), "plan", curve, "--sampling", sampling,
                        "--density", str(density), "-o", table, "--json"] + extra)
    if rc != 0:
        msg = err.strip().splitlines()[-1] if err.strip() else f"exit {rc}"
        return head + f" no plan: {msg.replace('|', '/')} |" + " |" * 5
    plan = json.loads(out)
    dense = plan["dense_check"]["ratios"]
    rc, out, err = run([os.path.join(ROOT, "target/release/feedsim"), "run", table, "--csv", csv, "--json"])
    if rc != 0:
        msg = err.strip().splitlines()[-1] if err.strip() else f"exit {rc}"
        return head + f" {plan['predicted_time_s']:.4f} | sim error: {msg.replace('|', '/')} |" + " |" * 4
    sim = json.loads(out)
    rc, out, err = run([os.path.join(ROOT, "target/release/feedsim"), "check", csv, "--curve", curve,
                        "--pad-rest", "50", "--json"])
    if rc not in (0, 5):
        msg = err.strip().splitlines()[-1] if err.strip() else f"exit {rc}"
        verdict = f"check error: {msg.replace('|', '/')}"
    else:
        chk = json.loads(out)
        fails = chk["fail"]
        worst = max(chk["ratios"], key=lambda k: chk["ratios"][k]["ratio"])
        verdict = (f"pass, worst {worst} {chk['ratios'][worst]['ratio']:.4f}" if not fails else "fail: " + ", ".join(
            f"{k} {chk['ratios'][k]['ratio']:.4f}" if k in chk["ratios"] else k for k in fails))
    ratios = " / ".join(f"{dense[k]:.3f}" for k in LIMITS)
    return (head + f" {plan['predicted_time_s']:.4f} | {sim['machining_time_s']:.4f} | {ratios} | {verdict} |"
            f" {1e3 * plan['total_time_s']:.0f} |")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--curves", nargs="*", default=None)
    ap.add_argument("--samplings", nargs="*", default=["par", "len", "ada"])
    ap.add_argument("--densities", nargs="*", type=float, default=[0.5, 1.0, 2.0])
    ap.add_argument("extra", nargs="*", help="extra feedplan arguments (after --)")
    a = ap.parse_args()
    curves = a.curves or sorted(
        os.path.join(CURVES, f) for f in os.listdir(CURVES) if f.endswith(".json"))
    print("| curve | sampling | P /mm | T plan s | T sim s | dense ratios vel / acc / jerk / feed / tacc / tjerk"
          " | feedsim check --pad-rest 50 | plan ms |")
    print("|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for c in curves:
            for s in a.samplings:
                for d in a.densities:
                    print(one(c, s, d, a.extra, tmp), flush=True)


if __name__ == "__main__":
    main()
