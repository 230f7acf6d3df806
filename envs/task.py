"""The task interface: what a goal is, how it is drawn at reset, and when it is reached."""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np

from hoap_actions.envs import scene as scene_module
from hoap_actions.envs.robot import Robot
from hoap_actions.envs.scene import Scene
from hoap_actions.envs.sim import Sim


class Task(ABC):
    """One task on the shared world; subclasses take extra keyword arguments after ``scene``."""

    episode_steps: int  # env steps (30 Hz) an episode may last: the registered time limit

    def __init__(self, sim: Sim, robot: Robot, scene: Scene) -> None:
        self.sim, self.robot, self.scene = sim, robot, scene

    @abstractmethod
    def reset(self, rng: np.random.Generator) -> None:
        """Draw and place a new layout / goal from the env's seeded generator."""

    @abstractmethod
    def observation(self) -> np.ndarray:
        """The task's part of the observation vector (documented by each task)."""

    @abstractmethod
    def parse_observation(self, part: np.ndarray) -> dict[str, np.ndarray | int]:
        """Named fields of the task's part of the observation vector."""

    @abstractmethod
    def achieved_goal(self) -> np.ndarray: ...

    @abstractmethod
    def desired_goal(self) -> np.ndarray: ...

    @abstractmethod
    def goal_reached(self, achieved_goal: np.ndarray, desired_goal: np.ndarray) -> np.ndarray:
        """Vectorised success test on goal batches (used by the sparse reward)."""

    def is_success(self) -> bool:
        """Success of the current state; tasks with more than a goal distance override it."""
        return bool(self.goal_reached(self.achieved_goal(), self.desired_goal()))

    def scene_observation(self) -> np.ndarray:
        """Where the objects are (float, m): every peg's centre (3) and quaternion (4, x y z w) in peg
        order (red, green, blue), then every hole opening's centre (3). Layouts change at each reset,
        so a policy needs this to plan around the pegs and the board (the observation stays Markov)."""
        poses = [np.concatenate(self.scene.peg_pose(i)) for i in range(self.scene.n_pegs)]
        return np.concatenate([*poses, self.scene.hole_positions().ravel()])

    def scene_observation_size(self) -> int:
        return 7 * self.scene.n_pegs + 3 * scene_module.N_HOLES

    def parse_scene_observation(self, part: np.ndarray) -> dict[str, np.ndarray]:
        """``peg_positions`` (n_pegs, 3), ``peg_quaternions`` (n_pegs, 4), ``hole_positions`` (N_HOLES, 3)
        of a :meth:`scene_observation`."""
        n, k = self.scene.n_pegs, 7 * self.scene.n_pegs
        poses = part[:k].reshape(n, 7)
        return {
            "peg_positions": poses[:, :3].copy(),
            "peg_quaternions": poses[:, 3:].copy(),
            "hole_positions": part[k: self.scene_observation_size()].reshape(scene_module.N_HOLES, 3).copy(),
        }
