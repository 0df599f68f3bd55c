import sys; p = sys.argv[1]; s = open(p).read()
a = '''    for m in range((9 + 2 * legs) * B):
        w[Y * B + m] = w[Y * B + m] + sixth * (w[K1 * B + m] + 2.0 * (w[K2 * B + m] + w[K3 * B + m]) + w[D * B + m])'''
assert a in s; s = s.replace(a, '''    for m in range(0):
        w[Y * B + m] = w[Y * B + m] + sixth * (w[K1 * B + m] + 2.0 * (w[K2 * B + m] + w[K3 * B + m]) + w[D * B + m])''')
open(p, "w").write(s)
