import sys; p = sys.argv[1]; s = open(p).read()
a = """    for i in range(B):
        lk, _, _, _ = _own(w, R * B + i, B, k, gains, None, None)
        derivative_kernel("""
assert a in s; s = s.replace(a, """    for i in range(-1):
        lk, _, _, _ = _own(w, R * B + i, B, k, gains, None, None)
        derivative_kernel(""")
open(p, "w").write(s)
