"""``HoapEnv``: the one Gymnasium class joining a :class:`Sim`, the robot, the scene and a task.

Each concrete environment is this class plus a :class:`~hoap_actions.envs.task.Task`. Resets
restore a PyBullet snapshot taken once after loading (never reload), so the same seed gives the
same episode bit for bit.
"""

from __future__ import annotations

import inspect
import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any, ClassVar

import gymnasium
import numpy as np
from gymnasium import spaces

from hoap_actions.controllers.hand_control import RobotDescription
from hoap_actions.envs.camera import Camera, check_image_size
from hoap_actions.envs.controls import CONTROL_MODES, HAND_CONTROL_MODES, IK_PERIOD, make_controller
from hoap_actions.envs.robot import ROBOT_MODELS, Robot
from hoap_actions.envs.scene import Scene
from hoap_actions.envs.sim import Sim
from hoap_actions.envs.task import Task
from hoap_actions.errors import EnvClosedError, EnvCopyError, InvalidInputError, ResetNeededError
from hoap_actions.seeds import check_seed

logger = logging.getLogger(__name__)

PHYSICS_STEPS_PER_ACTION = 8  # 240 Hz physics, 30 Hz actions
SETTLE_STEPS = 24  # physics steps after placing a layout, so objects rest before the first observation
SOLVER_ITERATIONS = {"full": 50, "fixed_legs": 10}
"""Constraint-solver iterations per physics step, by robot model. The free-standing robot keeps
PyBullet's 50: its standing depends on stiff foot contacts. With welded legs, 10 make a PegInsert
physics step 1.5x cheaper (196 -> 132 us) and the policies solve as many validation layouts
(61000-61049: scripted 50/50 at 10, 20 and 50 iterations; PHMM 48, 49, 49)."""


_NO_COPIES = ("a hoap_actions env owns its PyBullet client, which a copy or a pickle would share with it (or with "
              "whatever env holds the same client number in another process); make another env instead: "
              "gymnasium.make(env.spec), and reset it with the same seed for the same episode")

DENSE_DISTANCE_CAP = 1.0  # m: a dense step's reward is at least -1, as a sparse one's
FALL_PENALTY_STEPS = 1.0  # a fall costs this many episodes' worth of the worst step reward (-1 each)


def _fallen(info: dict | Sequence[dict] | None, shape: tuple[int, ...]) -> np.ndarray:
    """The ``fallen`` flags of one info dict or of one dict per goal, broadcast to ``shape``."""
    if info is None:
        return np.zeros(shape, dtype=bool)
    if isinstance(info, dict):
        return np.full(shape, bool(info.get("fallen", False)))
    return np.array([bool(i.get("fallen", False)) for i in np.ravel(info)], dtype=bool).reshape(shape)


@dataclass(frozen=True)
class CameraView:
    """What a camera delivers to a policy: ``rgb`` (H, W, 3) uint8, ``depth`` (H, W) metres along the
    view axis, and the ``camera`` (pose and intrinsics) that took them; never the simulator's
    segmentation, which is ground truth."""

    rgb: np.ndarray
    depth: np.ndarray
    camera: Camera


@dataclass(frozen=True)
class HandStatus:
    """The ee_delta hand controller's state, as a robot's controller would report it: the smoothed
    hand ``reference`` (3, m) the IK tracks, whether the IK has ``unreachable`` its target for a
    while, and whether the hand is ``yielding`` to balance."""

    reference: np.ndarray
    unreachable: bool
    yielding: bool


