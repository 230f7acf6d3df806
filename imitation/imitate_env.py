"""``hoap_actions/Imitate-v0``: watch a person do something to a block on their table, then do the same
to the block on the robot's table.

Each reset draws a demonstration from the reset's seed (:mod:`~hoap_actions.imitation.demonstrations`),
or replays one from a recording (``options={"demonstration": (path, episode)}``), and lays out the
robot's table: its block (a 2 cm yellow cube) where the person's started, mapped by the project's one
human-to-robot map (:func:`hoap_actions.envs.world.human_to_robot`), or elsewhere (``level="shifted"``),
and the pegs and the board away from the block's way. What counts as success is
:mod:`~hoap_actions.imitation.goals`.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Sequence
from typing import Any

import numpy as np

from hoap_actions.demonstration.bodies import DEMONSTRATORS
from hoap_actions.envs import scene as scene_module
from hoap_actions.envs import world
from hoap_actions.envs.camera import check_image_size
from hoap_actions.envs.hoap_env import DENSE_DISTANCE_CAP, FALL_PENALTY_STEPS, HoapEnv, _fallen
from hoap_actions.envs.robot import Robot
from hoap_actions.envs.scene import Scene
from hoap_actions.envs.sim import Sim
from hoap_actions.envs.task import Task
from hoap_actions.errors import EnvClosedError, InvalidInputError, ResetNeededError
from hoap_actions.imitation import goals
from hoap_actions.imitation.demonstrations import Demonstration, DemonstrationWorld, ShownEpisode

__all__ = ["BLOCK_SIZE", "LEVELS", "ImitateEnv", "ImitateTask", "draw_layout"]

logger = logging.getLogger(__name__)

LEVELS = ("mapped", "shifted")
BLOCK = "block"  # the body's name in the robot's world
BLOCK_SIZE = 0.02  # m: the 36 mm open hand closes on it with 8 mm to spare a side; a peg is 15 mm across
BLOCK_MASS = 0.0064  # kg, wood (0.8 g/cm^3)
BLOCK_FRICTION = 1.0  # as the pegs': the hand holds by friction (PyBullet multiplies: 0.5 on the table)
BLOCK_COLOUR = (0.95, 0.80, 0.10, 1.0)  # yellow: none of the pegs' red, green, blue nor the board's
DEMO_OBJECT_SIZE = 0.05  # m, the edge of demo_object.urdf, scaled down to BLOCK_SIZE
PARKED_XY = (0.18, -0.20)  # m, where the block waits before the first reset (a corner of the table)
SHIFT_MIN = 0.02  # m, a shifted block starts at least this far from where the mapped one would
SHIFTED_YAW = np.pi / 4  # rad, a shifted block's start yaw is drawn within +- this (a cube's quarter turn)
PATH_CLEARANCE = 0.04  # m, pegs and board stay this far from the block's way (centre path grown by its half diagonal)
LAYOUT_LOW = np.array([-0.05, -0.18])  # m, (x, y) corner of where the pegs stand
LAYOUT_HIGH = np.array([0.17, 0.18])
BOARD_LOW = np.array([-0.02, -0.19])  # m, board centres: its half diagonal (5.9 cm) inside the table whatever its yaw
BOARD_HIGH = np.array([0.16, 0.19])
MAX_LAYOUT_TRIES = 2000
_HALF_DIAGONAL = BLOCK_SIZE / np.sqrt(2.0)


def _yaw_quaternion(yaw: float) -> np.ndarray:
    return np.array([0.0, 0.0, np.sin(yaw / 2.0), np.cos(yaw / 2.0)])


def _segment_distance(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance (m) of points (N, 2) from the segment a-b in the table plane."""
    ab = b - a
    t = np.clip((points - a) @ ab / max(float(ab @ ab), 1e-12), 0.0, 1.0)
    return np.linalg.norm(points - (a + t[:, None] * ab), axis=1)


