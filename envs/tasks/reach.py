"""Reach: bring the right hand's grasp point (``r_tcp``) to a target above the table."""

from __future__ import annotations

import numpy as np

from hoap_actions.envs import world
from hoap_actions.envs.core import HoapEnv
from hoap_actions.envs.tasks.base import Task

TARGET_HEIGHT = (0.03, 0.10)  # m above the table top
DISTANCE_THRESHOLD = 0.01  # m


class ReachTask(Task):
    """Targets are drawn in the work area, 3-10 cm above the table; pegs and board stand as obstacles.

    Task observation (float, m): the target position (3), then the pegs and holes
    (:meth:`~hoap_actions.envs.tasks.base.Task.scene_observation`: the obstacles move with every layout).
    achieved_goal: r_tcp position; desired_goal: the target. Success: within 1 cm.
    """

    episode_steps = 150

    def reset(self, rng: np.random.Generator) -> None:
        self.scene.apply(self.scene.sample_layout(rng))
        xy = rng.uniform(world.WORK_AREA_LOW, world.WORK_AREA_HIGH)
        self._target = np.array([xy[0], xy[1], rng.uniform(*TARGET_HEIGHT)])

    def observation(self) -> np.ndarray:
        return np.concatenate([self._target, self.scene_observation()])

    def parse_observation(self, part: np.ndarray) -> dict[str, np.ndarray | int]:
        """``target`` (3, m), ``peg_positions`` (n_pegs, 3), ``peg_quaternions`` (n_pegs, 4),
        ``hole_positions`` (N_HOLES, 3)."""
        return {"target": part[:3].copy(), **self.parse_scene_observation(part[3:])}

    def achieved_goal(self) -> np.ndarray:
        return self.robot.frame_pose("r_tcp")[0]

    def desired_goal(self) -> np.ndarray:
        return self._target.copy()

    def goal_reached(self, achieved_goal: np.ndarray, desired_goal: np.ndarray) -> np.ndarray:
        return np.linalg.norm(np.asarray(achieved_goal) - np.asarray(desired_goal), axis=-1) < DISTANCE_THRESHOLD


class ReachEnv(HoapEnv):
    """``hoap_actions/Reach-v0``: see :class:`ReachTask` and :class:`~hoap_actions.envs.core.HoapEnv`."""

    task_cls = ReachTask
