"""The robot with welded legs (``robot="fixed_legs"``): the same kinematics above the pelvis as the
free-standing one, legs that never move or touch anything, the same observation layout, an IK that
keeps the legs and the pelvis where they are, and the scripted expert working on it."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from scipy.spatial.transform import Rotation

import hoap_actions  # noqa: F401  (registers the envs)
from hoap_actions.apps.episodes import run_episode
from hoap_actions.controllers.hand_control import rest_posture
from hoap_actions.controllers.wholebody_ik import WholeBodyIK
from hoap_actions.envs import world
from hoap_actions.envs.robot import Robot
from hoap_actions.envs.sim import Sim
from hoap_actions.errors import InvalidInputError
from hoap_actions.policies.scripted_expert import ScriptedExpert
from hoap_actions.urdf import LEG_JOINTS, STANDING_LEGS

FRAMES = ("r_tcp", "l_tcp", "camera", "r_sole", "l_sole", "r_shoulder_pitch_link", "trunk")


def _robots(feet_xy=(0.0, 0.0)):
    sims = [Sim(), Sim()]
    return sims, [Robot(sims[0], model="full", feet_xy=feet_xy), Robot(sims[1], model="fixed_legs", feet_xy=feet_xy)]


def test_folded_links_read_as_before(capfd):
    """``merge_fixed_links``: the welded model loads without a word on stdout, lists the same joints, and
    every frame (folded into another link or kept) sits where the unfolded model has it; a folded link
    cannot be changed or touched on its own (PyBullet would silently ignore it)."""
    sims = [Sim(), Sim()]
    try:
        for sim, merge in zip(sims, (False, True)):
            sim.load_urdf("robot", "hoap3_fixed_legs.urdf", fixed_base=True, merge_fixed_links=merge)
        assert "merge" not in capfd.readouterr().out
        assert sims[0].joint_names("robot") == sims[1].joint_names("robot")
        assert [len(sim.joint_names("robot")) for sim in sims] == [33, 33]
        folded = sims[1].link_index("robot", "r_tcp")
        assert folded < -1 <= sims[1].link_index("robot", "r_hand")
        for frame in FRAMES + ("r_foot", "r_thigh", "pelvis"):
            poses = [sim.link_poses("robot", [sim.link_index("robot", frame)]) for sim in sims]
            np.testing.assert_allclose(poses[1][0], poses[0][0], rtol=0, atol=1e-7, err_msg=frame)
            angle = (Rotation.from_quat(poses[1][1][0]).inv() * Rotation.from_quat(poses[0][1][0])).magnitude()
            assert angle < 1e-6, frame
        with pytest.raises(InvalidInputError, match="no link named"):
            sims[1].link_index("robot", "r_wing")
        for call in (lambda: sims[1].set_dynamics("robot", folded, lateralFriction=1.0),
                     lambda: sims[1].aabb("robot", folded), lambda: sims[1].contacts("robot", link_a=folded)):
            with pytest.raises(InvalidInputError, match="'r_tcp' of body 'robot' is folded into 'r_hand'"):
                call()
    finally:
        for sim in sims:
            sim.close()


def test_joint_vector_and_welded_legs():
    sims, (full, fixed) = _robots()
    try:
        assert fixed.joint_names == full.joint_names and len(fixed.joint_names) == 28
        welded = [fixed.joint_index(n) for n in LEG_JOINTS]
        expected = [STANDING_LEGS.get(n[2:], 0.0) for n in LEG_JOINTS]
        np.testing.assert_array_equal(fixed.lower[welded], expected)
        np.testing.assert_array_equal(fixed.upper[welded], expected)
        np.testing.assert_array_equal(fixed.home_posture, full.home_posture)
        assert len(sims[1].joints("robot")) == 16  # motors: waist, arms, head
        q = fixed.home_posture.copy()
        q[welded] = 1.0  # asked to bend the legs: they hold their weld
        fixed.set_targets(q)
        np.testing.assert_array_equal(fixed.targets[welded], expected)
    finally:
        for sim in sims:
            sim.close()


@pytest.mark.parametrize("posture", ["home", "reach"])
def test_same_kinematics_above_the_pelvis(posture):
    """Placed at the same spot in the same posture, every frame is where the free-standing robot's is:
    the welds reproduce the standing legs exactly (to 0.1 um: the welded robot's tcp, sole and camera
    frames are folded into their links and composed again, which PyBullet rounds at about 1e-8 m)."""
    sims, robots = _robots()
    try:
        q = robots[0].home_posture.copy()
        if posture == "reach":
            for name, value in {"waist_pitch": 0.3, "r_shoulder_pitch": 0.9, "r_shoulder_roll": -0.4, "r_elbow": -1.2,
                                "l_shoulder_yaw": 0.5, "head_pan": 0.3}.items():
                q[robots[0].joint_index(name)] = value
        for robot in robots:
            robot.reset(q)
        for frame in FRAMES:
            (p_full, q_full), (p_fixed, q_fixed) = (robot.frame_pose(frame) for robot in robots)
            np.testing.assert_allclose(p_fixed, p_full, rtol=0, atol=1e-7, err_msg=frame)
            angle = (Rotation.from_quat(q_fixed).inv() * Rotation.from_quat(q_full)).magnitude()
            assert angle < 1e-7, frame
    finally:
        for sim in sims:
            sim.close()


@pytest.fixture(scope="module")
def env():
    env = gymnasium.make("hoap_actions/PegInsert-v0", robot="fixed_legs")
    yield env
    env.close()


def test_env_passes_gymnasiums_checker_with_the_same_spaces():
    fixed = gymnasium.make("hoap_actions/PegInsert-v0", robot="fixed_legs")
    full = gymnasium.make("hoap_actions/PegInsert-v0")
    try:
        check_env(fixed.unwrapped, skip_render_check=True)
        assert fixed.observation_space == full.observation_space and fixed.action_space == full.action_space
    finally:
        fixed.close()
        full.close()


def test_legs_never_move_nor_touch_anything_and_it_never_falls(env):
    rng = np.random.default_rng(7)
    obs, _ = env.reset(seed=11)
    legs = [env.unwrapped.robot.joint_index(n) for n in LEG_JOINTS]
    base = env.unwrapped.parse_observation(obs)["base_position"]
    sim = env.unwrapped.sim
    leg_links = {sim.link_index("robot", f"{p}_{link}") for p in "rl" for link in ("thigh", "shin", "foot")}
    for _ in range(120):  # random waist and arm actions (joint_delta), 4 s
        obs, _, terminated, _, info = env.step(rng.uniform(-1, 1, 7))
        fields = env.unwrapped.parse_observation(obs)
        assert not info["fallen"]
        np.testing.assert_array_equal(fields["joint_positions"][legs],
                                      env.unwrapped.robot.lower[legs].astype(np.float32))
        np.testing.assert_array_equal(fields["joint_velocities"][legs], 0.0)
        np.testing.assert_allclose(fields["base_position"], base, atol=1e-9)
        touching = {c["link_a"] for c in sim.contacts("robot")} & leg_links
        assert not touching
        if terminated:
            obs, _ = env.reset(seed=12)
            base = env.unwrapped.parse_observation(obs)["base_position"]


def test_same_seed_same_episode(env):
    rng = np.random.default_rng(3)
    actions = rng.uniform(-1, 1, (30, 7))
    runs = []
    for _ in range(2):
        obs, _ = env.reset(seed=5)
        trace = [obs["observation"]]
        for a in actions:
            trace.append(env.step(a)[0]["observation"])
        runs.append(np.array(trace))
    np.testing.assert_array_equal(runs[0], runs[1])


def test_unknown_robot_model_is_refused_with_the_accepted_ones():
    with pytest.raises(InvalidInputError, match="fixed_legs"):
        gymnasium.make("hoap_actions/Reach-v1", robot="wheeled")


def test_ik_moves_the_hand_but_neither_legs_nor_pelvis():
    sims, (_, fixed) = _robots(world.FIXED_LEGS_FEET_XY)
    try:
        names = fixed.joint_names
        ik = WholeBodyIK(names, rest_posture(fixed), fixed_legs=True)
        position, quat = fixed.base_pose()
        ik.reset(fixed.home_posture, position, quat)
        pelvis = ik.robot.get_T_world_frame("pelvis").copy()
        legs = [names.index(n) for n in LEG_JOINTS]
        target = ik.hand_position() + np.array([0.04, 0.03, 0.02])
        for _ in range(400):
            result = ik.solve(target)
        assert result.hand_error < 1e-3
        np.testing.assert_array_equal(result.q[legs], fixed.home_posture[legs])
        np.testing.assert_allclose(ik.robot.get_T_world_frame("pelvis"), pelvis, atol=1e-12)
        # the IK model agrees with PyBullet: the same joints put PyBullet's hand on the target
        fixed.reset(result.q)
        np.testing.assert_allclose(fixed.frame_pose("r_tcp")[0], ik.hand_position(), atol=1e-6)
    finally:
        for sim in sims:
            sim.close()


def test_scripted_expert_inserts_a_peg_with_welded_legs():
    env = gymnasium.make("hoap_actions/PegInsert-v0", control_mode="ee_delta", robot="fixed_legs")
    try:
        results = [run_episode(env, ScriptedExpert(env), seed) for seed in (2, 3)]
    finally:
        env.close()
    assert any(r.success for r in results), [r.reason for r in results]
    assert not any(r.reason == "fell" for r in results)


@pytest.mark.parametrize("placement", [{"feet_xy": (np.nan, 0.0)}, {"feet_xy": (0.0,)}, {"yaw": np.inf},
                                       {"floor_z": float("nan")}])
def test_a_placement_that_is_not_finite_is_refused_before_pybullet(placement):
    sim = Sim()
    try:
        with pytest.raises(InvalidInputError, match="expected finite numbers"):
            Robot(sim, model="fixed_legs", **placement)
        assert sim.body_names == []  # refused before anything was loaded
    finally:
        sim.close()


def test_a_heading_asked_of_the_ik_turns_the_hand_where_the_arm_can():
    """A reachable heading 10 degrees off the one the IK picks is taken within 2 degrees, the hand kept on its
    point; the query leaves the IK as it found it (benchmarks/hand_heading_reach.py maps the reach)."""
    sims, (_, fixed) = _robots(world.FIXED_LEGS_FEET_XY)
    try:
        ik = WholeBodyIK(fixed.joint_names, rest_posture(fixed), fixed_legs=True)
        position, quat = fixed.base_pose()
        ik.reset(fixed.home_posture, position, quat)
        point = np.array([0.0, 0.06, 0.06])
        free = ik.probe(point)
        chosen = np.arctan2(free.rotation[1, 0], free.rotation[0, 0])
        turned = ik.probe(point, heading=chosen + np.radians(10.0))
        assert np.degrees(np.arctan2(turned.rotation[1, 0], turned.rotation[0, 0]) - chosen) == pytest.approx(10, abs=2)
        assert turned.error < 0.005
        again = ik.probe(point)  # the query left no heading behind
        np.testing.assert_allclose(again.rotation, free.rotation, atol=1e-12)
        assert again.error == free.error
    finally:
        for sim in sims:
            sim.close()


def test_the_left_hand_ik_moves_the_left_hand_and_holds_the_right_arm():
    """``hand="left"``: the left tcp reaches a point at the work area's far left (the left arm's side),
    the right arm stays at its posture; a hand that is not one is refused."""
    sims, (_, fixed) = _robots(world.FIXED_LEGS_FEET_XY)
    try:
        ik = WholeBodyIK(fixed.joint_names, rest_posture(fixed), fixed_legs=True, hand="left")
        position, quat = fixed.base_pose()
        q0 = rest_posture(fixed)
        ik.reset(q0, position, quat)
        point = np.array([0.0, 0.09, 0.03])
        assert np.linalg.norm(ik.hand_position() - point) > 0.05
        for _ in range(600):
            ik.solve(point)
        assert np.linalg.norm(ik.hand_position() - point) < 0.002
        right = [fixed.joint_names.index(f"r_{j}") for j in ("shoulder_pitch", "shoulder_roll", "elbow")]
        np.testing.assert_allclose(ik.q[right], q0[right], atol=0.05)
        with pytest.raises(InvalidInputError, match="accepted: \\['left', 'right'\\]"):
            WholeBodyIK(fixed.joint_names, rest_posture(fixed), fixed_legs=True, hand="middle")
    finally:
        for sim in sims:
            sim.close()
