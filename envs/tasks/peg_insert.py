"""PegInsert: put a given peg into a given hole of the board."""

from __future__ import annotations

import numpy as np

from hoap_actions.envs import scene as scene_module
from hoap_actions.envs.hoap_env import HoapEnv
from hoap_actions.envs.robot import Robot
from hoap_actions.envs.scene import Scene
from hoap_actions.envs.sim import Sim
from hoap_actions.envs.task import Task
from hoap_actions.errors import InvalidInputError

MIN_INSERTION_DEPTH = 0.01  # m: the peg bottom must be this far below the board surface


class PegInsertTask(Task):
    """A layout is drawn at every reset; the target peg and hole are drawn too unless fixed by keyword.

    Task observation (float, m): every peg's centre (3) and quaternion (4, x y z w), in peg order
    (red, green, blue); every hole opening's centre (3); a one-hot of the target peg; a one-hot of
    the target hole. achieved_goal: the target peg's bottom centre; desired_goal: the target hole's
    bottom centre (on the table top).
    Success (``info["is_success"]``): the peg's bottom is inside the hole's square, at least 1 cm
    below the board surface, and the peg is upright within 10 degrees. The sparse reward uses the
    goal vectors alone (bottom within the hole's inscribed circle and 1 cm deep), so it can be
    recomputed for relabelled goals.
    """

    episode_steps = 600

    def __init__(self, sim: Sim, robot: Robot, scene: Scene, peg: int | None = None, hole: int | None = None) -> None:
        super().__init__(sim, robot, scene)
        for label, value, count in (("peg", peg, scene.n_pegs), ("hole", hole, scene_module.N_HOLES)):
            if value is not None and not (isinstance(value, (int, np.integer)) and 0 <= value < count):
                raise InvalidInputError(f"{label}={value!r}; accepted: None (drawn at reset) or an int in "
                                        f"0..{count - 1}")
        self._fixed_peg, self._fixed_hole = peg, hole

    def reset(self, rng: np.random.Generator) -> None:
        layout = self.scene.sample_layout(rng)
        self.scene.apply(layout)
        self.peg = self._fixed_peg if self._fixed_peg is not None else int(rng.integers(self.scene.n_pegs))
        self.hole = self._fixed_hole if self._fixed_hole is not None else layout.hole_of_peg[self.peg]
        self._hole_bottom = self.scene.hole_positions()[self.hole] * np.array([1.0, 1.0, 0.0])
        self._targets_one_hot = np.concatenate([np.eye(self.scene.n_pegs)[self.peg],
                                                np.eye(scene_module.N_HOLES)[self.hole]])

    def observation(self) -> np.ndarray:
        return np.concatenate([self.scene_observation(), self._targets_one_hot])

    def parse_observation(self, part: np.ndarray) -> dict[str, np.ndarray | int]:
        """``peg_positions`` (n_pegs, 3), ``peg_quaternions`` (n_pegs, 4), ``hole_positions``
        (N_HOLES, 3), and the indices ``target_peg`` and ``target_hole`` of the one-hots."""
        n, end = self.scene.n_pegs, self.scene_observation_size()
        return {
            **self.parse_scene_observation(part),
            "target_peg": int(np.argmax(part[end: end + n])),
            "target_hole": int(np.argmax(part[end + n:])),
        }

    def achieved_goal(self) -> np.ndarray:
        centre, quat = self.scene.peg_pose(self.peg)
        qx, qy, qz, qw = quat
        axis = np.array([2 * (qx * qz + qw * qy), 2 * (qy * qz - qw * qx), 1 - 2 * (qx * qx + qy * qy)])
        return centre - 0.5 * scene_module.PEG_LENGTH * axis

    def desired_goal(self) -> np.ndarray:
        return self._hole_bottom.copy()

    def goal_reached(self, achieved_goal: np.ndarray, desired_goal: np.ndarray) -> np.ndarray:
        delta = np.asarray(achieved_goal) - np.asarray(desired_goal)
        inside = np.linalg.norm(delta[..., :2], axis=-1) <= scene_module.HOLE_SIZE / 2
        deep = delta[..., 2] <= self.scene.board_surface_z - MIN_INSERTION_DEPTH
        return inside & deep

    def is_success(self) -> bool:
        return self.scene.peg_in_hole(self.peg, self.hole, min_depth=MIN_INSERTION_DEPTH)


class PegInsertEnv(HoapEnv):
    """``hoap_actions/PegInsert-v0``: see :class:`PegInsertTask` and :class:`~hoap_actions.envs.hoap_env.HoapEnv`."""

    task_cls = PegInsertTask
