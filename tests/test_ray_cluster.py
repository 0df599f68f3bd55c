"""The gait search and train.py --seeds against a Ray cluster started as users start one: ``ray start
--head`` (token authentication on, as Ray turns it on where a token is found) and a second node joined
with ``ray start --address``; and the one-line errors of a head that refuses the driver."""

import contextlib
import json
import os
import re
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from concurrent import futures
from pathlib import Path

import pytest

from rrrobot_gym import cli, gait_search

ROOT = Path(__file__).resolve().parents[1]
SEARCH = ["gait-search", "--model", "plane", "--evaluations", "48", "--popsize", "16", "--duration", "1",
          "--robustness-seeds", "0", "--no-progress"]  # fmt: skip
TINY = ["--total-timesteps", "2048", "--num-envs", "16", "--n-steps", "64", "--n-epochs", "1", "--eval-freq", "1024",
        "--checkpoint-freq", "100000", "--episode-steps", "40", "--bootstrap-reps", "1000"]  # fmt: skip


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def _clean_env(**extra) -> dict:
    """This environment without Ray's settings (RAY_*) or PYTHONPATH, plus ``extra``."""
    return {**{k: v for k, v in os.environ.items() if not k.startswith("RAY_") and k != "PYTHONPATH"}, **extra}


def _processes_under(folder: str) -> list:
    """Pids of the processes whose command line names ``folder`` (a node's --temp-dir)."""
    pids = []
    for entry in Path("/proc").iterdir():
        with contextlib.suppress(OSError):
            if entry.name.isdigit() and folder in (entry / "cmdline").read_bytes().decode(errors="replace"):
                pids.append(int(entry.name))
    return pids


def _stop(groups, folder: str) -> None:
    """Kill this cluster only: the process groups its `ray start`s made, then whatever still names its
    temp dir (never `ray stop`, which stops every Ray of this user)."""
    for group in groups:
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(group, signal.SIGKILL)
    for _ in range(50):
        left = _processes_under(folder)
        if not left:
            break
        for pid in left:
            with contextlib.suppress(ProcessLookupError, PermissionError):
                os.kill(pid, signal.SIGKILL)
        time.sleep(0.1)
    shutil.rmtree(folder, ignore_errors=True)


