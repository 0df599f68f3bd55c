"""benchmarks.versus: its ratios from given rates, and its refusal of a CPU it cannot pin to."""

import json
import os

import pytest

from benchmarks import versus


def test_ratios_of_medians_and_round_by_round(tmp_path, monkeypatch):
    # A machine whose speed drifts between rounds: the medians' ratio (150 / 200) mixes rounds, the
    # round-by-round ratios (0.95, 0.8, 0.75) pair each run with its neighbour.
    speeds = iter([100.0, 95.0, 300.0, 240.0, 200.0, 150.0])
    seen = []

    def fake_rate(tree, num_envs, steps, backend=None, cpu=None, model=None):
        seen.append((tree == versus.HERE, cpu, model))
        return next(speeds)

    monkeypatch.setattr(versus, "rate", fake_rate)
    out = tmp_path / "v.json"
    versus.main(["HEAD", "--rounds", "3", "--steps", "2", "--json", str(out), "--cpu", str(min(os.sched_getaffinity(0))),
                 "--model", "pivot"])  # fmt: skip
    result = json.loads(out.read_text())["results"][0]
    assert [here for here, _, _ in seen] == [False, True] * 3  # alternating, the commit first
    assert {cpu for _, cpu, _ in seen} == {min(os.sched_getaffinity(0))}
    assert {model for _, _, model in seen} == {"pivot"}  # (both trees' envs on the model asked for)
    assert result["old_steps_per_s"] == 200.0 and result["new_steps_per_s"] == 150.0
    assert result["ratio"] == pytest.approx(0.75)
    assert result["paired_ratio_median"] == pytest.approx(0.8)
    assert result["paired_ratio_range"] == pytest.approx([0.75, 0.95])


def test_a_cpu_outside_the_affinity_is_refused(capsys):
    bad = max(os.sched_getaffinity(0)) + 1
    with pytest.raises(SystemExit):
        versus.main(["HEAD", "--cpu", str(bad)])
    assert "--cpu must be one of the CPUs this process may use" in capsys.readouterr().err


def test_the_env_keywords_reach_the_timed_process_as_json():
    assert versus._keywords(None) == ()
    assert json.loads(versus._keywords("numpy", "pivot")[0]) == {"backend": "numpy", "model": "pivot"}
