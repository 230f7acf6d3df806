"""The scripted grasp-and-insert expert on PegInsert-v0 (ee_delta): success on fixed layouts, no falls.

The fast test runs the layouts of seeds 0-9 (not picked: the first ten) and asks for at least 9
successes; the slow one runs 100 layouts on seeds the expert was not tuned on and holds it to the
goal of 95 %.
"""

from __future__ import annotations

import collections

import gymnasium
import numpy as np
import pytest

from hoap_actions.apps.episodes import run_episode
from hoap_actions.errors import InvalidInputError
from hoap_actions.policies.registry import policy_class
from hoap_actions.policies.scripted_expert import ScriptedExpert, footprint_clearance, thumb_outline

FAILURE_REASONS = {"unreachable layout", "grasp slipped", "peg knocked over", "approach blocked", "timeout",
                   "finished without success"}
FIXED_LAYOUTS = range(10)  # seeds 0-9, the first ten: not picked


@pytest.fixture(scope="module")
def env():
    env = gymnasium.make("hoap_actions/PegInsert-v0", control_mode="ee_delta")
    yield env
    env.close()


def _run(env, seeds):
    policy = ScriptedExpert(env)
    return [run_episode(env, policy, seed) for seed in seeds]


def test_expert_solves_at_least_9_of_10_fixed_layouts(env):
    results = _run(env, FIXED_LAYOUTS)
    reasons = collections.Counter(r.reason for r in results)
    assert reasons["fell"] == 0, reasons
    assert sum(r.success for r in results) >= 9, reasons
    assert set(reasons) <= FAILURE_REASONS | {"success"}, reasons


@pytest.mark.slow
def test_expert_on_100_unseen_layouts(env):
    results = _run(env, range(2000, 2100))
    reasons = collections.Counter(r.reason for r in results)
    assert reasons["fell"] == 0, reasons
    assert set(reasons) <= FAILURE_REASONS | {"success"}, reasons
    assert np.mean([r.success for r in results]) >= 0.95, reasons


def test_policies_are_found_by_name_with_their_control_mode():
    assert policy_class("scripted") is ScriptedExpert and ScriptedExpert.control_mode == "ee_delta"
    assert policy_class("random").control_mode == "joint_delta"
    with pytest.raises(InvalidInputError,
                       match=r"unknown policy 'nope'; accepted: \['bc', 'imitation-camera', 'imitation-frequent', "
                             r"'imitation-markers', 'imitation-oracle', 'nothing', 'phmm', 'random', 'scripted', "
                             r"'straight'\]"):
        policy_class("nope")


def test_expert_needs_the_ee_delta_control_mode():
    joint_env = gymnasium.make("hoap_actions/PegInsert-v0")
    with pytest.raises(InvalidInputError, match="ee_delta"):
        ScriptedExpert(joint_env)
    joint_env.close()


def test_footprint_model_matches_the_hand():
    """The thumb outline at the contact closure lies parallel to the palm, 15 mm from it."""
    contact = thumb_outline(0.75)
    np.testing.assert_allclose(contact[:, 1].max(), -0.0075, atol=1e-9)  # inner face
    # a peg centred on the tcp touches neither plate; one 2 cm to the palm side is inside the palm
    assert footprint_clearance(np.array([[0.0, 0.0]]), 0.007, closure=0.75) > 0.0
    assert footprint_clearance(np.array([[0.0, 0.02]]), 0.0075, closure=0.75) < 0.0
