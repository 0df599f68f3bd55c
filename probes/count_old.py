import sys; sys.path.insert(0, '/tmp/gen'); sys.path.insert(0, '/tmp/tmpx54ro9vz/old')
import rrrobot_gym; print(rrrobot_gym.__file__)
import tracer as T
from tracer import node
from rrrobot_gym import dynamics
from rrrobot_gym.params import RobotParams
def trig(p1, p2):
    s1, c1 = T.sym_sincos(p1); s2, c2 = T.sym_sincos(p2); return c1, s1, c2, s2
dynamics._leg_trig = trig
p = RobotParams()
for record in (False, True):
    T.reset()
    c = [node('in', 'y%d' % j) for j in range(13)]
    tau = [node('in', 'tau0'), node('in', 'tau1')]
    k = dynamics.constants(p, p.radius)
    co = [None]*7 if record else None
    d = dynamics.derivative_kernel(c, tau, k, contact_out=co)
    outs = list(d) + (co if record else [])
    print("old record" if record else "old", T.counts(outs))
