import sys; p = sys.argv[1]; s = open(p).read()
a = '''    for m in range((9 + 2 * legs) * B):  # one loop over every row's lanes: long enough to be vectorised, not unrolled
        d = w[D * B + m]
        w[keep * B + m] = d
        w[S * B + m] = w[Y * B + m] + scale * d'''
b = '''    for j in range(9 + 2 * legs):
        for i in range(B):
            d = w[(D + j) * B + i]
            w[(keep + j) * B + i] = d
            w[(S + j) * B + i] = w[(Y + j) * B + i] + scale * d'''
assert a in s; s = s.replace(a, b)
a = '''    for m in range((9 + 2 * legs) * B):
        w[Y * B + m] = w[Y * B + m] + sixth * (w[K1 * B + m] + 2.0 * (w[K2 * B + m] + w[K3 * B + m]) + w[D * B + m])'''
b = '''    for j in range(9 + 2 * legs):
        for i in range(B):
            m = j * B + i
            w[Y * B + m] = w[Y * B + m] + sixth * (w[K1 * B + m] + 2.0 * (w[K2 * B + m] + w[K3 * B + m]) + w[D * B + m])'''
assert a in s; s = s.replace(a, b)
open(p, "w").write(s)
