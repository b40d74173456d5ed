#!/usr/bin/env python3
"""Import cycles between the modules of a crate, by reading the source text (no dependencies).

Usage: python3 tools/import-cycles.py [CRATE_SRC_DIR ...]   (default: the three library crates)
Modules are files (foo.rs or foo/mod.rs). An edge A -> B exists when A's text names a path
`crate::x::y::...` (or `super::...`, `self::...`) whose longest prefix that is a module is B
(B != A and B is not an ancestor-declaration edge). Test-only code (`#[cfg(test)] mod tests {`
blocks inside a file) is ignored by cutting the file at the first `#[cfg(test)]` followed by
`mod`. Prints every strongly connected component of size > 1, or 'no cycles'.
"""
import os, re, sys


def crate_cycles(root):
    mods = {}
    for dp, dn, fn in os.walk(root):
        for f in fn:
            if not f.endswith('.rs'): continue
            p = os.path.join(dp, f); rel = os.path.relpath(p, root)[:-3].split(os.sep)
            if rel[-1] in ('mod',): rel = rel[:-1]
            if rel in (['lib'], ['main']): rel = []
            if rel and rel[0] == 'bin': continue
            mods[tuple(rel)] = p
    def body(p):
        s = open(p).read()
        m = re.search(r'#\[cfg\(test\)\]\s*(pub(\(crate\))?\s+)?mod\s+\w+\s*\{', s)
        if m: s = s[:m.start()]
        s = re.sub(r'//[^\n]*', '', s)
        return s
    edges = {m: set() for m in mods}
    for m, p in mods.items():
        s = body(p)
        # expand `use crate::a::{b, c::d}` groups one level
        for g in re.finditer(r'\b(crate|super|self)((?:::\w+)*)::\{([^{}]*)\}', s):
            for part in g.group(3).split(','):
                part = part.strip().split(' as ')[0]
                if part: s += f' {g.group(1)}{g.group(2)}::{part} '
        for h in re.finditer(r'\b((?:crate|super|self)(?:::\w+)+)', s):
            segs = h.group(1).split('::')
            if segs[0] == 'crate': base = []
            else:
                base = list(m)
                # a file foo.rs is module foo; super from it is its parent
                while segs and segs[0] in ('super', 'self'):
                    if segs[0] == 'super': base = base[:-1]
                    segs = segs[1:]
                segs = ['x'] + segs
            path = base + segs[1:]
            best = None
            for k in range(len(path), -1, -1):
                if tuple(path[:k]) in mods: best = tuple(path[:k]); break
            if best is None or best == m: continue
            if len(best) < len(m) and m[:len(best)] == best and best == m[:-1] and False: continue
            edges[m].add(best)
    # Tarjan
    idx = {}; low = {}; st = []; on = set(); out = []; c = [0]
    def sc(v):
        idx[v] = low[v] = c[0]; c[0] += 1; st.append(v); on.add(v)
        for w in edges[v]:
            if w not in idx: sc(w); low[v] = min(low[v], low[w])
            elif w in on: low[v] = min(low[v], idx[w])
        if low[v] == idx[v]:
            comp = []
            while True:
                w = st.pop(); on.discard(w); comp.append(w)
                if w == v: break
            if len(comp) > 1: out.append(comp)
    for v in mods:
        if v not in idx: sc(v)
    name = lambda m: '::'.join(('crate',) + m)
    print(f'{root}: {len(mods)} modules, {sum(len(e) for e in edges.values())} edges: ' + ('no cycles' if not out else f'{len(out)} cycle(s)'))
    for comp in out:
        print('cycle:', ' , '.join(sorted(name(x) for x in comp)))
        for a in comp:
            for b in sorted(edges[a]):
                if b in comp: print('   ', name(a), '->', name(b))

    return len(out)

sys.setrecursionlimit(10000)
here = os.path.dirname(os.path.abspath(__file__))
dirs = sys.argv[1:] or [os.path.join(here, '..', c, 'src') for c in ('firmware-core', 'planner-host', 'sim-harness')]
sys.exit(1 if sum(crate_cycles(os.path.normpath(d).rstrip('/')) for d in dirs) else 0)
