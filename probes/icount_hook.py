import os, sys, runpy
if os.environ.get("RR_GEN"):
    import importlib.util
    from rrrobot_gym import compiled
    src = None if os.environ["RR_GEN"] == "none" else open(os.environ["RR_GEN"]).read()
    compiled.specialised = lambda robot, model: src
runpy.run_path(sys.argv.pop(1), run_name="__main__")
