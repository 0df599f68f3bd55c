import sys
sys.path.insert(0, "/tmp/sched")
from blocks import blocks
path, name, out = sys.argv[1:4]
b = blocks(path)
open(out, "w").write("\n".join(b[name]) + "\n")
