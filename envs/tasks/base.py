"""The task interface: what a goal is, how it is drawn at reset, and when it is reached."""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np

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
