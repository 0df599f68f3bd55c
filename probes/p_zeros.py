import sys; p = sys.argv[1]; s = open(p).read()
a = "    w = np.zeros(TOTAL * B)\n"
assert a in s; s = s.replace(a, "    w = np.empty(TOTAL * B)\n    w[:R * B] = 0.0\n")
open(p, "w").write(s)