def draw_layout(rng: np.random.Generator, start_xy: np.ndarray, end_xy: np.ndarray, n_pegs: int) -> scene_module.Layout:
    """Pegs and board drawn over the table (not only the work area) clear of the block's way from
    ``start_xy`` to ``end_xy`` (m) by :data:`PATH_CLEARANCE`, no peg where the forearm comes down on the
    block, pegs apart and off the board as :meth:`Scene.sample_layout` has them. Rejection sampling
    whose draws depend only on ``rng``."""
    start, end = np.asarray(start_xy, float), np.asarray(end_xy, float)
    way = start + np.linspace(0.0, 1.0, 5)[:, None] * (end - start)
    keep_off = PATH_CLEARANCE + _HALF_DIAGONAL
    for _ in range(MAX_LAYOUT_TRIES):
        board = rng.uniform(BOARD_LOW, BOARD_HIGH)
        yaw = float(rng.uniform(*scene_module.BOARD_YAW_RANGE))
        if min(scene_module.distance_to_board(p, board, yaw) for p in way) < keep_off:
            continue
        pegs: list[np.ndarray] = []
        for _ in range(50 * n_pegs):
            xy = rng.uniform(LAYOUT_LOW, LAYOUT_HIGH)
            if (_segment_distance(xy[None], start, end)[0] >= keep_off + scene_module.PEG_RADIUS
                    and scene_module.distance_to_board(xy, board, yaw) >= scene_module.MIN_PEG_BOARD_GAP
                    and all(np.hypot(*(xy - other)) >= scene_module.MIN_PEG_SPACING for other in pegs)
                    and not any(scene_module.in_forearm_strip(xy, p) for p in way)):
                pegs.append(xy)
                if len(pegs) == n_pegs:
                    return scene_module.Layout(
                        board_xy=(float(board[0]), float(board[1])), board_yaw=yaw,
                        peg_xy=tuple((float(x), float(y)) for x, y in pegs),
                        hole_of_peg=tuple(int(j) for j in rng.permutation(scene_module.N_HOLES)[:n_pegs]),
                    )
    raise RuntimeError(f"no layout clear of the block's way in {MAX_LAYOUT_TRIES} board draws")


