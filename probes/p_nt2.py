import sys; p = sys.argv[1]; s = open(p).read()
a = '''    if params.shape[0] == 1:  # the same targets for every robot: once a stage
        for m in range(legs):'''
assert a in s
s = s.replace(a, '''    for m in range(legs):
        for i in range(B):
            w[(DRIVE + m) * B + i] = 0.0
    if params.shape[0] == -5:
        for m in range(legs):''')
s = s.replace('''    else:
        for i in range(B):
            _, g, tl, rl = _own(w, R * B + i, B, k, gains, torque_limit, rate_limit)''', '''    elif params.shape[0] == -7:
        for i in range(B):
            _, g, tl, rl = _own(w, R * B + i, B, k, gains, torque_limit, rate_limit)''')
open(p, "w").write(s)
