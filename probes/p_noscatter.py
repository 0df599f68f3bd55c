import sys; p = sys.argv[1]; s = open(p).read()
a = "                flat[(row * size + j) * n + first + i] = w[(REC + j) * B + i]"
assert a in s; s = s.replace(a, "                pass")
open(p, "w").write(s)