@pytest.fixture(scope="module")
def cluster():
    """A head and a worker node of one CPU each, started by the ``ray`` command in sessions of their
    own, the token in a file of the test's (RAY_AUTH_TOKEN_PATH) rather than the user's ~/.ray, from
    a folder holding a broken copy of this package (a user's other checkout, where Ray's workers run):
    (address, token path, {node id: "head" or "worker", its temp dir's name}, the folder of both)."""
    ray = pytest.importorskip("ray")
    if tuple(int(part) for part in ray.__version__.split(".")[:2]) < (2, 59):
        pytest.skip(f"Ray {ray.__version__}: `ray start --head` turns token authentication on from Ray 2.59")
    ray_cli = shutil.which("ray")
    if ray_cli is None:
        pytest.skip("the ray command is not on PATH")
    folder = tempfile.mkdtemp(prefix="rrray", dir="/tmp")  # (short: Ray's socket paths live under it)
    token = Path(folder) / "token"
    token.write_text(secrets.token_hex(32))
    groups = []
    elsewhere = Path(folder) / "elsewhere" / "rrrobot_gym"
    elsewhere.mkdir(parents=True)
    (elsewhere / "__init__.py").write_text("raise ImportError('the copy in the working directory of ray start')\n")

    def start(args, env, node):
        command = [ray_cli, "start", *args, "--num-cpus", "1", "--temp-dir", str(Path(folder) / node),
                   "--dashboard-agent-listen-port", str(_free_port()), "--disable-usage-stats"]  # fmt: skip
        process = subprocess.Popen(command, cwd=elsewhere.parent, env=env, start_new_session=True, text=True,
                                   stdout=subprocess.PIPE, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
        groups.append(process.pid)
        out, _ = process.communicate(timeout=180)
        assert process.returncode == 0, out[-3000:]
        return out

    try:
        port = _free_port()
        head = start(["--head", "--port", str(port), "--include-dashboard", "false", "--dashboard-port",
                      str(_free_port()), "--ray-client-server-port", str(_free_port())],
                     _clean_env(RAY_AUTH_TOKEN_PATH=str(token)), "head")  # fmt: skip
        assert "Token authentication is enabled" in head, head[-3000:]  # (Ray's default where a token is found)
        (address,) = set(re.findall(r"ray start --address='([^']+)'", head))
        start(["--address", address], _clean_env(RAY_AUTH_MODE="token", RAY_AUTH_TOKEN_PATH=str(token)), "worker")
        nodes = {}
        for node in ("head", "worker"):
            (session,) = (Path(folder) / node).glob("session_2*")
            (name,) = [p.name for p in session.iterdir() if p.name.startswith("metrics_export_port_")]
            nodes[name.removeprefix("metrics_export_port_")] = node
        yield address, token, nodes, Path(folder)
    finally:
        _stop(groups, folder)


def _driver(argv, token, timeout=300, **env):
    """Our command line (rrrobot or train.py) as a user runs it in a shell, in this checkout."""
    env = _clean_env(**{"PYTHONPATH": str(ROOT), "RAY_AUTH_TOKEN_PATH": str(token), **env})
    return subprocess.run([sys.executable, *argv], cwd=ROOT, env=env, capture_output=True, text=True, timeout=timeout)


@pytest.mark.slow
def test_the_gait_search_on_a_token_cluster_of_two_nodes_equals_the_local_search(cluster, tmp_path, capsys):
    address, token, nodes, folder = cluster
    cli.main([*SEARCH, "--out", str(tmp_path / "local.json")])
    capsys.readouterr()
    done = _driver(["-m", "rrrobot_gym", *SEARCH, "--out", str(tmp_path / "ray.json"), "--ray-address", address], token,
                   RAY_AUTH_MODE="token")  # fmt: skip
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    local, remote = (json.loads((tmp_path / f"{name}.json").read_text()) for name in ("local", "ray"))
    assert remote["used"]["evaluations"] == local["used"]["evaluations"] == 48
    assert remote["gaits"] == local["gaits"]
    untimed = [[{k: v for k, v in row.items() if k != "seconds"} for row in run["history"]] for run in (local, remote)]
    assert untimed[0] == untimed[1] and len(untimed[0]) >= 2  # (the screen, then CMA-ES generations)
    ran_on = {node for node in nodes.values() for log in (folder / node).glob("session_2*/logs/worker-*")
              if ":task_name:_rollout_chunk" in log.read_text(errors="replace")}  # fmt: skip
    assert ran_on == {"head", "worker"}  # (two one-CPU tasks a population, one a node)


@pytest.mark.slow
def test_seeds_on_a_token_cluster_of_two_nodes_run_one_on_each(cluster, tmp_path):
    address, token, nodes, _ = cluster
    started = time.time()
    done = _driver(["train.py", "--seeds", "2", "--bar", "-1000", *TINY, "--runs-dir", str(tmp_path),
                    "--ray-address", address], token, RAY_AUTH_MODE="token")  # fmt: skip
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    (folder,) = [p for p in tmp_path.iterdir() if p.is_dir()]
    summary = json.loads((folder / "summary.json").read_text())
    runs = summary["runs"]
    assert [run["seed"] for run in runs] == [1, 2] and all(run["status"] == "ok" for run in runs), runs
    assert summary["reached_bar"] == 2 and summary["worst_heading_iqm"]["runs"] == 2
    assert {nodes[run["ray_node_id"]] for run in runs} == {"head", "worker"}  # (one-CPU nodes: one run each)
    for run in runs:
        assert all((folder / run["run_dir"] / name).is_file() for name in ("best_model.zip", "evaluations.npz"))
        log = (folder / run["log"]).read_text()
        (when,) = re.findall(r"first PPO update done .* \(unix time ([0-9.]+)\)", log)
        assert started < float(when) < time.time()


@pytest.mark.slow
def test_a_token_cluster_that_refuses_the_driver_says_what_to_set_in_one_line(cluster, tmp_path):
    address, token, _, _ = cluster
    wrong = tmp_path / "wrong"
    wrong.write_text(secrets.token_hex(32))
    cases = [  # (the driver's environment, what the line says)
        ({}, "the cluster uses token authentication: set RAY_AUTH_MODE=token"),
        ({"RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN_PATH": str(wrong)},
         f"the cluster refuses this driver's token (read from RAY_AUTH_TOKEN_PATH, {wrong})"),
    ]
    for env, said in cases:
        done = _driver(["-m", "rrrobot_gym", *SEARCH, "--out", str(tmp_path / "out.json"), "--ray-address", address],
                       token, **env)  # fmt: skip
        # one line: refused before ray.init, which would print 20 s of warnings, then a traceback
        lines = done.stderr.strip().splitlines()
        assert done.returncode == 2 and len(lines) == 1 and said in lines[0], (env, done.stderr[-3000:])
        assert "ray get-auth-token" in lines[0] or "RAY_AUTH_MODE=token" in lines[0]
        assert not (tmp_path / "out.json").exists()
    done = _driver(["train.py", "--seeds", "2", "--bar", "1", "--ray-address", address], token)
    assert done.returncode == 2 and done.stderr.strip().splitlines()[-1].endswith(
        f"--ray-address '{address}': the cluster uses token authentication: set RAY_AUTH_MODE=token (as `ray start "
        f"--address` needs too), with the cluster's token in {gait_search.RAY_TOKEN_SOURCES}")


# ---------------------------------------------------------------- the probe, against a stand-in head


@contextlib.contextmanager
def _head_wanting(token: str):
    """A gRPC server answering the GCS's GetClusterId as a head with token authentication does:
    UNAUTHENTICATED unless the request carries ``Bearer <token>``. Its address."""
    grpc = pytest.importorskip("grpc")
    pytest.importorskip("ray")
    from ray.core.generated import gcs_service_pb2, gcs_service_pb2_grpc

    class Head(gcs_service_pb2_grpc.NodeInfoGcsServiceServicer):
        def GetClusterId(self, request, context):
            if dict(context.invocation_metadata()).get("authorization") != f"Bearer {token}":
                context.abort(grpc.StatusCode.UNAUTHENTICATED, "InvalidAuthToken")
            return gcs_service_pb2.GetClusterIdReply()

    server = grpc.server(futures.ThreadPoolExecutor(max_workers=1))
    gcs_service_pb2_grpc.add_NodeInfoGcsServiceServicer_to_server(Head(), server)
    port = server.add_insecure_port("127.0.0.1:0")
    server.start()
    try:
        yield f"127.0.0.1:{port}"
    finally:
        server.stop(None)


def _problem(monkeypatch, address, **env):
    from ray._raylet import AuthenticationTokenLoader

    for name in ("RAY_AUTH_MODE", "RAY_AUTH_TOKEN", "RAY_AUTH_TOKEN_PATH"):
        monkeypatch.delenv(name, raising=False)
    for name, value in env.items():
        monkeypatch.setenv(name, value)
    AuthenticationTokenLoader.instance().reset_cache()  # (Ray's loader keeps the token it read)
    try:
        return gait_search._ray_auth_problem(address)
    finally:
        monkeypatch.undo()
        AuthenticationTokenLoader.instance().reset_cache()


def test_the_token_probe_sends_the_token_ray_would_send_and_names_what_to_set(monkeypatch, tmp_path, capsys):
    token = secrets.token_hex(32)
    (tmp_path / "right").write_text(token)
    (tmp_path / "wrong").write_text(secrets.token_hex(32))
    with _head_wanting(token) as address:
        assert _problem(monkeypatch, address, RAY_AUTH_MODE="token", RAY_AUTH_TOKEN=token) is None
        right = str(tmp_path / "right")
        assert _problem(monkeypatch, address, RAY_AUTH_MODE="token", RAY_AUTH_TOKEN_PATH=right) is None
        # without token mode Ray sends no token to an address it is given, even one it has
        said = _problem(monkeypatch, address, RAY_AUTH_TOKEN=token)
        assert said.startswith("the cluster uses token authentication: set RAY_AUTH_MODE=token")
        said = _problem(monkeypatch, address, RAY_AUTH_MODE="token", RAY_AUTH_TOKEN_PATH=str(tmp_path / "wrong"))
        assert said.startswith(f"the cluster refuses this driver's token (read from RAY_AUTH_TOKEN_PATH, {tmp_path}")
        said = _problem(monkeypatch, address, RAY_AUTH_MODE="token", RAY_AUTH_TOKEN="x" + token)
        assert said.startswith("the cluster refuses this driver's token (read from RAY_AUTH_TOKEN)")
        said = _problem(monkeypatch, address, RAY_AUTH_MODE="token", RAY_AUTH_TOKEN_PATH=str(tmp_path / "absent"))
        assert said.startswith("RAY_AUTH_MODE=token, but the token cannot be read") and "absent" in said
        said = _problem(monkeypatch, address, RAY_AUTH_MODE="token", HOME=str(tmp_path))  # (no ~/.ray/auth_token)
        assert said.startswith("RAY_AUTH_MODE=token, but no token is set here")
        # the CLI: one line, before any work
        monkeypatch.setenv("RAY_AUTH_MODE", "token")
        monkeypatch.setenv("RAY_AUTH_TOKEN_PATH", str(tmp_path / "wrong"))
        from ray._raylet import AuthenticationTokenLoader

        AuthenticationTokenLoader.instance().reset_cache()
        try:
            assert cli.main([*SEARCH, "--out", str(tmp_path / "out.json"), "--ray-address", address]) == 2
        finally:
            AuthenticationTokenLoader.instance().reset_cache()
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert line.startswith(f"rrrobot: error: ray_address '{address}': the cluster refuses this driver's token")
    assert not (tmp_path / "out.json").exists()


def test_the_token_probe_reads_no_refusal_where_no_ray_head_answers():
    pytest.importorskip("ray")
    with socket.socket() as other:  # (something that is not a Ray head)
        other.bind(("127.0.0.1", 0))
        other.listen()
        assert gait_search._ray_auth_problem(f"127.0.0.1:{other.getsockname()[1]}") is None
