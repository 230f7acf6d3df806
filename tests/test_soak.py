"""Soak: 10 000 random and 10 000 bang-bang actions in each control mode (slow; run with ``-m slow``).

Episodes are reset on ``terminated`` or ``truncated``. In every run the observations stay finite and
the process's resident memory stays flat after a warm-up. Under ``ee_delta`` and ``ee_heading_delta`` the
robot never falls: the whole-body IK keeps the centre of mass over the feet and the hand yields to balance. Under
``joint_delta`` a random waist lean may topple it (the env reports the fall and the episode is
reset). In both modes no joint ever turns faster than its servo's limit.
"""

from __future__ import annotations

import os
from pathlib import Path

import gymnasium
import numpy as np
import pytest

import hoap_actions  # noqa: F401  (registers the environments)
from hoap_actions.envs.controls import HAND_CONTROL_MODES

STEPS = 10_000
SEED = 7
WARM_UP = 1_000  # steps before the memory baseline: allocator pools and PyBullet's caches fill first
MEMORY_GROWTH_MB = 20.0  # largest RSS growth after the warm-up (flat within 0.1 MB measured); 2.5 kB a step exceeds it
SPEED_TOLERANCE = 0.01  # joint speeds may exceed the limit by 1 %: float32 observations, solver round-off
VELOCITIES = slice(28, 56)  # joint velocities in the observation vector (after the 28 joint angles)
STATM = Path("/proc/self/statm")

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(not STATM.exists(), reason="reads the resident memory from /proc (Linux)"),
]


def _resident_mb() -> float:
    """This process's resident memory (MB)."""
    return int(STATM.read_text().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


def _action(kind: str, rng: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
    if kind == "random":
        return rng.uniform(-1.0, 1.0, shape).astype(np.float32)
    return rng.choice(np.array([-1.0, 1.0], dtype=np.float32), size=shape)


@pytest.mark.parametrize("kind", ["random", "bang_bang"])
@pytest.mark.parametrize("control_mode", ["joint_delta", "ee_delta", "ee_heading_delta"])
def test_soak_10000_steps(control_mode, kind):
    env = gymnasium.make("hoap_actions/PegInsert-v0", control_mode=control_mode)
    limits = env.unwrapped.robot.max_velocity
    rng = np.random.default_rng(SEED)
    env.reset(seed=SEED)
    falls, episodes, fastest = [], 1, 0.0
    baseline = None
    for step in range(STEPS):
        if step == WARM_UP:
            baseline = _resident_mb()
        obs, _, terminated, truncated, info = env.step(_action(kind, rng, env.action_space.shape))
        assert all(np.all(np.isfinite(value)) for value in obs.values()), (
            f"NaN or inf in the observation at step {step}")
        fastest = max(fastest, float(np.max(np.abs(obs["observation"][VELOCITIES]) / limits)))
        if info["fallen"]:
            falls.append(step)
        if terminated or truncated:
            env.reset()
            episodes += 1
    growth = _resident_mb() - baseline
    env.close()

    assert episodes > STEPS // 600, f"only {episodes} episodes: the time limit should end one every 600 steps"
    assert growth < MEMORY_GROWTH_MB, f"resident memory grew {growth:.1f} MB over {STEPS - WARM_UP} steps"
    assert fastest <= 1.0 + SPEED_TOLERANCE, f"a joint reached {fastest:.3f} times its velocity limit"
    if control_mode in HAND_CONTROL_MODES:
        assert not falls, f"the robot fell at steps {falls[:10]} of {STEPS} {kind} {control_mode} actions"
