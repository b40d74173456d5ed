#!/usr/bin/env python3
"""Count Thumb instructions executed in marked windows of an MCU image under QEMU.

A window is the instructions executed from an entry of
`firmware_mcu::mark_begin` up to (not including) the next entry of
`firmware_mcu::mark_end` (addresses found with `nm`). Two ways to count:

* `--method plugin` (default, fast: QEMU at near full speed): the TCG plugin
  tools/insn_window.c, compiled here with `cc` into target/tools/.
* `--method exec-log` (no C compiler, ~1000x slower, a cross-check): QEMU runs
  with one guest instruction per translation block (`-singlestep`) and logs
  every executed block (`-d exec,nochain`), so every log line is one executed
  instruction. The log goes through a FIFO (~120 bytes per instruction; nothing
  is written to disk) and is scanned in large chunks for the marker addresses.

The firmware prints `BENCH-GROUP <label> <n>` lines in execution order; the
windows are split into groups by them. The first group must be `empty`
(back-to-back markers): its median is the marker overhead, subtracted from
every other window. Nothing is hard-coded: all numbers come from the run.

Usage: bench_insn.py ELF [--method plugin|exec-log] [--csv FILE] [--timeout S]
       [--machine M] [--marks BEGIN,END] [--qemu-arg ARG]...
Exit code: the firmware's (semihosting) exit code, or 2 on a measurement error.
"""
import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import threading


def qemu_args(a):
    """QEMU's arguments before the plugin and the kernel: the machine
    (`a.machine`, default mps2-an386) and any extra `a.qemu_arg` (callers
    such as wcet.py pass a namespace without either)."""
    machine = getattr(a, "machine", "mps2-an386")
    return ["-cpu", "cortex-m4", "-machine", machine, "-nographic",
            "-semihosting-config", "enable=on,target=native", *getattr(a, "qemu_arg", [])]


def symbol_addr(elf, nm, name):
    out = subprocess.run([nm, "-C", elf], check=True, capture_output=True, text=True).stdout
    hits = [l.split()[0] for l in out.splitlines() if l.endswith(" " + name)]
    if len(hits) != 1:
        sys.exit(f"bench_insn: symbol {name!r}: {len(hits)} matches in {elf}")
    return int(hits[0], 16) & ~1  # clear the Thumb bit


def scan(fifo_path, begin, end, result):
    """Streams the exec log; appends window lengths to result['windows']."""
    # Exec-log line (QEMU 7.x): "Trace 0: 0xHOST [CSBASE/PC/FLAGS/CFLAGS] sym\n";
    # match "/PC/" right after the 8-digit cs_base field.
    pats = {b"/%08x/" % begin: "b", b"/%08x/" % end: "e"}
    windows = result["windows"]
    total = 0          # instructions (lines) seen so far
    open_at = None     # line index of the current window's begin, or None
    rest = b""
    with open(fifo_path, "rb", buffering=0) as f:
        while True:
            chunk = f.read(1 << 24)
            if not chunk:
                break
            buf = rest + chunk
            cut = buf.rfind(b"\n") + 1
            buf, rest = buf[:cut], buf[cut:]
            hits = []
            for pat, kind in pats.items():
                i = buf.find(pat)
                while i >= 0:
                    if i >= 9 and buf[i - 9] == 0x5B:  # '[' before the cs_base field
                        hits.append((i, kind))
                    i = buf.find(pat, i + 1)
            hits.sort()
            pos, line = 0, total
            for i, kind in hits:
                line += buf.count(b"\n", pos, i)
                pos = i
                if kind == "b":
                    if open_at is not None:
                        result["errors"].append(f"nested mark_begin at insn {line}")
                    open_at = line
                else:
                    if open_at is None:
                        result["errors"].append(f"mark_end without mark_begin at insn {line}")
                    else:
                        windows.append(line - open_at)
                        open_at = None
            total += buf.count(b"\n")
    result["total"] = total


def build_plugin(cc):
    here = os.path.dirname(os.path.abspath(__file__))
    src = os.path.join(here, "tools", "insn_window.c")
    so = os.path.join(here, "target", "tools", "insn_window.so")
    if not os.path.exists(so) or os.path.getmtime(so) < os.path.getmtime(src):
        os.makedirs(os.path.dirname(so), exist_ok=True)
        subprocess.run([cc, "-O2", "-shared", "-fPIC", "-fvisibility=hidden", "-Wall", "-Wextra",
                        "-o", so, src], check=True)
    return so


def run_plugin(a, begin, end, tmp):
    so = build_plugin(a.cc)
    out = os.path.join(tmp, "windows.txt")
    prof = os.path.join(tmp, "prof.txt")
    popt = f",prof={prof}" if a.profile else ""
    if a.profile and getattr(a, "window", None) is not None:
        popt += f",pwin={a.window}"
    cmd = [a.qemu, *qemu_args(a), "-plugin", f"{so},begin=0x{begin:x},end=0x{end:x},out={out}{popt}",
           "-kernel", a.elf]
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=a.timeout)
    except subprocess.TimeoutExpired:
        return None, None
    result = {"windows": [], "errors": [], "total": None}
    with open(out) as f:
        for line in f:
            if line.startswith("total "):
                result["total"] = int(line.split()[1])
            else:
                result["windows"].append(int(line))
    if result["total"] is None:
        result["errors"].append("plugin wrote no total line (atexit callback not run?)")
    if a.profile:
        with open(prof) as f:
            result["prof"] = [(int(x, 16), int(n), int(c)) for x, n, c in (l.split() for l in f)]
    return p, result


