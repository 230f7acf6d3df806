"""The robot does what it learned: grasp-and-insert with hand paths synthesised by the PHMMs (paper Fig. 9).

:class:`PHMMPolicy` reads only what a robot has: the overhead camera's rgb-d image (through the env's
``capture``), its own joint state and hand position (the observation's robot fields), the hand
controller's state, and which peg goes into which hole (the task's target one-hots: the supervisor
pointing, as in the paper). It never reads the simulator's object poses.

At the start of an episode it locates the pegs and the holes
(:func:`~hoap_actions.vision.perception.locate`); P is where the hand is, S the located target
peg, E its hole. The shared execution layer
(:class:`~hoap_actions.policies.execution.GraspAndInsert`) then runs approach (phi = (P, S)), grasp,
move (phi = (S, E)), release and remove (phi = (E, P)); each path is synthesised by the learned action
models, mapped to the robot, rescaled onto its endpoints and retimed
(:class:`~hoap_actions.policies.phmm_paths.PHMMPaths`), and tracked by the whole-body IK of the
ee_delta controller. Each primitive starts where the previous one ended. What is scripted is what
the paper scripts, the gripper: it closes at the end of the approach (after the palm slides the last
3.5 mm onto the peg) and opens at the end of the move, over the hole, and the peg drops in; and a
hand blocked on its way down backs off 3 cm and comes again with another grasp along the palm.

Where the held peg's bottom is relative to the hand is taken at the grasp, from the located peg and
the measured hand: this policy does not see the peg once it holds it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import gymnasium
import numpy as np

from hoap_actions.controllers.hand_control import HandLimits
from hoap_actions.envs import scene as scene_module
from hoap_actions.policies.execution import GraspAndInsert, Leg, Phase, WorldEstimate
from hoap_actions.policies.figures import draw_episode
from hoap_actions.policies.phmm_paths import PHMMPaths, resample
from hoap_actions.primitives.models.action_models import ActionModels
from hoap_actions.vision.perception import Detections, locate

__all__ = ["PHMMPolicy"]

CAMERA = "overhead"
IMAGE_SIZE = (320, 240)  # px: 1.2 mm per pixel on the table, the resolution perception was measured at
APPROACH_TOLERANCE = 0.002  # m, the approach ends with the hand settled this near the grasp point
MOVE_TOLERANCE = 0.002  # m, the move ends with the peg this near its place in the hole
REMOVE_TOLERANCE = 0.01  # m
RELEASE_HEIGHT = 0.003  # m, the held peg's bottom over the board's top when the gripper opens over the hole
CARRY_LIMITS = HandLimits(velocity=0.15, acceleration=0.3, jerk=3.0)


class PHMMPolicy(GraspAndInsert):
    """``obs -> action`` grasp-and-insert from the camera and the learned models (module docstring).

    Parameters
    ----------
    env
        a PegInsert env made with ``control_mode="ee_delta"`` (wrappers are fine).
    models
        fitted :class:`ActionModels` with an action level, or a models directory; default:
        the package's shipped models (:func:`hoap_actions.models.shipped.load_default_models`).
    """

    def __init__(self, env: gymnasium.Env, models: ActionModels | str | Path | None = None) -> None:
        super().__init__(env)
        if models is None:
            from hoap_actions.models.shipped import load_default_models

            models = load_default_models()
        elif not isinstance(models, ActionModels):
            models = ActionModels.load(models)
        self.paths = PHMMPaths(models, dt=1.0 / float(env.metadata["render_fps"]))
        self._capture = env.get_wrapper_attr("capture")
        self.detections: Detections | None = None
        self.synthesised: dict[str, np.ndarray] = {}
        self.executed: dict[str, list[np.ndarray]] = {}

    # ------------------------------------------------------------------ the world, from the camera
    def locate(self, obs: dict[str, np.ndarray], fields: dict[str, Any]) -> WorldEstimate | None:
        self.view = view = self._capture(CAMERA, *IMAGE_SIZE)
        self.detections = found = locate(view.rgb, view.depth, view.camera)
        self.target = (list(scene_module.PEG_COLOURS)[fields["target_peg"]], int(fields["target_hole"]))
        self.synthesised, self.executed = {}, {}
        colour = list(scene_module.PEG_COLOURS)[fields["target_peg"]]
        peg = found.peg(colour)
        if peg is None or not peg.standing:
            self.failure = f"target peg not seen standing ({colour})"
            return None
        if len(found.holes) != scene_module.N_HOLES:
            self.failure = "board not seen"
            return None
        others = np.array([p.position_m for p in found.pegs if p.colour != colour]).reshape(-1, 3)
        holes = np.array([h.position_m for h in found.holes])
        return WorldEstimate(peg=peg.position_m, others=others, holes=holes, hole=holes[fields["target_hole"]])

    # ------------------------------------------------------------------ synthesised paths
    def move_bottom_target(self) -> np.ndarray:
        """Over the hole, the peg's bottom :data:`RELEASE_HEIGHT` above the board: the gripper opens
        there and the peg drops in, as the paper's robot lets go over the hole. (Ending the move 8 mm
        down in the hole, as the expert's straight descent does, drove the peg's bottom into the
        board beside the hole: a synthesised set-down still has 1.5 cm to go sideways 1 cm above
        its end, measured on development layouts.)"""
        return np.array([*self.world.hole[:2], scene_module.BOARD_SIZE[2] + RELEASE_HEIGHT])

    def _legs(self, name: str, path: np.ndarray, tolerance: float) -> list[Leg]:
        self.synthesised[name] = path
        self.executed[name] = []  # a new path (e.g. an approach after backing off) replaces the last
        return [Leg(self.paths.timed(path), tolerance)]

    def approach_legs(self, start: np.ndarray, grasp: np.ndarray) -> list[Leg]:
        return self._legs("approach", self.paths.approach(start, grasp), APPROACH_TOLERANCE)

    def move_legs(self, start: np.ndarray, end: np.ndarray) -> list[Leg]:
        peg, hole = self.world.peg, self.world.hole
        path = self.paths.move(start, end, peg, hole)
        self.synthesised["move"], self.executed["move"] = path, []
        return [Leg(self.paths.timed(path, CARRY_LIMITS), MOVE_TOLERANCE)]

    def remove_legs(self, start: np.ndarray, end: np.ndarray) -> list[Leg]:
        return self._legs("remove", self.paths.remove(start, end), REMOVE_TOLERANCE)

    # ------------------------------------------------------------------ what it did
    def __call__(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        action = super().__call__(obs)
        name = {Phase.APPROACH: "approach", Phase.MOVE: "move", Phase.REMOVE: "remove"}.get(self.phase)
        if name is not None:
            self.executed.setdefault(name, []).append(self.tcp.copy())
        return action

    def figure(self) -> np.ndarray | None:
        """This episode as the paper's Fig. 9: the overhead image with the located pegs and holes, the
        synthesised paths and the executed hand path (:func:`~hoap_actions.policies.figures.draw_episode`)."""
        if self.detections is None:
            return None
        executed = {name: np.asarray(points) for name, points in self.executed.items() if points}
        return draw_episode(self.view.rgb, self.view.camera, self.detections, self.synthesised, executed, self.target)

    def located(self) -> dict[str, np.ndarray] | None:
        """The target peg and hole as located at the start of the episode (m), or None if not."""
        if self.world is None:
            return None
        return {"peg": self.world.peg.copy(), "hole": self.world.hole.copy()}

    def path_deviations(self) -> dict[str, float]:
        """Per primitive performed so far, the largest distance (m) from an executed hand position to
        the synthesised path (densely resampled polyline)."""
        deviations = {}
        for name, executed in self.executed.items():
            path = resample(self.synthesised[name], 0.0005)
            hand = np.asarray(executed)
            deviations[name] = float(np.max(np.min(np.linalg.norm(hand[:, None] - path[None], axis=2), axis=1)))
        return deviations

