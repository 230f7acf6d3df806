"""Reach: bring the right hand's grasp point (``r_tcp``) to a target above the table."""

from __future__ import annotations

import numpy as np

from hoap_actions.envs import scene as scene_module
from hoap_actions.envs import world
from hoap_actions.envs.hoap_env import HoapEnv
from hoap_actions.envs.task import Task

TARGET_HEIGHT = (0.03, 0.10)  # m above the table top
DISTANCE_THRESHOLD = 0.01  # m
# Where the hand fits: the hand and thumb reach 2.1-3.0 cm below the tcp in a reach's end pose (their
# bounding boxes, 17 reaches), so a target lower than that over a peg's top or the board's is out of
# reach for any policy; Reach-v0 drew such targets. The rule is cautious (3 cm each way, no hand model):
# it redraws 46 % of v0's targets (first draws, layouts 0-999), not all of them out of reach.
HAND_DEPTH = 0.03  # m below the tcp
HAND_REACH = 0.03  # m sideways from the tcp to an obstacle's outline within which the hand is over it
MAX_TARGET_TRIES = 1000


class ReachTask(Task):
    """Targets are drawn in the work area, 3-10 cm above the table where the hand fits (not lower than
    :data:`HAND_DEPTH` above a peg or the board within :data:`HAND_REACH` of the target); pegs and board
    stand as obstacles.

    Task observation (float, m): the target position (3), then the pegs and holes
    (:meth:`~hoap_actions.envs.task.Task.scene_observation`: the obstacles move with every layout).
    achieved_goal: r_tcp position; desired_goal: the target. Success: within 1 cm.
    """

    episode_steps = 150

    def reset(self, rng: np.random.Generator) -> None:
        layout = self.scene.sample_layout(rng)
        self.scene.apply(layout)
        for _ in range(MAX_TARGET_TRIES):
            xy = rng.uniform(world.WORK_AREA_LOW, world.WORK_AREA_HIGH)
            target = np.array([xy[0], xy[1], rng.uniform(*TARGET_HEIGHT)])
            if hand_fits(target, layout):
                self._target = target
                return
        raise RuntimeError(f"no target where the hand fits in {MAX_TARGET_TRIES} draws; the work area is too crowded")

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


def hand_fits(target: np.ndarray, layout: scene_module.Layout) -> bool:
    """Whether the hand can hold its tcp at ``target`` (m) above the standing pegs and the board of ``layout``."""
    obstacles = [(scene_module.distance_to_board(target[:2], np.array(layout.board_xy), layout.board_yaw),
                  scene_module.BOARD_SIZE[2])]
    obstacles += [(np.hypot(*(target[:2] - np.array(xy))) - scene_module.PEG_RADIUS, scene_module.PEG_LENGTH)
                  for xy in layout.peg_xy]
    return all(distance >= HAND_REACH or target[2] >= top + HAND_DEPTH for distance, top in obstacles)


class ReachEnv(HoapEnv):
    """``hoap_actions/Reach-v1``: see :class:`ReachTask` and :class:`~hoap_actions.envs.hoap_env.HoapEnv`."""

    task_cls = ReachTask