def print_profile(elf, nm, prof, top):
    """Attributes each block's instructions to the function containing its start."""
    import bisect
    out = subprocess.run([nm, "-C", "-n", "-S", elf], check=True, capture_output=True, text=True).stdout
    syms = []
    for l in out.splitlines():
        parts = l.split(None, 3)
        if len(parts) == 4 and parts[2].lower() == "t":
            syms.append((int(parts[0], 16) & ~1, int(parts[1], 16), parts[3]))
    syms.sort()
    starts = [s[0] for s in syms]
    per = {}
    for va, n, c in prof:
        k = bisect.bisect_right(starts, va) - 1
        name = syms[k][2] if k >= 0 and va < syms[k][0] + max(syms[k][1], 1) else f"?0x{va:x}"
        per[name] = per.get(name, 0) + n * c
    tot = sum(per.values())
    print(f"== profile: instructions inside windows by function (block starts), {tot} in all")
    for name, v in sorted(per.items(), key=lambda x: -x[1])[:top]:
        print(f"{v:14d} {100.0 * v / tot:6.2f}%  {name}")


def run_exec_log(a, begin, end, tmp):
    fifo = os.path.join(tmp, "exec.fifo")
    os.mkfifo(fifo)
    result = {"windows": [], "errors": [], "total": 0}
    t = threading.Thread(target=scan, args=(fifo, begin, end, result))
    t.start()
    cmd = [a.qemu, *qemu_args(a), "-singlestep", "-d", "exec,nochain", "-D", fifo, "-kernel", a.elf]
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=a.timeout)
    except subprocess.TimeoutExpired:
        # Unblock the reader if QEMU never opened the FIFO, then give up.
        with open(fifo, "wb"):
            pass
        t.join()
        return None, None
    t.join()
    return p, result


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("elf")
    ap.add_argument("--method", choices=["plugin", "exec-log"], default="plugin")
    ap.add_argument("--cc", default=os.environ.get("CC", "cc"))
    ap.add_argument("--profile", type=int, metavar="N", default=0,
                    help="plugin only: also print the N functions with the most instructions inside windows")
    ap.add_argument("--csv", help="write every window (group,index,insns) to this file")
    ap.add_argument("--timeout", type=float, default=3600)
    ap.add_argument("--qemu", default="qemu-system-arm")
    ap.add_argument("--nm", default=shutil.which("arm-none-eabi-nm") or "nm")
    ap.add_argument("--machine", default="mps2-an386",
                    help="QEMU machine (boards/stm32f4 under QEMU: netduinoplus2)")
    ap.add_argument("--qemu-arg", action="append", default=[],
                    help="one more QEMU argument (repeat for more), e.g. --qemu-arg=-icount --qemu-arg=shift=3,sleep=off")
    ap.add_argument("--marks", default="firmware_mcu::mark_begin,firmware_mcu::mark_end",
                    help="the window's begin and end functions (demangled names, comma-separated)")
    a = ap.parse_args()

    mark_begin, mark_end = a.marks.split(",")
    begin = symbol_addr(a.elf, a.nm, mark_begin)
    end = symbol_addr(a.elf, a.nm, mark_end)
    tmp = tempfile.mkdtemp(prefix="bench-insn-")
    try:
        if a.method == "plugin":
            p, result = run_plugin(a, begin, end, tmp)
        else:
            p, result = run_exec_log(a, begin, end, tmp)
    finally:
        shutil.rmtree(tmp)
    if p is None:
        sys.exit(f"bench_insn: QEMU timed out after {a.timeout} s")
    sys.stdout.write(p.stdout)
    sys.stderr.write(p.stderr)
    if p.returncode != 0:
        print(f"bench_insn: firmware exited {p.returncode}", file=sys.stderr)
        return p.returncode

    groups = []
    for l in p.stdout.splitlines():
        if l.startswith("BENCH-GROUP "):
            _, label, n = l.split()
            groups.append((label, int(n)))
    w = result["windows"]
    if result["errors"] or sum(n for _, n in groups) != len(w) or not groups or groups[0][0] != "empty":
        print(f"bench_insn: {len(w)} windows, groups {groups}, errors {result['errors'][:5]}",
              file=sys.stderr)
        return 2
    print(f"== {a.method}: {result['total']} instructions executed in total; {len(w)} windows "
          f"(marker entries at 0x{begin:x}/0x{end:x})")
    i = 0
    base = None
    rows = []
    nops = {}
    print(f"{'group':40} {'n':>7} {'mean':>10} {'median':>8} {'min':>7} {'max':>7} {'mean-nop':>9}"
          "  (Thumb insns, marker overhead subtracted)")
    for label, n in groups:
        vals = w[i:i + n]
        i += n
        if base is None:
            base = statistics.median_low(vals)
            print(f"{'(marker overhead)':40} {n:7d} {statistics.mean(vals):10.1f} {base:8d} "
                  f"{min(vals):7d} {max(vals):7d}")
            continue
        v = [x - base for x in vals]
        rows += [(label, k, x) for k, x in enumerate(v)]
        # "<prefix>.nop" is a call-overhead baseline for the later "<prefix>.*" groups
        prefix = label.rsplit(".", 1)[0] if "." in label else None
        if label.endswith(".nop"):
            nops[prefix] = statistics.mean(v)
        rel = f"{statistics.mean(v) - nops[prefix]:9.1f}" if prefix in nops and not label.endswith(".nop") else ""
        print(f"{label:40} {n:7d} {statistics.mean(v):10.1f} {statistics.median_low(v):8d} "
              f"{min(v):7d} {max(v):7d} {rel}")
    if a.profile and "prof" in result:
        print_profile(a.elf, a.nm, result["prof"], a.profile)
    if a.csv:
        with open(a.csv, "w") as f:
            f.write("group,index,insns\n")
            for r in rows:
                f.write("%s,%d,%d\n" % r)
    return 0


if __name__ == "__main__":
    sys.exit(main())
