"""Whole-body IK and per-tick hand control on the standing robot in PyBullet (real physics)."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from hoap_actions.controllers.hand_control import BALANCE_BODY_SPEED, BALANCE_HOLD, BALANCE_TILT, HandController
from hoap_actions.controllers.wholebody_ik import BODY, BODY_SPEED, IKStatus, WholeBodyIK, polygon_distance
from hoap_actions.envs import world
from hoap_actions.envs.robot import Robot
from hoap_actions.envs.scene import Scene
from hoap_actions.envs.sim import TIMESTEP, Sim
from hoap_actions.errors import InvalidInputError

TICKS = 480  # 2 s at 240 Hz: a move of up to 0.2 m at 0.15 m/s, then settling


@pytest.fixture(scope="module")
def standing():
    """A standing robot with the table cleared (pegs and board moved off it), and its hand controller."""
    sim = Sim()
    robot = Robot(sim)
    scene = Scene(sim)
    sim.set_base_pose("hole_board", (0.5, 0.5, 0.0125))
    for i, name in enumerate(scene.peg_names):
        sim.set_base_pose(name, (0.5, -0.5 + 0.05 * i, 0.025))
    sim.step(48)
    state = sim.save_state()
    hand = HandController(robot, TIMESTEP)
    yield sim, robot, hand, state
    sim.close()


def _move(sim, robot, hand, target, ticks=TICKS):
    """Run the controller towards ``target``; returns the least CoM margin seen (m) and the last IK result."""
    hand.set_target(target)
    margin = np.inf
    for k in range(ticks):
        result = hand.tick()
        sim.step(1)
        if k % 8 == 0:
            margin = min(margin, polygon_distance(robot.com()[:2], robot.support_polygon()))
    return margin, result


def test_reset_syncs_the_ik_model_with_pybullet(standing):
    sim, robot, hand, state = standing
    sim.restore_state(state)
    hand.reset()
    model = hand.ik.robot
    for frame in ("r_sole", "l_sole", "r_tcp"):
        np.testing.assert_allclose(model.get_T_world_frame(frame)[:3, 3], robot.frame_pose(frame)[0], atol=1e-6)
    np.testing.assert_allclose(hand.ik.q, robot.joint_positions(), atol=1e-9)


def test_reachable_targets_are_reached_within_2mm_and_the_com_stays_inside(standing):
    sim, robot, hand, state = standing
    rng = np.random.default_rng(3)
    checked = 0
    for _ in range(10):
        target = np.r_[rng.uniform(world.WORK_AREA_LOW, world.WORK_AREA_HIGH), rng.uniform(0.02, 0.12)]
        sim.restore_state(state)
        hand.reset()
        # Well inside the reachable set only: where the IK model itself ends 0.1 mm or more short, it
        # is at a limit (close to the right shoulder and high), the robot leans, its knees give under
        # the load and PyBullet's hand sags up to ~5 mm from the model's.
        if hand.ik.probe(target).error > 1e-4:
            continue
        margin, result = _move(sim, robot, hand, target)
        error = np.linalg.norm(robot.frame_pose("r_tcp")[0] - target)
        assert error < 0.002, f"target {target.round(3)} missed by {error * 1000:.2f} mm"
        assert result.status == IKStatus.OK
        assert margin > 0.01, f"CoM came within {margin * 1000:.1f} mm of the support polygon's edge"
        assert not robot.has_fallen()
        checked += 1
    assert checked >= 7, f"only {checked} of 10 work-area targets were reachable"


def test_hand_reach_polygon_is_reachable_and_its_far_corner_is_not(standing):
    """world.HAND_REACH_XY (where layouts put holes) against the IK: its corners are reached at the
    height the expert lines pegs up over holes; 3 cm beyond its far-left edge they are not."""
    sim, robot, hand, state = standing
    sim.restore_state(state)
    hand.reset()
    for corner in world.HAND_REACH_XY:
        assert hand.ik.probe(np.r_[corner, 0.07]).error < 1.5e-3, f"corner {corner} out of reach"
    for outside in ([0.07, 0.11], [0.04, 0.13], [0.12, 0.06]):
        assert hand.ik.probe(np.r_[outside, 0.07]).error > 1.5e-3, f"{outside} is reachable after all"


def test_unreachable_target_is_reported_and_the_robot_stays_up(standing):
    sim, robot, hand, state = standing
    sim.restore_state(state)
    hand.reset()
    target = robot.frame_pose("r_tcp")[0] + np.array([1.0, 0.0, 0.0])
    margin, result = _move(sim, robot, hand, target)
    assert result.status == IKStatus.TARGET_UNREACHED
    assert result.hand_error > hand.ik.tolerance
    assert hand.unreachable
    assert margin > 0.0
    assert not robot.has_fallen()


def test_legs_and_waist_move_no_faster_than_body_speed(standing):
    """A far target puts the whole body to work, at BODY_SPEED at most (the arms keep their 5 rad/s)."""
    sim, robot, hand, state = standing
    sim.restore_state(state)
    hand.reset()
    body = [hand.ik.joint_names.index(name) for name in BODY]
    hand.set_target(robot.frame_pose("r_tcp")[0] + np.array([0.3, -0.2, -0.1]))
    fastest, q = 0.0, hand.ik.q.copy()
    for _ in range(TICKS // 2):
        hand.tick()
        sim.step(1)
        fastest = max(fastest, float(np.abs(hand.ik.q[body] - q[body]).max()) / hand.dt)
        q = hand.ik.q.copy()
    assert 0.5 * BODY_SPEED < fastest <= BODY_SPEED + 1e-9, f"fastest body joint: {fastest:.3f} rad/s"
    assert not robot.has_fallen()


@pytest.mark.parametrize("speed", [0.0, -0.3, np.nan])
def test_body_speed_must_be_a_positive_speed(standing, speed):
    _, _, hand, _ = standing
    with pytest.raises(InvalidInputError, match="speed must be a finite joint speed > 0"):
        hand.ik.set_body_speed(speed)


def _knee_reversals(ik: WholeBodyIK, target: np.ndarray, ticks: int = 120) -> int:
    """Ticks on which the IK's right knee reverses at >= 80 % of BODY_SPEED while holding ``target``."""
    knee = ik.joint_names.index("r_knee")
    start = ik.hand_position()
    steps = int(np.ceil(np.linalg.norm(target - start) / 5e-4))  # streamed like the controller's reference
    for k in range(1, steps + 1):
        ik.solve(start + (target - start) * k / steps)
    angles = []
    for _ in range(ticks):
        ik.solve(target)
        angles.append(ik.q[knee])
    speed = np.diff(angles) / ik.dt
    fast = np.abs(speed) >= 0.8 * BODY_SPEED
    return int(np.sum(fast[1:] & fast[:-1] & (np.sign(speed[1:]) != np.sign(speed[:-1]))))


