import sys; p = sys.argv[1]; s = open(p).read()
reps = [
 ("def _block_combine(w, legs, keep, scale):\n    \"\"\"Copy the last derivative to rows ``keep`` and set the stage state to y + scale * it.\"\"\"\n    B = BLOCK\n",
  "def _block_combine(w, layout, keep, scale):\n    \"\"\"Copy the last derivative to rows ``keep`` and set the stage state to y + scale * it.\"\"\"\n    B, legs = BLOCK, len(layout)\n"),
 ("def _block_update(w, legs, sixth):\n    \"\"\"RK4's step from the four stages, then the quaternion back to unit length.\"\"\"\n    B = BLOCK\n",
  "def _block_update(w, layout, sixth):\n    \"\"\"RK4's step from the four stages, then the quaternion back to unit length.\"\"\"\n    B, legs = BLOCK, len(layout)\n"),
 ("_block_combine(w, legs, K1, half)", "_block_combine(w, layout, K1, half)"),
 ("_block_combine(w, legs, K2, half)", "_block_combine(w, layout, K2, half)"),
 ("_block_combine(w, legs, K3, h)", "_block_combine(w, layout, K3, h)"),
 ("_block_update(w, legs, sixth)", "_block_update(w, layout, sixth)"),
]
for a, b in reps:
    assert a in s, a; s = s.replace(a, b)
open(p, "w").write(s)
