"""Reading a demonstration from its markers and the block's path: the naming rules on made-up decodings,
the shipped models on one drawn demonstration of each action, bad input, and the policy built on it."""

from __future__ import annotations

import json
from types import SimpleNamespace

import gymnasium
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import hoap_actions  # noqa: F401  (registers the environments)
from hoap_actions.apps.episodes import run_episode
from hoap_actions.errors import InvalidInputError
from hoap_actions.imitation.reading import LIFTED, MOVED, TURNED, read_markers
from hoap_actions.models.shipped import load_default_models
from hoap_actions.policies.imitation_policy import MarkerImitation, intent_of
from hoap_actions.policies.registry import policy_class
from hoap_actions.primitives.discovery.estimator import MANIPULATION
from hoap_actions.primitives.models.class_models import DecodedSegment

ENV_ID = "hoap_actions/Imitate-v0"
SEEDS = {"approach": 90003, "push": 90014, "move": 90006, "rotate": 90008}  # validation episodes, one per action
T = 100


class FixedDecoding:
    """Action models stand-in: class 0 an approach, 5 a manipulation; ``decode`` returns ``segments``."""

    classes_ = {0: SimpleNamespace(kind="approach"), 5: SimpleNamespace(kind=MANIPULATION)}

    def __init__(self, segments: list[DecodedSegment]) -> None:
        self.segments = segments

    def decode(self, H: np.ndarray) -> list[DecodedSegment]:
        return self.segments


def _segment(class_id: int, start: int, end: int) -> DecodedSegment:
    return DecodedSegment(class_id, start, end, np.zeros(6))


def _path(step_xy=(0.0, 0.0), lift=0.0, turn_deg=0.0) -> np.ndarray:
    """A block path resting at frames 0-39, moved over 40-59 (raised by ``lift`` at frame 50), resting after."""
    O = np.zeros((T, 6))
    O[:, 2] = 0.02
    share = np.clip((np.arange(T) - 40) / 20.0, 0.0, 1.0)
    O[:, :2] = share[:, None] * np.asarray(step_xy)
    O[:, 2] += lift * np.exp(-0.5 * ((np.arange(T) - 50) / 4.0) ** 2)
    O[:, 3:] = Rotation.from_euler("z", share[:, None] * np.radians(turn_deg)).as_rotvec()
    return O


MANIPULATED = [_segment(0, 0, 40), _segment(5, 40, 60), _segment(0, 60, T)]


@pytest.mark.parametrize("path, action", [
    (_path((0.1, 0.0), lift=2 * LIFTED), "move"),
    (_path((0.0, 0.0), turn_deg=2 * np.degrees(TURNED)), "rotate"),
    (_path((0.0, 0.05)), "push"),
    (_path((0.3 * MOVED, 0.0)), "approach"),
])
def test_the_action_is_named_by_what_the_block_did_over_the_manipulation(path, action):
    reading = read_markers(FixedDecoding(MANIPULATED), np.zeros((T, 6, 3)), path)
    assert reading.action == action
    assert reading.manipulation == (40, 60)
    assert reading.class_ids == (0, 5, 0)
    np.testing.assert_array_equal(reading.object_start, path[0])
    np.testing.assert_array_equal(reading.object_end, path[-1])


def test_a_lift_outside_the_recognised_manipulation_is_not_read_as_a_carry():
    late = [_segment(0, 0, 70), _segment(5, 70, 90), _segment(0, 90, T)]  # the block rose at frame 50
    assert read_markers(FixedDecoding(late), np.zeros((T, 6, 3)), _path((0.05, 0.0), lift=0.05)).action == "push"


def test_no_manipulation_recognised_is_an_approach_only_if_the_block_stayed():
    approach_only = [_segment(0, 0, T)]
    assert read_markers(FixedDecoding(approach_only), np.zeros((T, 6, 3)), _path()).action == "approach"
    moved = read_markers(FixedDecoding(approach_only), np.zeros((T, 6, 3)), _path((0.05, 0.0)))
    assert moved.action is None and moved.manipulation is None
    assert read_markers(FixedDecoding([]), np.zeros((T, 6, 3)), _path()).action is None


@pytest.mark.parametrize("path", [np.zeros((T - 1, 6)), np.zeros((T, 7)), np.full((T, 6), np.nan)])
def test_a_block_path_that_does_not_fit_the_markers_is_refused(path):
    with pytest.raises(InvalidInputError, match=r"\(100, 6\)"):
        read_markers(FixedDecoding(MANIPULATED), np.zeros((T, 6, 3)), path)


# ------------------------------------------------------------------ the shipped models on drawn demonstrations
@pytest.fixture(scope="module")
def env():
    env = gymnasium.make(ENV_ID, robot="fixed_legs", control_mode="ee_delta", demo_image_size=(80, 60))
    yield env
    env.close()


@pytest.fixture(scope="module")
def models():
    return load_default_models()


@pytest.mark.parametrize("action", sorted(SEEDS))
def test_the_shipped_models_read_each_action_and_its_effect(env, models, action):
    env.reset(seed=SEEDS[action])
    shown = env.get_wrapper_attr("true_demonstration")()
    reading = read_markers(models, shown.H, shown.O)
    assert shown.action == action and reading.action == action
    truth, read = intent_of(action, shown.object_start, shown.object_end), intent_of(
        reading.action, reading.object_start, reading.object_end)
    np.testing.assert_allclose(read.displacement, truth.displacement, atol=1e-3)
    assert abs(read.turn - truth.turn) < np.radians(1.0)
    if action != "approach":
        a, b = reading.manipulation
        moving = np.flatnonzero(np.linalg.norm(np.diff(shown.O[:, :3], axis=0), axis=1) > 1e-4)
        assert a <= moving[-1] and b >= moving[0]  # the recognised manipulation overlaps the block's motion


def test_the_marker_policy_is_registered_and_imitates_a_push(env):
    assert policy_class("imitation-markers", ENV_ID) is MarkerImitation
    policy = MarkerImitation(env)
    result = run_episode(env, policy, SEEDS["push"])
    assert policy.reading.action == "push"
    assert result.success, result


def test_the_imitate_command_runs_the_reading_beside_the_ceiling_and_writes_its_report(tmp_path, capsys):
    from hoap_actions.apps.cli import main

    report = tmp_path / "imitate.json"
    assert main(["imitate", "--from-markers", "--ceiling", "--episodes", "1", "--seed", str(SEEDS["push"]),
                 "--json", str(report)]) == 0
    out = capsys.readouterr().out
    assert "imitation-markers policy on hoap_actions/Imitate-v0 (fixed_legs robot): success rate 100.0%" in out
    assert "imitation-oracle policy" in out
    assert set(json.loads(report.read_text())["policies"]) == {"imitation-markers", "imitation-oracle"}
    assert main(["imitate", "--episodes", "1", "--film", "1"]) == 2
    assert "--film 1 is past the last episode" in capsys.readouterr().err
