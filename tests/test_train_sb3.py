"""examples/train_sb3.py (needs the rl extra): a saved policy evaluates as it did in training; bad options."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("stable_baselines3")
SCRIPT = Path(__file__).resolve().parents[1] / "examples" / "train_sb3.py"


def run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(SCRIPT), *args], capture_output=True, text=True, timeout=600)


@pytest.mark.parametrize("learner, robot", [("sb3", "full"), ("sbx", "fixed_legs")])
def test_saved_policy_evaluates_as_in_training_and_demonstrations_fill_the_warm_up(tmp_path, learner, robot):
    """The straight-line reference takes the first steps (its episodes succeed); the policy saved after training,
    evaluated again from disk with its frozen statistics (and its learner and robot), ends every layout where the
    in-training evaluation did."""
    if learner == "sbx":
        pytest.importorskip("sbx")
    curve, saved = tmp_path / "curve.json", tmp_path / "policy"
    common = ["--normalize", "--eval-first-seed", "70010", "--eval-episodes", "2"]
    done = run(*common, "--steps", "400", "--demo-steps", "300", "--eval-every", "400", "--fields", "tcp_position",
               "target", "--learner", learner, "--robot", robot, "--save", str(saved), "--json", str(curve))
    assert done.returncode == 0, done.stderr
    document = json.loads(curve.read_text())
    assert document["demo_steps"] == 300 and document["algorithm"] == "SAC + HER"
    assert (document["learner"], document["robot"]) == (learner, robot)
    point = document["curve"][-1]
    assert point["training_success_last_100"] > 0  # uniform random actions reach nothing in 400 steps
    again = tmp_path / "again.json"
    done = run(*common, "--evaluate", str(saved), "--json", str(again))
    assert done.returncode == 0, done.stderr
    assert json.loads(again.read_text())["final_distance_m"] == point["final_distance_m"]
    done = run(*common, "--evaluate", str(saved), "--json", str(again))  # never overwritten unless asked
    assert done.returncode == 2 and "exists" in done.stderr


@pytest.mark.parametrize("args, message", [
    (["--demo-steps", "10", "--env", "hoap_actions/PegInsert-v0"], "straight-line reach"),
    (["--steps", "100", "--demo-steps", "100"], "--demo-steps in"),
    (["--gamma", "1.0"], "--gamma in"),
    (["--fields", "elbow"], "accepted:"),
    (["--evaluate", "/nonexistent/policy"], "holds no policy saved by --save"),
])
def test_bad_options_end_in_one_line_and_status_2(args, message):
    done = run(*args)
    assert done.returncode == 2 and message in done.stderr and len(done.stderr.strip().splitlines()) == 1
