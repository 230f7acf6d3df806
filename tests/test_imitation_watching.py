"""Watching a demonstration through its camera: the carry test's geometry, and the whole reading on one
validation episode of each action (slow: each renders some 400 frames)."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest

import hoap_actions  # noqa: F401  (registers the environments)
from hoap_actions.demonstration.scene import DEMONSTRATOR_CAMERA
from hoap_actions.errors import InvalidInputError
from hoap_actions.imitation.demonstrations import Demonstration
from hoap_actions.imitation.watching import REST_FRAMES, carried_shift, watch
from hoap_actions.models.shipped import load_default_models
from hoap_actions.policies.imitation_policy import intent_of

SEEDS = {"approach": 90003, "push": 90014, "move": 90006, "rotate": 90008}  # validation episodes, one per action


def _away() -> np.ndarray:
    away = (np.asarray(DEMONSTRATOR_CAMERA.target) - np.asarray(DEMONSTRATOR_CAMERA.eye))[:2]
    return away / np.linalg.norm(away)


def _slide(offsets: np.ndarray) -> np.ndarray:
    """Centres resting, sliding 10 cm across the camera's view with ``offsets`` (m, away from it), resting."""
    across = np.array([-_away()[1], _away()[0]])
    share = np.concatenate([np.zeros(REST_FRAMES), np.linspace(0.0, 1.0, len(offsets)), np.ones(REST_FRAMES)])
    bump = np.concatenate([np.zeros(REST_FRAMES), offsets, np.zeros(REST_FRAMES)])
    return share[:, None] * 0.1 * across + bump[:, None] * _away()


def test_the_carry_shift_is_the_furthest_a_seen_centre_went_beyond_the_path_away_from_the_camera():
    offsets = 0.07 * np.sin(np.linspace(0.0, np.pi, 30))
    assert carried_shift(_slide(offsets), DEMONSTRATOR_CAMERA) == pytest.approx(offsets.max(), abs=1e-9)
    towards = carried_shift(_slide(-offsets), DEMONSTRATOR_CAMERA)  # towards the camera: not raised
    assert towards == pytest.approx(0.0, abs=1e-9)
    hidden = _slide(offsets)
    hidden[REST_FRAMES:REST_FRAMES + 30] = np.nan  # the hand over the block while it moves
    assert carried_shift(hidden, DEMONSTRATOR_CAMERA) == pytest.approx(0.0, abs=1e-9)


def test_frames_of_another_size_are_refused():
    camera = DEMONSTRATOR_CAMERA
    frames = np.zeros((2 * REST_FRAMES, camera.height + 1, camera.width, 3), np.uint8)
    shown = Demonstration(frames, camera, 100.0, np.zeros((camera.height, camera.width, 3), np.uint8))
    with pytest.raises(InvalidInputError, match="frames"):
        watch(load_default_models(), shown)


@pytest.mark.slow
@pytest.mark.parametrize("action", sorted(SEEDS))
def test_a_watched_demonstration_gives_the_action_and_the_effect_on_the_robots_table(action):
    env = gymnasium.make("hoap_actions/Imitate-v0", robot="fixed_legs", control_mode="ee_delta")
    try:
        env.reset(seed=SEEDS[action])
        truth = env.get_wrapper_attr("true_demonstration")()
        watched = watch(load_default_models(), env.get_wrapper_attr("demonstration")())
    finally:
        env.close()
    reading = watched.reading
    assert truth.action == action and reading.action == action
    shown = intent_of(action, truth.object_start, truth.object_end)
    seen = intent_of(reading.action, reading.object_start, reading.object_end)
    np.testing.assert_allclose(seen.displacement, shown.displacement, atol=2e-3)  # m, robot table
    assert abs(np.angle(np.exp(4j * (seen.turn - shown.turn))) / 4.0) < np.radians(5.0)
    assert len(watched.frames) == len(truth.H)


def test_a_demonstration_without_a_block_in_view_is_not_recognised():
    """A table filmed without a person or a block: the watcher reads no action (the camera policy then ends
    its episode "not recognised" instead of acting on a guess)."""
    camera = DEMONSTRATOR_CAMERA
    empty = np.full((camera.height, camera.width, 3), 200, np.uint8)
    empty[camera.height // 2:] = (150, 110, 70)  # the table's edge: an image with edges, as a camera gives
    shown = Demonstration(np.repeat(empty[None], 2 * REST_FRAMES + 5, axis=0), camera, 100.0, empty)
    watched = watch(load_default_models(), shown, particles=50)
    assert watched.reading.action is None
    assert np.isnan(watched.reading.object_start).all()