def test_legs_settle_without_cycling_near_straight_knees(standing):
    """Undamped, the QP's step overshoots along the straight legs' squat direction: on a fixed high
    target the knees reverse at the speed limit every tick. The leg damping settles them."""
    sim, robot, hand, state = standing
    sim.restore_state(state)
    target = np.array([-0.02, -0.1, 0.11])
    reversals = {}
    for label, options in (("undamped", {"leg_damping": 0.0}), ("default", {})):
        ik = WholeBodyIK(robot.joint_names, hand.ik.home_posture, **options)
        ik.reset(robot.joint_positions(), *robot.base_pose())
        reversals[label] = _knee_reversals(ik, target)
    assert reversals["undamped"] > 20, f"the scenario no longer provokes the cycle: {reversals}"
    assert reversals["default"] == 0, reversals


def test_hand_yields_while_a_sole_tilts(standing, monkeypatch):
    """A tilted sole freezes the hand reference where the hand is and slows the body; once the soles
    are level for BALANCE_HOLD the hand carries on to its target."""
    sim, robot, hand, state = standing
    sim.restore_state(state)
    hand.reset()
    tilt = {"rad": 0.0}
    monkeypatch.setattr(robot, "sole_tilt", lambda: tilt["rad"])
    target = robot.frame_pose("r_tcp")[0] + np.array([0.04, 0.0, 0.02])
    hand.set_target(target)
    for _ in range(24):
        hand.tick()
        sim.step(1)
    assert not hand.yielding
    tilt["rad"] = 2 * BALANCE_TILT
    hand.tick()
    sim.step(1)
    assert hand.yielding
    held = hand.reference.copy()
    assert np.linalg.norm(held - robot.frame_pose("r_tcp")[0]) < 0.003  # where the hand is, not the target
    body = [hand.ik.joint_names.index(name) for name in BODY]
    q = hand.ik.q.copy()
    for _ in range(48):
        hand.tick()
        sim.step(1)
        np.testing.assert_allclose(hand.reference, held, atol=1e-9)
        assert np.abs(hand.ik.q[body] - q[body]).max() <= BALANCE_BODY_SPEED * hand.dt + 1e-9
        q = hand.ik.q.copy()
    tilt["rad"] = 0.0
    hold_ticks = int(round(BALANCE_HOLD / hand.dt))
    for _ in range(hold_ticks):
        hand.tick()
        sim.step(1)
    assert not hand.yielding
    for _ in range(TICKS):
        hand.tick()
        sim.step(1)
    assert np.linalg.norm(robot.frame_pose("r_tcp")[0] - target) < 0.003
    assert not robot.has_fallen()


