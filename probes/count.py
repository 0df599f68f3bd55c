import sys; sys.path.insert(0, '/tmp/gen')
import numpy as np
import tracer as T
from tracer import Sym, node
from rrrobot_gym import dynamics
from rrrobot_gym.params import RobotParams
dynamics.sincos = T.sym_sincos
p = RobotParams()
for record in (False, True):
    T.reset()
    size, at, out, drive, scratch, rec = dynamics.kernel_work(2)
    w = [0.0] * size
    for j in range(13): w[at + j] = node('in', 'y%d' % j)
    for m in range(2): w[drive + m] = node('in', 'tau%d' % m)
    k = dynamics.constants(p, "plane")
    layout = dynamics.leg_layout(p)
    dynamics.derivative_kernel(w, at, out, 1, k, layout, drive, scratch, False, rec if record else -1)
    outs = w[out:out + 13] + (w[rec:rec + 9] if record else [])
    print("family record" if record else "family", T.counts(outs))
print(layout)