class ImitateTask(Task):
    """The robot's table carries a free block (:data:`BLOCK_SIZE` cube, yellow) besides the pegs and board.

    ``level="mapped"``: the block starts where the person's started, mapped to the robot's table; its
    target is the person's block's end, mapped. ``level="shifted"``: it starts elsewhere in the work area
    (at least :data:`SHIFT_MIN` away, any yaw), and its target is its own start moved by the demonstrated
    displacement (mapped: scaled by ``world.HUMAN_TO_ROBOT_SCALE``) and turned by the demonstrated turn
    about the vertical. An approach's target is the block itself: the hand points at it (its tcp's x y
    over the block's centre), the block stays put. ``demonstrator`` (a name of ``DEMONSTRATORS``) fixes who
    demonstrates; None draws one. ``demo_image_size`` (width, height) px is the demonstration camera's.

    Task observation (float): the block's centre (3, m) and quaternion (4, x y z w), then the pegs and
    holes (:meth:`~hoap_actions.envs.task.Task.scene_observation`). Goals: :mod:`~hoap_actions.imitation.goals`.
    """

    episode_steps = 600

    def __init__(self, sim: Sim, robot: Robot, scene: Scene, level: str = "mapped", demonstrator: str | None = None,
                 demo_image_size: tuple[int, int] = (320, 240)) -> None:
        super().__init__(sim, robot, scene)
        if level not in LEVELS:
            raise InvalidInputError(f"level={level!r} is not a level; accepted: {list(LEVELS)}")
        if demonstrator is not None and demonstrator not in DEMONSTRATORS:
            raise InvalidInputError(f"demonstrator={demonstrator!r}; accepted: None (drawn at reset) or one of "
                                    f"{sorted(DEMONSTRATORS)}")
        try:
            width, height = demo_image_size
        except (TypeError, ValueError):
            raise InvalidInputError(f"demo_image_size must be (width, height) in pixels; got {demo_image_size!r}") \
                from None
        check_image_size(width, height, what="demonstration")
        self.level, self.demonstrator, self.demo_image_size = level, demonstrator, (int(width), int(height))
        sim.load_urdf(BLOCK, "demo_object.urdf", (*PARKED_XY, BLOCK_SIZE / 2.0), scale=BLOCK_SIZE / DEMO_OBJECT_SIZE)
        sim.set_color(BLOCK, BLOCK_COLOUR)
        sim.set_dynamics(BLOCK, mass=BLOCK_MASS, localInertiaDiagonal=[BLOCK_MASS * BLOCK_SIZE**2 / 6.0] * 3,
                         lateralFriction=BLOCK_FRICTION)
        self.world = DemonstrationWorld()
        self._sized = False
        self.shown: ShownEpisode | None = None
        self._replay: ShownEpisode | None = None
        self._rendered: Demonstration | None = None
        self._desired = goals.goal_vector(np.zeros(3), _yaw_quaternion(0.0), np.zeros(2), False)
        self._approach = False
        self._start = np.r_[PARKED_XY, BLOCK_SIZE / 2.0, _yaw_quaternion(0.0)]

    # ------------------------------------------------------------------ episodes
    def replay_next(self, shown: ShownEpisode | None) -> None:
        """Show ``shown`` at the next reset instead of drawing a demonstration (None: draw one)."""
        self._replay = shown

    def reset(self, rng: np.random.Generator) -> None:
        if not self._sized:  # the env's constructor sizing the observation: no demonstration yet
            self._sized = True
            self.scene.apply(self.scene.sample_layout(rng))
            return
        shown, self._replay, self._rendered = self._replay, None, None
        self.shown = shown if shown is not None else self.world.perform(rng, self.demonstrator)
        start_h, end_h = self.shown.object_start, self.shown.object_end
        self._approach = self.shown.action == "approach"
        mapped_start = world.human_to_robot(start_h[:3])[:2]
        move = world.HUMAN_TO_ROBOT_SCALE * (end_h[:2] - start_h[:2])
        turn = goals.block_turn(start_h, end_h)
        if self._approach:
            move, turn = np.zeros(2), 0.0
        if self.level == "mapped":
            start_xy, start_yaw = mapped_start, goals.yaw_of(start_h[3:])
        else:
            start_xy, start_yaw = self._shifted_start(rng, mapped_start, move), float(rng.uniform(-SHIFTED_YAW,
                                                                                                    SHIFTED_YAW))
        end_xy = start_xy + move
        self.scene.apply(draw_layout(rng, start_xy, end_xy, self.scene.n_pegs))
        start_quaternion = _yaw_quaternion(start_yaw)
        self.sim.set_base_pose(BLOCK, (*start_xy, BLOCK_SIZE / 2.0), start_quaternion)
        self._start = np.r_[start_xy, BLOCK_SIZE / 2.0, start_quaternion]
        self._desired = goals.goal_vector(np.r_[end_xy, BLOCK_SIZE / 2.0], _yaw_quaternion(start_yaw + turn),
                                          start_xy if self._approach else np.zeros(2), self._approach)
        self._effect = {"displacement_m": move / world.HUMAN_TO_ROBOT_SCALE, "rotation_rad": turn}

    @staticmethod
    def _shifted_start(rng: np.random.Generator, mapped_start: np.ndarray, move: np.ndarray) -> np.ndarray:
        """A start in the work area, :data:`SHIFT_MIN` or more from ``mapped_start``, from which ``move`` ends
        in the work area too."""
        low = np.maximum(world.WORK_AREA_LOW, world.WORK_AREA_LOW - move)
        high = np.minimum(world.WORK_AREA_HIGH, world.WORK_AREA_HIGH - move)
        while True:  # the excluded disc is far smaller than the area: a few draws at most
            xy = rng.uniform(low, high)
            if np.hypot(*(xy - mapped_start)) >= SHIFT_MIN:
                return xy

    def settled(self) -> None:
        """Note the block's pose once it rests (after the env's settling steps): an approached block must
        not move from there."""
        if self.shown is None:
            return
        position, quaternion = self.sim.base_pose(BLOCK)
        self._start = np.r_[position, quaternion]
        if self._approach:
            self._desired = goals.goal_vector(position, quaternion, self._desired[7:9], True)

    def demonstration(self) -> Demonstration:
        if self.sim.closed:
            raise EnvClosedError("demonstration() called on a closed environment; create a new one with gymnasium.make")
        if self.shown is None:
            raise ResetNeededError("no demonstration yet: call reset() first")
        if self._rendered is None:
            self._rendered = self.world.render(self.shown, *self.demo_image_size)
        return self._rendered

    def truth(self) -> dict[str, Any]:
        """What an evaluation needs and a policy must not see (``info["demonstration_truth"]``)."""
        shown = self.shown
        achieved = self.achieved_goal()
        errors = {key: float(value) for key, value in goals.goal_errors(achieved, self._desired).items()}
        return {
            "source": shown.source, "level": self.level, "demonstrator": shown.demonstrator,
            "action": shown.action, "direction": shown.direction, "distance_m": shown.distance,
            "angle_rad": shown.angle, "human_block_start": shown.object_start.copy(),
            "human_block_end": shown.object_end.copy(),
            "effect": {key: np.copy(value) for key, value in self._effect.items()},
            "robot_block_start": self._start.copy(), "robot_block_target": self._desired[:7].copy(),
            "robot_block_end": achieved[:7].copy(),
            "point_target": self._desired[7:9].copy() if self._approach else None,
            "position_error_m": errors["position_error"], "angle_error_rad": errors["angle_error"],
            "point_error_m": errors["point_error"], "markers": shown.H.copy(), "labels": shown.labels.copy(),
            "phase_names": shown.phase_names, "fps": shown.fps,
        }

    # ------------------------------------------------------------------ observation and goals
    def observation(self) -> np.ndarray:
        position, quaternion = self.sim.base_pose(BLOCK)
        return np.concatenate([position, quaternion, self.scene_observation()])

    def parse_observation(self, part: np.ndarray) -> dict[str, np.ndarray | int]:
        """``block_position`` (3, m), ``block_quaternion`` (4, x y z w), then the pegs and holes."""
        return {"block_position": part[:3].copy(), "block_quaternion": part[3:7].copy(),
                **self.parse_scene_observation(part[7:])}

    def achieved_goal(self) -> np.ndarray:
        position, quaternion = self.sim.base_pose(BLOCK)
        return goals.goal_vector(position, quaternion, self.robot.frame_pose("r_tcp")[0][:2], self._approach)

    def desired_goal(self) -> np.ndarray:
        return self._desired.copy()

    def goal_reached(self, achieved_goal: np.ndarray, desired_goal: np.ndarray) -> np.ndarray:
        return goals.goal_reached(achieved_goal, desired_goal)

    def is_success(self) -> bool:
        """The goal reached (:func:`~hoap_actions.imitation.goals.goal_reached`) and the robot standing."""
        return bool(self.shown is not None and super().is_success() and not self.robot.has_fallen())


