import sys; p = sys.argv[1]; s = open(p).read()
a = "_BLOCK_FUNCTIONS = (_block_combine, _block_update, _block_stage, _block_substep, _block)"
b = "_BLOCK_INLINED = (_rows, _limit, _robot, _own, _block_torques, _block_derivatives)"
assert a in s and b in s
s = s.replace(a, "_BLOCK_FUNCTIONS = (_block_substep, _block)")
s = s.replace(b, "_BLOCK_INLINED = (_rows, _limit, _robot, _own, _block_torques, _block_derivatives, _block_combine, _block_update, _block_stage)")
open(p, "w").write(s)