def test_solver_failure_holds_the_last_posture(standing):
    sim, robot, hand, state = standing
    sim.restore_state(state)
    hand.reset()
    before = hand.ik.q.copy()
    result = hand.ik.solve(np.array([np.nan, 0.0, 0.1]))
    assert result.status == IKStatus.SOLVER_FAILED
    np.testing.assert_array_equal(result.q, before)
    ok = hand.ik.solve(robot.frame_pose("r_tcp")[0])
    assert ok.status == IKStatus.OK


def test_probe_leaves_the_ik_state_untouched(standing):
    sim, robot, hand, state = standing
    sim.restore_state(state)
    hand.reset()
    before = hand.ik.q.copy()
    probe = hand.ik.probe(np.array([0.0, 0.0, 0.06]))
    assert probe.error < 1e-3
    np.testing.assert_array_equal(hand.ik.q, before)


def test_ee_delta_env_passes_the_gymnasium_checker():
    env = gymnasium.make("hoap_actions/PegInsert-v0", control_mode="ee_delta")
    check_env(env.unwrapped, skip_render_check=True)
    env.close()


def test_ee_delta_random_actions_keep_the_robot_up():
    env = gymnasium.make("hoap_actions/PegInsert-v0", control_mode="ee_delta")
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    for k in range(150):
        action = np.r_[np.sign(rng.uniform(-1, 1, 3)), rng.uniform(-1, 1)] if k % 30 < 15 else rng.uniform(-1, 1, 4)
        _, _, terminated, _, info = env.step(action.astype(np.float32))
        assert not info["fallen"], f"the robot fell after {k + 1} random ee_delta actions"
        if terminated:
            break
    env.close()


@pytest.mark.parametrize("bad", [0, -2, 1.5, True, "4"])
def test_the_ik_period_must_be_a_whole_number_of_ticks(standing, bad):
    _, robot, _, _ = standing
    with pytest.raises(InvalidInputError, match="ik_period"):
        HandController(robot, TIMESTEP, ik_period=bad)


def test_between_ik_steps_the_joint_targets_move_on_the_line_between_their_answers(standing):
    sim, robot, _, state = standing
    period = 4
    hand = HandController(robot, TIMESTEP, ik_period=period)
    sim.restore_state(state)
    hand.reset()
    hand.set_target(hand.reference + [0.03, -0.02, 0.02])
    sent, answers = [], []
    for _ in range(6 * period):
        before = hand.last
        hand.tick()
        if hand.last is not before:
            answers.append(hand.last.q.copy())
        sent.append(robot.targets.copy())
        sim.step(1)
    assert len(answers) == 6  # one IK step per period
    moving = [n for n in range(len(robot.joint_names)) if n != robot.joint_index("r_gripper")]
    for step in range(1, 6):
        start, end = answers[step - 1][moving], answers[step][moving]
        for k in range(1, period + 1):
            np.testing.assert_allclose(sent[step * period + k - 1][moving], start + k / period * (end - start),
                                       atol=1e-12)


def test_ik_period_belongs_to_ee_delta():
    with pytest.raises(InvalidInputError, match="ee_delta"):
        gymnasium.make("hoap_actions/Reach-v1", control_mode="joint_delta", ik_period=4)
