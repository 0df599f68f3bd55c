import subprocess, sys, os, statistics
rounds, variants, args = int(sys.argv[1]), sys.argv[2].split(","), sys.argv[3:]
res = {k: [] for k in variants}
for r in range(rounds):
    for v in variants:
        env = dict(os.environ, VAR=v, XDG_CACHE_HOME="/tmp/sched/xdg", OMP_NUM_THREADS="1", PYTHONPATH="/work/main")
        out = subprocess.run(["taskset", "-c", "1", "python", "/tmp/sched/tvar.py", *args], env=env, capture_output=True, text=True)
        res[v].append(float(out.stdout.split()[-1]))
base = res[variants[0]]
for v in variants:
    rat = [b / a for a, b in zip(base, res[v])]
    print(args, v, "%.0f" % statistics.median(res[v]), "ratio %.3f (%.3f-%.3f)" % (statistics.median(rat), min(rat), max(rat)), flush=True)
