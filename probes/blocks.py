import re, sys, collections
def blocks(path):
    lines = open(path).read().splitlines()
    cur, out = None, collections.OrderedDict()
    for l in lines:
        m = re.match(r"^(\.LBB\S+):", l)
        if m: cur = m.group(1); out[cur] = []; continue
        s = l.strip()
        if cur and s and not s.startswith(".") and not s.startswith("#"):
            out[cur].append(s)
    return out
if __name__ == "__main__":
    for path in sys.argv[1:]:
      b = blocks(path)
      names = list(b)
      print(path)
      for i, (name, ins) in enumerate(b.items()):
          if len(ins) > 300:
              back = [x for x in ins if x.split()[0].startswith("j") and x.split()[-1] in names[:i+1]]
              c = collections.Counter(x.split()[0] for x in ins)
              spill = sum(1 for x in ins if "rsp)" in x)
              print(f"  {name}: {len(ins)} ins, mul {c['vmulpd']} add {c['vaddpd']+c['vsubpd']} div {c['vdivpd']} sqrt {c['vsqrtpd']} movupd {c['vmovupd']} rsp {spill} backjump {back}")
