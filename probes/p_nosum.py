import sys; p = sys.argv[1]; s = open(p).read()
s = s.replace("    if rows.shape[0]:\n        _summarise(rows, summary, first, B, legs)", "    pass")
open(p, "w").write(s)
