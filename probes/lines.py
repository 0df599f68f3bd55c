import sys, collections
from rrrobot_gym import specialise as S, dynamics
from rrrobot_gym.params import RobotParams
orig = S._Trace.node
where = {}
def node(self, op, *operands):
    v = orig(self, op, *operands)
    if v.at not in where:
        f = sys._getframe(1)
        while f.f_code.co_filename.endswith("specialise.py"): f = f.f_back
        where[v.at] = (f.f_code.co_name, f.f_lineno)
    return v
S._Trace.node = node
model = sys.argv[1] if len(sys.argv) > 1 else "plane"
src = S.kernel_source.__wrapped__(RobotParams(), model)
# map v-names in derivative part to lines
body = src.split("    if record >= 0:")[0].splitlines()
c = collections.Counter()
for line in body:
    if line.startswith("    v") and "= w[" not in line:
        at = int(line.split("=")[0].strip().split(",")[0][1:])
        c[where[at]] += 1
byfn = collections.Counter()
for (fn, ln), n in c.items(): byfn[fn] += n
print(byfn)
for (fn, ln), n in sorted(c.items(), key=lambda x: x[0][1]): print(fn, ln, n)
