import sys; p = sys.argv[1]; s = open(p).read()
a = "_BLOCK_FUNCTIONS = (_block_combine, _block_update, _block_stage, _block_substep, _block)"
assert a in s; s = s.replace(a, "_BLOCK_FUNCTIONS = (_block_stage, _block_substep, _block)")
a = '''            _copies(_BLOCK_INLINED, inline, copy, f"{suffix}_{block}", legs)'''
b = '''            _copies(_BLOCK_INLINED, inline, copy, f"{suffix}_{block}", legs)
            _copies((_block_combine, _block_update), functools.partial(njit, inline="always"), copy, f"{suffix}_{block}", legs)'''
assert a in s; s = s.replace(a, b); open(p, "w").write(s)