class HoapEnv(gymnasium.Env):
    """A HOAP-3-style humanoid at a table with pegs and a hole board.

    Observation (a ``Dict``, float32, SI units):
      - ``"observation"``: robot joint positions (28, rad), joint velocities (28, rad/s), base
        position (3, m) and quaternion (4, x y z w), right-hand tcp position (3, m), then the task's
        own part (see the task's docstring).
      - ``"achieved_goal"`` / ``"desired_goal"``: the task's goal vectors (m), as in goal-based envs.

    Robot (``robot``): ``"full"``, the free-standing humanoid (default), or ``"fixed_legs"``, the same
    robot bolted at the pelvis with its legs welded in the standing posture: it cannot fall, and it
    simulates 3.8x faster (joint_delta; 2.0x in ee_delta, whose free-standing IK steps every 4 ticks).
    Observations have the same layout for both.

    Actions: a Box in [-1, 1] (see the control mode); values outside it are clipped to it, as
    Gymnasium's bounded Box actions are, and ``info["action_clipped"]`` says so on that step.

    Rewards (``reward_type``): sparse 0 on success else -1, dense minus the goal distance capped at
    1 m; a fall ends the episode and costs a whole episode's worth of -1s (:meth:`compute_reward`),
    so no learner gains by falling. ``info["is_success"]`` is set on reset and on every step. The
    episode terminates on success or when the robot falls; the time limit is applied by Gymnasium's
    ``TimeLimit`` on registration. ``render_mode="human"`` opens PyBullet's window; without a display it
    raises :class:`~hoap_actions.errors.DisplayUnavailableError`.
    """

    metadata = {"render_modes": ["rgb_array", "human"], "render_fps": int(round(240 / PHYSICS_STEPS_PER_ACTION))}
    task_cls: ClassVar[type[Task]]
    ik_periods: ClassVar[Mapping[str, int]] = IK_PERIOD
    """The hand-space modes' physics ticks per IK step by robot model when ``ik_period`` is not given."""
    robot_stances: ClassVar[Mapping[str, tuple[float, float]]] = {}
    """Where a robot model stands in this env (its ankles' midpoint on the floor, m), when not where
    :class:`~hoap_actions.envs.robot.Robot` stands it by default."""

    def __init__(
        self,
        render_mode: str | None = None,
        control_mode: str = "joint_delta",
        camera: str = "front",
        render_width: int = 320,
        render_height: int = 240,
        reward_type: str = "sparse",
        robot: str = "full",
        ik_period: int | None = None,
        **task_kwargs: Any,
    ) -> None:
        self._check_keywords(task_kwargs)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise InvalidInputError(
                f"render_mode={render_mode!r} is not supported; accepted: None, {self.metadata['render_modes']}"
            )
        if control_mode not in CONTROL_MODES:
            raise InvalidInputError(f"control_mode={control_mode!r} is not supported; accepted: {list(CONTROL_MODES)}")
        if reward_type not in ("sparse", "dense"):
            raise InvalidInputError(f"reward_type={reward_type!r} is not supported; accepted: 'sparse', 'dense'")
        if robot not in ROBOT_MODELS:
            raise InvalidInputError(f"robot={robot!r} is not a robot model; accepted: {list(ROBOT_MODELS)}")
        check_image_size(render_width, render_height, what="render")
        self.render_mode = render_mode
        self._episode_ready = False  # set by a reset that ran to its end: step refuses a half-made world
        self.control_mode = control_mode
        self.reward_type = reward_type
        self.sim = Sim(gui=render_mode == "human")
        try:
            self.sim.set_solver_iterations(SOLVER_ITERATIONS[robot])
            self.robot = Robot(self.sim, model=robot, feet_xy=self.robot_stances.get(robot))
            self.scene = Scene(self.sim)
            if camera not in self.sim.cameras:
                raise InvalidInputError(
                    f"camera={camera!r} is not a camera of this scene; accepted: {sorted(self.sim.cameras)}"
                )
            self.camera = camera
            self._render_camera = replace(self.sim.cameras[camera], width=render_width, height=render_height)
            self.task = self.task_cls(self.sim, self.robot, self.scene, **task_kwargs)
            if ik_period is None and control_mode in HAND_CONTROL_MODES:
                ik_period = self.ik_periods[robot]
            self.controller = make_controller(control_mode, self.robot, ik_period)
            self.robot.reset()
            self.task.reset(np.random.default_rng(0))  # a first layout, only to size the observation
            obs = self._observation()
        except BaseException:
            self.sim.close()
            raise
        self.action_space = self.controller.action_space
        self.observation_space = spaces.Dict(
            {key: spaces.Box(-np.inf, np.inf, shape=value.shape, dtype=np.float32) for key, value in obs.items()}
        )

    # ------------------------------------------------------------------ gymnasium API
    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        if self.sim.closed:
            raise EnvClosedError("reset() called on a closed environment; create a new one with gymnasium.make")
        if seed is not None:
            check_seed(seed)
        if options:
            raise InvalidInputError(f"reset takes no options; got {sorted(options)} (the layout comes from the seed)")
        self._episode_ready = False  # until this reset ends: an interrupted one leaves the env needing another
        super().reset(seed=seed)
        self.sim.rebuild()  # a fresh world every episode: same seed, same episode, whatever ran before
        self.robot.reset()
        self.controller.start_episode()
        self.task.reset(self.np_random)
        self.robot.set_targets(self.robot.joint_positions())
        self.sim.step(SETTLE_STEPS)
        self.controller.reset()
        observation, info = self._observation(), self._info()
        self._episode_ready = True
        return observation, info

    def step(self, action: np.ndarray) -> tuple[dict, float, bool, bool, dict]:
        if self.sim.closed:
            raise EnvClosedError("step() called on a closed environment; create a new one with gymnasium.make")
        if not self._episode_ready:
            raise ResetNeededError("step() called before a reset finished (never reset, or the last reset was "
                                   "interrupted); call reset() first")
        action, action_clipped = self._checked_action(action)
        self.controller.apply(action)
        tick = getattr(self.controller, "tick", None)
        if tick is None:
            self.sim.step(PHYSICS_STEPS_PER_ACTION)
        else:  # controllers with a per-tick loop (ee_delta: retiming + IK) run at the physics rate
            for _ in range(PHYSICS_STEPS_PER_ACTION):
                tick()
                self.sim.step(1)
        obs = self._observation()
        info = self._info(action_clipped)
        reward = float(self.compute_reward(obs["achieved_goal"], obs["desired_goal"], info))
        terminated = bool(info["is_success"] or info["fallen"])
        return obs, reward, terminated, False, info

    def compute_reward(self, achieved_goal: np.ndarray, desired_goal: np.ndarray,
                       info: dict | Sequence[dict] | None) -> np.ndarray:
        """Vectorised reward over goal batches (``info`` one dict, or one per goal as HER passes them).

        Sparse: 0 on success, else -1. Dense: minus the distance (m), at most 1 m. Every step's reward
        is thus in [-1, 0], and a step on which the robot falls (``info["fallen"]``; it ends the
        episode) earns :data:`FALL_PENALTY_STEPS` times the task's episode length in steps, negated:
        at least as bad as any whole episode without a fall, so falling early never pays (without it
        PPO learned to fall on ``Reach-v0``: a fall ended an episode of negative rewards)."""
        width = self.observation_space["desired_goal"].shape[-1]
        achieved_goal, desired_goal = np.asarray(achieved_goal), np.asarray(desired_goal)
        if achieved_goal.shape[-1:] != (width,) or desired_goal.shape[-1:] != (width,):
            raise InvalidInputError(f"goals must end in this env's goal width {width}; got achieved_goal "
                                    f"{achieved_goal.shape} and desired_goal {desired_goal.shape}")
        distance = np.linalg.norm(achieved_goal - desired_goal, axis=-1)
        if self.reward_type == "dense":
            reward = -np.minimum(distance, DENSE_DISTANCE_CAP)
        else:
            reward = -(~self.task.goal_reached(achieved_goal, desired_goal)).astype(float)
        fallen = _fallen(info, np.shape(distance))
        penalty = -FALL_PENALTY_STEPS * float(self.task_cls.episode_steps)
        return np.where(fallen, penalty, reward).astype(np.float32)

    def __deepcopy__(self, memo: dict) -> HoapEnv:
        raise EnvCopyError(_NO_COPIES)

    def __reduce_ex__(self, protocol: object) -> tuple:
        raise EnvCopyError(_NO_COPIES)

    def render(self) -> np.ndarray | None:
        if self.render_mode == "rgb_array":
            return self.sim.render(self._render_camera).rgb
        return None

    def close(self) -> None:
        self.sim.close()

    # ------------------------------------------------------------------ what a policy may ask the robot
    def parse_observation(self, obs: dict[str, np.ndarray]) -> dict[str, Any]:
        """Named fields of an observation of this env, so no policy slices it by offset: the robot's
        ``joint_positions``, ``joint_velocities``, ``base_position``, ``base_quaternion``,
        ``tcp_position``, the task's own fields (see the task's ``parse_observation``) and the two
        goal vectors. Arrays are float64 copies."""
        try:
            vector = np.asarray(obs["observation"], dtype=float)
            goals = {key: np.asarray(obs[key], dtype=float).copy() for key in ("achieved_goal", "desired_goal")}
        except (KeyError, TypeError, ValueError):
            raise InvalidInputError("obs must be an observation dict of this env (keys 'observation', "
                                    "'achieved_goal', 'desired_goal')") from None
        expected = self.observation_space["observation"].shape
        if vector.shape != expected:
            raise InvalidInputError(f"obs['observation'] has shape {vector.shape}; this env's is {expected}")
        n = len(self.robot.joint_names)
        sizes = {"joint_positions": n, "joint_velocities": n, "base_position": 3, "base_quaternion": 4,
                 "tcp_position": 3}
        fields: dict[str, Any] = {}
        offset = 0
        for name, size in sizes.items():
            fields[name] = vector[offset: offset + size].copy()
            offset += size
        return fields | self.task.parse_observation(vector[offset:]) | goals

    def capture(self, camera: str = "overhead", width: int = 320, height: int = 240) -> CameraView:
        """An rgb-d image from one of the scene's cameras (``sim.cameras``), as a robot's camera would
        give it: a policy that perceives the world calls this instead of reading the simulator."""
        if camera not in self.sim.cameras:
            raise InvalidInputError(f"camera={camera!r} is not a camera of this scene; accepted: "
                                    f"{sorted(self.sim.cameras)}")
        check_image_size(width, height, what="capture")
        view = replace(self.sim.cameras[camera], width=width, height=height)
        image = self.sim.render(view)
        return CameraView(rgb=image.rgb, depth=image.depth, camera=view)

    @property
    def robot_description(self) -> RobotDescription:
        """The robot's joint names (the order of the observation's joint vectors), home posture and
        whether its legs are welded."""
        return RobotDescription(
            tuple(self.robot.joint_names), tuple(float(v) for v in self.robot.home_posture), self.robot.fixed_legs
        )

    @property
    def hand_status(self) -> HandStatus:
        """The hand controller's state (the hand-space control modes only: ``"ee_delta"``, ``"ee_heading_delta"``)."""
        hand = getattr(self.controller, "hand", None)
        if hand is None:
            raise InvalidInputError(f"hand_status needs control_mode in {list(HAND_CONTROL_MODES)}; "
                                    f"this env uses {self.control_mode!r}")
        return HandStatus(reference=hand.reference.copy(), unreachable=hand.unreachable, yielding=hand.yielding)

    # --------------------------------------------------------------------- internals
    @classmethod
    def _check_keywords(cls, task_kwargs: dict[str, Any]) -> None:
        """Unknown keywords are a TypeError that lists every accepted one (env's and task's)."""
        task_params = list(inspect.signature(cls.task_cls.__init__).parameters)[4:]  # after self, sim, robot, scene
        unknown = sorted(set(task_kwargs) - set(task_params))
        if unknown:
            env_params = list(inspect.signature(HoapEnv.__init__).parameters)[1:-1]
            raise TypeError(f"{cls.__name__} got unknown keyword argument(s) {unknown}; accepted: "
                            f"{env_params + task_params}")

    def _checked_action(self, action: Any) -> tuple[np.ndarray, bool]:
        """The action as float64 clipped to the Box, and whether clipping changed it."""
        expected = self.action_space.shape
        accepted = f"this env ({self.control_mode}) expects an array of {expected[0]} finite numbers in [-1, 1]"
        try:
            raw = action if np.ma.isMaskedArray(action) else np.asarray(action)
        except (TypeError, ValueError):
            raise InvalidInputError(f"action {action!r} ({type(action).__name__}) is not numeric; {accepted}") from None
        if np.ma.is_masked(raw):
            raise InvalidInputError(f"action has masked entries: {action}; {accepted}")
        if raw.dtype.kind not in "iuf":  # strings, complex numbers, booleans, objects: not one real number each
            raise InvalidInputError(f"action {action!r} ({type(action).__name__}) is not real numbers; {accepted}")
        array = np.asarray(raw, dtype=np.float64)
        if array.shape != expected:
            raise InvalidInputError(f"action has shape {array.shape}; {accepted}")
        if not np.all(np.isfinite(array)):
            raise InvalidInputError(f"action contains NaN or inf: {array}; {accepted}")
        clipped = np.clip(array, self.action_space.low, self.action_space.high)
        return clipped, bool(np.any(clipped != array))

    def _observation(self) -> dict[str, np.ndarray]:
        q, qd = self.robot.joint_state()
        base_pos, base_quat = self.robot.base_pose()
        tcp, _ = self.robot.frame_pose("r_tcp")
        robot_part = np.concatenate([q, qd, base_pos, base_quat, tcp])
        return {
            "observation": np.concatenate([robot_part, self.task.observation()]).astype(np.float32),
            "achieved_goal": self.task.achieved_goal().astype(np.float32),
            "desired_goal": self.task.desired_goal().astype(np.float32),
        }

    def _info(self, action_clipped: bool = False) -> dict[str, Any]:
        return {
            "is_success": bool(self.task.is_success()),
            "fallen": bool(self.robot.has_fallen()),
            "target_clipped": bool(self.controller.last_clipped),
            "action_clipped": action_clipped,
        }
