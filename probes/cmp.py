import subprocess, sys, os, statistics, json
# usage: cmp.py ROUNDS N name=ENV;ENV;PYTHONPATH ...
rounds, n = int(sys.argv[1]), sys.argv[2]
variants = []
for spec in sys.argv[3:]:
    name, rest = spec.split("=", 1)
    env = dict(os.environ)
    for kv in rest.split(";"):
        k, v = kv.split(":", 1); env[k] = v
    variants.append((name, env))
res = {name: [] for name, _ in variants}
for r in range(rounds):
    for name, env in variants:
        out = subprocess.run(["taskset", "-c", "1", "python", os.environ.get("CORE", "/tmp/gen/core.py"), n], env=env, capture_output=True, text=True).stdout
        res[name].append(float(out.split()[-1]))
base = statistics.median(res[variants[0][0]])
for name, v in res.items():
    m = statistics.median(v)
    print(f"{name:12s} median {m:9.0f}  ratio {m/base:.3f}  all {[int(x) for x in v]}")
