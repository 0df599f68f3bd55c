import sys; p = sys.argv[1]; s = open(p).read()
a = "        inv = 1.0 / np.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)\n"
assert a in s; s = s.replace(a, "        inv = 1.0\n")
open(p, "w").write(s)
