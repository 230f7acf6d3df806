"""Motor groups: the lists PyBullet takes, made once, drive the motors exactly as a per-call conversion
does, and bad groups or target counts are refused before PyBullet sees them."""

from __future__ import annotations

import numpy as np
import pytest

from hoap_actions.envs.motors import MotorGroup
from hoap_actions.envs.robot import Robot
from hoap_actions.envs.sim import Sim
from hoap_actions.errors import InvalidInputError


def _arm_motion(use_group: bool) -> np.ndarray:
    """Joint angles after 60 ticks of a swinging arm on a welded-legs robot, driven per call or by a group."""
    sim = Sim()
    try:
        robot = Robot(sim, model="fixed_legs")
        indices, motorised = robot._indices, robot._motorised
        forces, speeds = robot.max_force[motorised], robot.max_velocity[motorised]
        group = MotorGroup.of(robot.name, indices, forces, speeds, robot.position_gain, robot.velocity_gain)
        q = robot.home_posture.copy()
        shoulder = robot.joint_index("r_shoulder_pitch")
        for tick in range(60):
            q[shoulder] = 0.5 * np.sin(tick / 10.0)
            targets = np.clip(q, robot.lower, robot.upper)[motorised]
            if use_group:
                sim.drive(group, targets)
            else:
                sim.set_joint_targets(robot.name, indices, targets, forces, speeds, robot.position_gain,
                                      robot.velocity_gain)
            sim.step()
        return robot.joint_state()[0]
    finally:
        sim.close()


def test_a_group_drives_the_motors_bit_for_bit_as_per_call_targets():
    driven = _arm_motion(use_group=True)
    assert np.array_equal(driven, _arm_motion(use_group=False))
    assert np.ptp(driven) > 0.1  # the arm did move


@pytest.mark.parametrize("forces, speeds, match", [
    ([1.0, 1.0], [5.0], "2 forces and 1 caps"),
    ([1.0, np.nan], [5.0, 5.0], "finite"),
    ([1.0, 1.0], [5.0, -5.0], ">= 0"),
])
def test_a_group_refuses_limits_that_do_not_fit_its_joints(forces, speeds, match):
    with pytest.raises(InvalidInputError, match=match):
        MotorGroup.of("robot", [0, 1], forces, speeds)


def test_drive_refuses_a_wrong_number_of_targets():
    sim = Sim()
    try:
        robot = Robot(sim, model="fixed_legs")
        group = MotorGroup.of(robot.name, robot._indices[:3], [1.0] * 3, [5.0] * 3)
        with pytest.raises(InvalidInputError, match="4 targets for a group of 3 joints"):
            sim.drive(group, np.zeros(4))
    finally:
        sim.close()
