#!/usr/bin/env python3
"""Import cycles between the modules of each library crate, as `cargo modules` sees them.

    cargo install cargo-modules --version 0.27.0 --locked   # once (0.27 is the last for rustc 1.95)
    python3 tools/module-cycles.py [CRATE ...]             # default: the three library crates

Runs `cargo modules dependencies --lib` with types, functions, traits, extern and sysroot
items and "owns" edges filtered out, so the graph is modules joined by their "uses" edges,
and prints every strongly connected component of more than one module (a cycle), or
"no cycles". Exits 1 when there is a cycle. (`--acyclic` itself also counts a type and its
own methods as a cycle, which says nothing about the layout, hence this filter.)
"""
import re, subprocess, sys

crates = sys.argv[1:] or ["firmware-core", "planner-host", "sim-harness"]
bad = False
for crate in crates:
    dot = subprocess.run(
        ["cargo", "modules", "dependencies", "--lib", "-p", crate, "--no-externs", "--no-sysroot",
         "--no-fns", "--no-types", "--no-traits", "--no-owns"],
        capture_output=True, text=True, check=True).stdout
    nodes = set(re.findall(r'^\s*"([^"]+)" \[label=', dot, re.M))
    edges = {n: set() for n in nodes}
    for a, b in re.findall(r'^\s*"([^"]+)" -> "([^"]+)" \[label="uses"', dot, re.M):
        edges.setdefault(a, set()).add(b); edges.setdefault(b, set())
    index, low, stack, on, comps, counter = {}, {}, [], set(), [], [0]
    def visit(v):
        index[v] = low[v] = counter[0]; counter[0] += 1; stack.append(v); on.add(v)
        for w in edges[v]:
            if w not in index: visit(w); low[v] = min(low[v], low[w])
            elif w in on: low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop(); on.discard(w); comp.append(w)
                if w == v: break
            if len(comp) > 1: comps.append(sorted(comp))
    sys.setrecursionlimit(10000)
    for v in sorted(edges):
        if v not in index: visit(v)
    n_edges = sum(len(e) for e in edges.values())
    print(f"{crate}: {len(edges)} modules, {n_edges} use edges: "
          + ("no cycles" if not comps else f"{len(comps)} cycle(s)"))
    for c in comps:
        bad = True
        print("  cycle: " + " <-> ".join(c))
sys.exit(1 if bad else 0)
