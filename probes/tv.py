import subprocess, sys, os, statistics
rounds, variants, rec, zero = int(sys.argv[1]), sys.argv[2].split(","), sys.argv[3], sys.argv[4]
res = {k: [] for k in variants}
for r in range(rounds):
    for v in variants:
        env = dict(os.environ, REC=rec, ZERO=zero if not v.startswith("old") else ("old" if zero == "main" else ""), OMP_NUM_THREADS="1",
                   PYTHONPATH="/tmp/tmpx54ro9vz/old" if v == "old" else f"/tmp/v/{v}", XDG_CACHE_HOME=f"/tmp/v/xdg-{v}-{zero}")
        env["PYTHONPATH"] = env["PYTHONPATH"]; out = subprocess.run(["taskset", "-c", "1", "python", "/tmp/gen/hook.py", "/tmp/gen/tphys2.py", "4096", "plane"], env=env, capture_output=True, text=True)
        try: res[v].append(float(out.stdout.split()[-1]))
        except Exception: print(v, out.stderr[-2000:]); raise
for v in variants:
    print(f"REC={rec} ZERO={zero}", v, "%.0f  us/robot-advance %.3f" % (statistics.median(res[v]), 1e6 / statistics.median(res[v])), flush=True)
