"""Generate a derivative_kernel specialised to one robot (constants folded) by tracing the general one."""
import sys; sys.path.insert(0, '/tmp/gen')
import tracer as T
from tracer import Sym, node, NODES

def name(a, names):
    if isinstance(a, Sym):
        return names[a.i]
    return repr(float(a))

def generate(params, model, path):
    from rrrobot_gym import dynamics
    saved = dynamics.sincos
    dynamics.sincos = T.sym_sincos
    try:
        T.reset()
        legs = params.num_legs
        n = 9 + 2 * legs
        size, at, out, drive, scratch, rec = dynamics.kernel_work(legs)
        w = [0.0] * size
        for j in range(n): w[at + j] = node('in', ('y', j))
        for m in range(legs): w[drive + m] = node('in', ('tau', m))
        k = dynamics.constants(params, model)
        dynamics.derivative_kernel(w, at, out, 1, k, dynamics.leg_layout(params), drive, scratch, False, rec)
        outs = w[out:out + n]
        recs = w[rec:rec + 2 * legs + 5]
    finally:
        dynamics.sincos = saved
    first = T.live(outs)
    second = T.live(outs + recs) - first
    names = {}
    lines = ["import math", "from rrrobot_gym.numerics import sincos", "",
             "def derivative_kernel(w, at, out, step, k, layout, drive, scratch, kinematic, record):"]
    def emit(ids, indent):
        for i in sorted(ids):
            op, args = NODES[i]
            v = f"t{i}"
            names[i] = v
            if op == 'in':
                kind, j = args[0]
                src = f"w[at + {j} * step]" if kind == 'y' else f"w[drive + {j} * step]"
                lines.append(f"{indent}{v} = {src}")
            elif op in ('sin', 'cos'):
                other = T.INDEX[('cos' if op == 'sin' else 'sin', args[0].i if isinstance(args[0], Sym) else ('c', args[0]))]
                if other in names:
                    continue
                s, c = (i, other) if op == 'sin' else (other, i)
                names[s], names[c] = f"t{s}", f"t{c}"
                lines.append(f"{indent}t{s}, t{c} = sincos({name(args[0], names)})")
            elif op == 'neg':
                lines.append(f"{indent}{v} = -{name(args[0], names)}")
            elif op == 'sqrt':
                lines.append(f"{indent}{v} = math.sqrt({name(args[0], names)})")
            elif op == 'max':
                x = name(args[0], names)
                lines.append(f"{indent}{v} = {x} if not {x} < 0.0 else 0.0")
            else:
                sym = {'add': '+', 'sub': '-', 'mul': '*', 'div': '/'}[op]
                lines.append(f"{indent}{v} = {name(args[0], names)} {sym} {name(args[1], names)}")
    emit(first, "    ")
    for j, o in enumerate(outs):
        lines.append(f"    w[out + {j} * step] = {name(o, names)}")
    lines.append("    if record >= 0:")
    emit(second, "        ")
    for j, o in enumerate(recs):
        lines.append(f"        w[record + {j} * step] = {name(o, names)}")
    open(path, "w").write("\n".join(lines) + "\n")
    return T.counts(outs), T.counts(outs + recs)

if __name__ == "__main__":
    from rrrobot_gym.params import RobotParams
    print(generate(RobotParams(), sys.argv[2] if len(sys.argv) > 2 else "plane", sys.argv[1]))
