"""Symbolically execute dynamics.derivative_kernel for one robot with its numbers substituted, CSE, emit Python."""
import sys, sympy as sp
sys.path.insert(0, sys.argv[1])
from rrrobot_gym import dynamics
from rrrobot_gym.params import RobotParams
model = sys.argv[2]
p = RobotParams()
k = dynamics.constants(p, model)
layout = dynamics.leg_layout(p)
L = len(layout)
n = 9 + 2 * L
S = sp.symbols(f"c0:{n}")
T = sp.symbols(f"tau0:{L}")
SC = [sp.Symbol(f"sin{m}") for m in range(L)]
CC = [sp.Symbol(f"cos{m}") for m in range(L)]
angle_of = {S[6 + m]: m for m in range(L)}
dynamics.sincos = lambda x: (SC[angle_of[x]], CC[angle_of[x]])
dynamics._sqrt = sp.sqrt
size, at, out, drive, scratch, rec = dynamics.kernel_work(L)
w = [*S, *([0.0] * (size - n))]
for m in range(L):
    w[drive + m] = T[m]
dynamics.derivative_kernel(w, at, out, 1, k, layout, drive, scratch, False, -1)
outs = [sp.sympify(e) for e in w[out:out + n]]
reps, red = sp.cse(outs, symbols=sp.numbered_symbols("t"), optimizations="basic")
lines = [f"def generated_kernel(w, at, out, step, drive):"]
for j in range(n):
    lines.append(f"    c{j} = w[at + {j} * step]")
for m in range(L):
    lines.append(f"    tau{m} = w[drive + {m} * step]")
    lines.append(f"    sin{m}, cos{m} = sincos(c{6 + m})")
from sympy.printing.pycode import PythonCodePrinter
pr = PythonCodePrinter({"fully_qualified_modules": False})
def code(e):
    s = pr.doprint(e)
    return s.replace("math.sqrt", "_sqrt")
for sym, e in reps:
    lines.append(f"    {sym} = {code(e)}")
for j, e in enumerate(red):
    lines.append(f"    w[out + {j} * step] = {code(e)}")
open(sys.argv[3], "w").write("\n".join(lines) + "\n")
ops = sp.count_ops(red) + sum(sp.count_ops(e) for _, e in reps)
print("subexpressions", len(reps), "ops", ops)
