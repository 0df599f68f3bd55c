"""Reorder the derivative part of a specialised kernel source (bits unchanged: only independent statements move)."""
import re, sys

def parse(src):
    lines = src.splitlines()
    head = lines[:2]
    cut = next(i for i, l in enumerate(lines) if l.strip() == "if record >= 0:")
    body, tail = lines[2:cut], lines[cut:]
    stmts = []  # (defs, uses, text)
    for l in body:
        lhs, rhs = l.strip().split(" = ", 1)
        defs = [x.strip() for x in lhs.split(",")]
        uses = re.findall(r"\bv\d+\b", rhs)
        if lhs.startswith("w["):
            defs = []
        stmts.append((defs, uses, l))
    return head, stmts, tail

def order_demand(stmts, big_first=True):
    by_def = {}
    for i, (d, u, _) in enumerate(stmts):
        for x in d:
            by_def[x] = i
    size = {}
    def sz(i):
        if i in size: return size[i]
        s = 1 + sum(sz(by_def[x]) for x in set(stmts[i][1]) if x in by_def)
        size[i] = s; return s
    done, out = set(), []
    sys.setrecursionlimit(10000)
    def visit(i):
        if i in done: return
        done.add(i)
        deps = [by_def[x] for x in dict.fromkeys(stmts[i][1]) if x in by_def]
        if big_first:
            deps.sort(key=lambda j: -sz(j))
        for j in deps: visit(j)
        out.append(i)
    stores = [i for i, s in enumerate(stmts) if not s[0]]
    for i in stores: visit(i)
    # anything unused by the stores (needed by the record) keeps its place at the end
    for i in range(len(stmts)):
        if i not in done: visit(i)
    return out

def order_greedy(stmts):
    """List scheduling: among ready statements, pick the one that kills the most live values (ties: earliest)."""
    by_def = {}
    for i, (d, u, _) in enumerate(stmts):
        for x in d: by_def[x] = i
    users = {}
    for i, (d, u, _) in enumerate(stmts):
        for x in set(u): users.setdefault(x, set()).add(i)
    deps = [set(by_def[x] for x in u if x in by_def) for d, u, _ in stmts]
    remaining_users = {x: len(s) for x, s in users.items()}
    indeg = [len(d) for d in deps]
    succ = [[] for _ in stmts]
    for i, d in enumerate(deps):
        for j in d: succ[j].append(i)
    ready = {i for i in range(len(stmts)) if indeg[i] == 0}
    out = []
    while ready:
        def score(i):
            d, u, _ = stmts[i]
            kills = sum(1 for x in set(u) if remaining_users.get(x) == 1)
            new = len([x for x in d if x in users])
            return (new - kills, i)
        i = min(ready, key=score)
        ready.remove(i); out.append(i)
        for x in set(stmts[i][1]):
            if x in remaining_users: remaining_users[x] -= 1
        for j in succ[i]:
            indeg[j] -= 1
            if indeg[j] == 0: ready.add(j)
    return out

def emit(head, stmts, tail, order):
    assert sorted(order) == list(range(len(stmts)))
    return "\n".join(head + [stmts[i][2] for i in order] + tail) + "\n"

def variant(src, name):
    head, stmts, tail = parse(src)
    if name == "base": order = list(range(len(stmts)))
    elif name == "demand": order = order_demand(stmts)
    elif name == "demand_small": order = order_demand(stmts, big_first=False)
    elif name == "greedy": order = order_greedy(stmts)
    else: raise ValueError(name)
    return emit(head, stmts, tail, order)

def maxlive(src):
    head, stmts, tail = parse(src)
    lastuse = {}
    for i, (d, u, _) in enumerate(stmts):
        for x in u: lastuse[x] = i
    live, peak, tot = set(), 0, 0
    for i, (d, u, _) in enumerate(stmts):
        for x in set(u):
            if lastuse[x] == i: live.discard(x)
        live.update(x for x in d if x in lastuse)
        peak = max(peak, len(live)); tot += len(live)
    return peak, tot / len(stmts)

if __name__ == "__main__":
    src = open(sys.argv[1]).read()
    for n in ["base", "demand", "demand_small", "greedy"]:
        print(n, maxlive(variant(src, n)))

LAT = {"*": 3, "+": 3, "-": 3, "/": 13, "sqrt": 20, "sincos": 40, "load": 4, "neg": 1, "store": 1}
def latency(text):
    rhs = text.split(" = ", 1)[1]
    if "sincos" in rhs: return LAT["sincos"]
    if "_sqrt" in rhs: return LAT["sqrt"]
    if rhs.startswith("w["): return LAT["load"]
    for op in "/*+-":
        if f" {op} " in rhs: return LAT[op]
    return 1

def graph(stmts):
    by_def = {}
    for i, (d, u, _) in enumerate(stmts):
        for x in d: by_def[x] = i
    deps = [sorted(set(by_def[x] for x in u if x in by_def)) for d, u, _ in stmts]
    succ = [[] for _ in stmts]
    for i, d in enumerate(deps):
        for j in d: succ[j].append(i)
    return deps, succ

def order_list(stmts, width=2, key="height"):
    """Cycle-by-cycle list scheduling on a machine issuing ``width`` statements a cycle, priority: height."""
    deps, succ = graph(stmts)
    lat = [latency(s[2]) for s in stmts]
    height = [0] * len(stmts)
    for i in reversed(range(len(stmts))):
        height[i] = lat[i] + max((height[j] for j in succ[i]), default=0)
    indeg = [len(d) for d in deps]
    ready_at = [0] * len(stmts)
    ready = {i for i in range(len(stmts)) if indeg[i] == 0}
    out, cycle = [], 0
    while ready:
        avail = sorted((i for i in ready if ready_at[i] <= cycle), key=lambda i: (-height[i], i))
        for i in avail[:width]:
            ready.remove(i); out.append(i)
            for j in succ[i]:
                indeg[j] -= 1
                ready_at[j] = max(ready_at[j], cycle + lat[i])
                if indeg[j] == 0: ready.add(j)
        cycle += 1
    return out, cycle

def critical(src):
    head, stmts, tail = parse(src)
    deps, succ = graph(stmts)
    lat = [latency(s[2]) for s in stmts]
    fin = [0] * len(stmts)
    for i in range(len(stmts)):
        fin[i] = lat[i] + max((fin[j] for j in deps[i]), default=0)
    return max(fin)

_old_variant = variant
def variant(src, name):
    if name.startswith("list"):
        head, stmts, tail = parse(src)
        width = int(name[4:] or 2)
        order, _ = order_list(stmts, width)
        return emit(head, stmts, tail, order)
    return _old_variant(src, name)
