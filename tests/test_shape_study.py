"""rrrobot shape-study: the members it studies, a small study end to end, and its refusals."""

from __future__ import annotations

import json

import pytest

from rrrobot_gym import shape_study
from rrrobot_gym.cli import main


def test_the_default_study_spans_oblate_to_prolate_and_two_to_four_legs_with_the_papers_robot_once():
    rows = shape_study.members()
    shells = [(ratio, kwargs) for _, kwargs, ratio, legs in rows if legs == 2]
    assert len(shells) >= 7 and min(r for r, _ in shells) == 0.6 and max(r for r, _ in shells) == 1.4
    assert dict(shells)[1.0] == {}  # the paper's robot, with no keyword of its own
    for ratio, kwargs in shells:
        if ratio != 1.0:
            a, b, c = kwargs["shell_axes"]
            assert a == b == shape_study.RADIUS and c == pytest.approx(ratio * a, abs=1e-12)
    assert sorted(legs for _, _, ratio, legs in rows if ratio == 1.0) == [2, 3, 4]
    assert len({label for label, *_ in rows}) == len(rows)


@pytest.mark.parametrize("kwargs, message", [
    ({"ratios": (0.1,)}, "c/a must be a number from 0.2 to 5"), ({"ratios": (1.0, 1.0)}, "repeat"),
    ({"leg_counts": (1,)}, "leg count must be a whole number from 2"), ({"leg_counts": (7,)}, "from 2 to 6"),
])  # fmt: skip
def test_bad_members_are_refused_naming_the_problem(kwargs, message):
    with pytest.raises(ValueError, match=message):
        shape_study.members(**kwargs)


def test_a_small_study_writes_its_summary_gait_files_and_figure(tmp_path, capsys):
    out = tmp_path / "study"
    assert main(["shape-study", "--out-dir", str(out), "--evaluations", "6", "--seeds", "0", "--ratios", "0.8,1",
                 "--legs", "2"]) == 0  # fmt: skip
    summary = json.loads((out / "summary.json").read_text())
    assert summary["schema"] == shape_study.SCHEMA and summary["command"].startswith("rrrobot shape-study")
    assert [m["member"] for m in summary["members"]] == ["c0.8-legs2", "c1-legs2"]
    for member in summary["members"]:
        gaits = json.loads((out / member["gait_file"]).read_text())
        best = gaits["gaits"][0]
        assert member["gait"] == best["parameters"] and member["speed_mps"] == best["robustness"]["mean_speed_mps"]
        assert gaits["used"]["evaluations"] == 6 and gaits["duration_s"] == pytest.approx(50.0)
    assert summary["members"][0]["shell_axes"] == pytest.approx([0.12, 0.12, 0.096])
    assert (out / "speed.png").stat().st_size > 10_000
    assert "wrote" in capsys.readouterr().out


def test_the_cli_refuses_a_bad_ratio_before_any_search(tmp_path, capsys):
    assert main(["shape-study", "--out-dir", str(tmp_path), "--ratios", "0.6,9"]) == 2
    assert "c/a must be a number from 0.2 to 5" in capsys.readouterr().err
    assert not (tmp_path / "summary.json").exists()


def test_every_search_starts_from_the_papers_best_gait_carried_over_to_its_legs():
    """Two legs: the paper robot's gait itself; four: legs 1 and 3 (at -90 and +90 deg, the paper's
    two) swing as the paper's and legs 2 and 4 rest upright."""
    import math

    import numpy as np

    from rrrobot_gym.gait_search import SinusoidGait

    assert tuple(shape_study.start_gait(2)) == shape_study.PAPER_GAIT
    paper, four = SinusoidGait(*shape_study.PAPER_GAIT), SinusoidGait(*shape_study.start_gait(4))
    times = np.linspace(0.0, 3.0, 31)
    np.testing.assert_array_equal(four.angles(times)[:, [0, 2]], paper.angles(times))
    np.testing.assert_array_equal(four.angles(times)[:, [1, 3]], 0.5 * math.pi)