class ImitateEnv(HoapEnv):
    """``hoap_actions/Imitate-v0``: see :class:`ImitateTask` and :class:`~hoap_actions.envs.hoap_env.HoapEnv`.

    ``reset(seed=..., options={"demonstration": (path, episode)})`` replays that recording's episode
    instead of drawing one. :meth:`demonstration` gives the policy what a person would: the camera's
    frames, its pose and intrinsics, the frame rate. ``info["demonstration_truth"]`` (what was shown, the
    block's and hand's errors, the markers) comes only on the step that ends the episode: when it
    terminates, or on the registered time limit's last step (``ImitateTask.episode_steps``).

    Rewards as the other tasks: sparse 0 on success else -1; dense minus
    :func:`~hoap_actions.imitation.goals.goal_distance` (at most 1); a fall costs a whole episode.
    ``desired_goal`` holds the mapped target for goal-conditioned learners (HER): a policy that imitates
    must read the demonstration, not it.
    """

    task_cls = ImitateTask
    task: ImitateTask
    ik_periods = {"full": 4, "fixed_legs": 1}
    """The welded robot's hand IK every tick here (the other envs: every 4): the block skills' servoed pushes
    lost to 4 ticks, paired on held-out Imitate 94450-94649, execution ceiling 178 -> 163 of 200
    (``docs/experiments/imitation.md``)."""
    robot_stances = {"full": world.FIXED_LEGS_FEET_XY}
    """The free-standing robot stands where the welded one does (3 cm further back, 5 cm further left than
    in the peg task): there its hand is headed as the welded robot's over the block area (3 degrees at the
    centre, not 21), within the thumb's reach of a face for most targets; on validation demonstrations
    90000-90099 its execution ceiling went 76 -> 91 of 100 (``docs/experiments/imitation.md``)."""

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        replay = self._replay_option(options)
        if replay is not None:
            self.task.replay_next(self.task.world.replay(*replay))
        try:
            super().reset(seed=seed)
        finally:
            self.task.replay_next(None)  # a replay is for this reset only, even an interrupted one
        self.task.settled()
        self._steps = 0
        return self._observation(), self._info()

    @staticmethod
    def _replay_option(options: dict | None) -> tuple[str | os.PathLike, int] | None:
        if not options:
            return None
        if not isinstance(options, dict) or set(options) != {"demonstration"}:
            raise InvalidInputError(f"reset takes options={{'demonstration': (path, episode)}} or none; got "
                                    f"{options!r}")
        value = options["demonstration"]
        if not (isinstance(value, (tuple, list)) and len(value) == 2 and isinstance(value[0], (str, os.PathLike))):
            raise InvalidInputError(f"options['demonstration'] must be (path of a recording, episode index); got "
                                    f"{value!r}")
        return value[0], value[1]

    def step(self, action: np.ndarray) -> tuple[dict, float, bool, bool, dict]:
        obs, reward, terminated, truncated, info = super().step(action)
        self._steps += 1
        if terminated or truncated or self._steps >= self.task_cls.episode_steps:
            info["demonstration_truth"] = self.task.truth()
        return obs, reward, terminated, truncated, info

    def demonstration(self) -> Demonstration:
        """This episode's demonstration as the camera filmed it (rendered at the first call, then kept)."""
        return self.task.demonstration()

    def true_demonstration(self) -> ShownEpisode:
        """The oracle: what this episode's demonstration truly was (action, block start and end, markers).
        For evaluation and the execution-ceiling baseline only; a policy that imitates must not call it."""
        if self.task.shown is None:
            raise ResetNeededError("no demonstration yet: call reset() first")
        return self.task.shown

    def compute_reward(self, achieved_goal: np.ndarray, desired_goal: np.ndarray,
                       info: dict | Sequence[dict] | None) -> np.ndarray:
        if self.reward_type == "sparse":
            return super().compute_reward(achieved_goal, desired_goal, info)
        achieved_goal, desired_goal = np.asarray(achieved_goal), np.asarray(desired_goal)
        if achieved_goal.shape[-1:] != (goals.GOAL_SIZE,) or desired_goal.shape[-1:] != (goals.GOAL_SIZE,):
            raise InvalidInputError(f"goals must end in this env's goal width {goals.GOAL_SIZE}; got achieved_goal "
                                    f"{achieved_goal.shape} and desired_goal {desired_goal.shape}")
        reward = -np.minimum(goals.goal_distance(achieved_goal, desired_goal), DENSE_DISTANCE_CAP)
        fallen = _fallen(info, np.shape(reward))
        return np.where(fallen, -FALL_PENALTY_STEPS * float(self.task_cls.episode_steps), reward).astype(np.float32)

    def close(self) -> None:
        task = getattr(self, "task", None)
        if task is not None:
            task.world.close()
        super().close()
