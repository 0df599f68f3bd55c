import subprocess, sys, os, statistics
rounds, variants, zero, N, steps = int(sys.argv[1]), sys.argv[2].split(","), sys.argv[3], sys.argv[4], sys.argv[5]
res = {k: [] for k in variants}
for r in range(rounds):
    for v in variants:
        old = v.startswith("old")
        env = dict(os.environ, ZERO=("old" if old else "main") if zero == "1" else "", OMP_NUM_THREADS="1",
                   PYTHONPATH=("/tmp/tmpx54ro9vz/old" if v == "old" else f"/tmp/v/{v}"), XDG_CACHE_HOME=f"/tmp/v/xdg-{v}-{zero}")
        out = subprocess.run(["taskset", "-c", "1", "python", "/tmp/gen/hook.py", "/tmp/gen/envtime.py", N, steps], env=env, capture_output=True, text=True)
        try: res[v].append(float(out.stdout.split()[-1]))
        except Exception: print(v, out.stderr[-2000:]); raise
b = res[variants[0]]
for v in variants:
    rat = [x / y for x, y in zip(res[v], b)]
    print(f"N={N} zero={zero}", v, "%.0f  us/step %.3f  ratio %.3f (%.3f-%.3f)" % (statistics.median(res[v]), 1e6 / statistics.median(res[v]), statistics.median(rat), min(rat), max(rat)), flush=True)
