import sys; p = sys.argv[1]; s = open(p).read()
a = '''            _copies(_BLOCK_INLINED, inline, copy, f"{suffix}_{block}", legs)'''
b = '''            _copies(tuple(f for f in _BLOCK_INLINED if f.__name__ not in ("_block_combine", "_block_update")), inline, copy, f"{suffix}_{block}", legs)
            _copies((_block_combine, _block_update), functools.partial(njit, inline="always"), copy, f"{suffix}_{block}", legs)'''
assert a in s; s = s.replace(a, b); open(p, "w").write(s)
