"""The robot's block skills and the execution-ceiling policy on ``Imitate-v0``: each skill on a fixed
validation episode of its action, the policy's checks of its env, determinism, the block's location by
colour and the skills' geometry."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import hoap_actions  # noqa: F401  (registers the environments)
from hoap_actions.apps.episodes import run_episode
from hoap_actions.envs import world
from hoap_actions.errors import InvalidInputError, ResetNeededError
from hoap_actions.imitation.imitate_env import BLOCK_SIZE
from hoap_actions.policies.block_skills import (
    HALF,
    INNER_ALONG,
    INNER_GAIN,
    INNER_THUMB_HIGH,
    OPEN_STOP_MARGIN,
    PUSH_ALONG,
    PUSH_Z,
    THUMB_HIGH,
    THUMB_LOW,
    TURN_REACH,
    BlockHand,
    closure_for,
    thumb_angle,
    wrap_quarter,
)
from hoap_actions.policies.grasp import thumb_outline
from hoap_actions.policies.imitation_policy import (
    DoNothing,
    ExecutionCeiling,
    FrequentImitation,
    Intent,
    frequent_intent,
    intent_of,
)
from hoap_actions.policies.registry import policy_class
from hoap_actions.vision.block import locate_block

ENV_ID = "hoap_actions/Imitate-v0"
SEEDS = {"approach": 90003, "push": 90014, "move": 90006, "rotate": 90008}  # validation episodes, one per action


@pytest.fixture(scope="module")
def env():
    env = gymnasium.make(ENV_ID, robot="fixed_legs", control_mode=ExecutionCeiling.control_mode,
                         demo_image_size=(80, 60))
    yield env
    env.close()


@pytest.fixture(scope="module")
def plain():
    """The env in ``ee_delta``: the hand headed as the IK chooses, where a turn out of the thumb's reach is
    turned through."""
    env = gymnasium.make(ENV_ID, robot="fixed_legs", control_mode="ee_delta", demo_image_size=(80, 60))
    yield env
    env.close()


def _yaw(quaternion: np.ndarray) -> float:
    return float(Rotation.from_quat(quaternion).as_euler("zyx")[0])


# ------------------------------------------------------------------ each skill, on an episode of its action
@pytest.mark.parametrize("action", ["approach", "push"])
def test_the_oracle_imitates_a_short_episode_of_each_action(env, action):
    policy = ExecutionCeiling(env)
    result = run_episode(env, policy, SEEDS[action])
    assert env.get_wrapper_attr("true_demonstration")().action == action
    assert result.success, result
    assert policy.skills == [action]


def test_the_skills_also_run_with_the_hand_headed_as_the_ik_chooses(plain):
    """The policies' own mode asks the hand's heading; in ``ee_delta`` the same skills run without the turn."""
    assert ExecutionCeiling.control_mode == "ee_heading_delta" == DoNothing.control_mode
    policy = ExecutionCeiling(plain)
    result = run_episode(plain, policy, SEEDS["push"])
    assert result.success, result
    assert policy.skills == ["push"] and not policy.hand.turns


@pytest.mark.slow
@pytest.mark.parametrize("action, skills", [("move", {"place", "push"}), ("rotate", {"place", "push", "turn through"})])
def test_the_oracle_imitates_a_move_and_a_rotate(env, action, skills):
    policy = ExecutionCeiling(env)
    result = run_episode(env, policy, SEEDS[action])
    assert env.get_wrapper_attr("true_demonstration")().action == action
    assert result.success, result
    assert set(policy.skills) <= skills and "place" in policy.skills


@pytest.mark.slow
def test_a_turn_out_of_the_thumbs_reach_is_turned_through(plain):
    """A rotate 3 cm right of the centre line, by 60 degrees clockwise: no thumb heading there leaves the
    block turned as the target (validation episode 90065, missed before this skill); turned past the
    target and pushed back through it, it ends there."""
    policy = ExecutionCeiling(plain)
    result = run_episode(plain, policy, 90065)
    assert plain.get_wrapper_attr("true_demonstration")().action == "rotate"
    assert result.success, result
    assert policy.skills[:2] == ["turn through", "place"], policy.skills


@pytest.mark.slow
def test_a_turning_hand_pushes_that_rotate_with_its_thumb_at_the_target_heading(env):
    """The same rotate in the policies' own mode: the hand turns left for the push, so the thumb holds the
    target's heading and one push ends it there, with no turn through."""
    policy = ExecutionCeiling(env)
    result = run_episode(env, policy, 90065)
    assert result.success, result
    assert policy.skills == ["place", "push"], policy.skills


@pytest.mark.slow
def test_a_square_target_at_the_far_left_is_pushed_there_by_the_thumbs_inner_face(env):
    """A move to 5.9 cm left of the centre line, the block square (validation episode 90095, missed
    while the outer face's push held the thumb at its open stop there): pushed leftwards by the thumb's
    inner face, with no grasp at the target first, it ends there."""
    policy = ExecutionCeiling(env)
    result = run_episode(env, policy, 90095)
    assert env.get_wrapper_attr("true_demonstration")().action == "move"
    assert result.success, result
    assert "inner push" in policy.skills and "push" not in policy.skills, policy.skills


def test_a_move_whose_target_needs_a_turn_through_is_not_grasped_onto_it_first(plain):
    """A move to a target turned past the thumb's reach (validation episode 90021): a grasp would leave
    the block turned as the hand, so the turn through's own run-up is the first skill, not a grasp at
    the target."""
    obs, info = plain.reset(seed=90021)
    assert plain.get_wrapper_attr("true_demonstration")().action == "move"
    policy = ExecutionCeiling(plain)
    policy.reset(obs, info)
    obs, *_ = plain.step(policy(obs))  # the first step plans the episode and starts its first skill
    assert policy.skills and policy.skills[0] == "turn through", policy.skills


@pytest.mark.slow
def test_a_move_whose_target_needs_a_turn_through_ends_there(plain):
    """The same move, run to its end, reaches its target (missed while it was first grasped onto it)."""
    policy = ExecutionCeiling(plain)
    result = run_episode(plain, policy, 90021)
    assert result.success, result
    assert policy.skills[0] == "turn through" and "place" in policy.skills, policy.skills


def test_the_thumbs_face_takes_the_asked_heading_within_reach_and_its_stop_beyond(env):
    obs, _ = env.reset(seed=SEEDS["push"])
    hand = BlockHand(env)
    hand.start(obs)
    target = np.array([0.0, -0.03])
    tcp, _, _ = hand.contact_tcp(target, 0.0, 0.0)
    heading = hand.heading_at(tcp)
    within = heading - 0.3  # the thumb 17 degrees open: in its range
    assert hand.face_reached(target, within) == pytest.approx(within, abs=np.radians(1.0))
    for past, stop in ((heading + THUMB_HIGH + 0.5, THUMB_HIGH), (heading + THUMB_LOW - 0.5, THUMB_LOW)):
        tcp, thumb, _ = hand.contact_tcp(target, past, 0.0)
        assert thumb == stop
        reached = hand.face_reached(target, past)
        assert reached == pytest.approx(hand.heading_at(tcp) + stop)
        assert abs(wrap_quarter(past - reached)) > TURN_REACH


def test_same_seed_same_episode(env):
    runs = []
    for _ in range(2):
        policy = ExecutionCeiling(env)
        obs, info = env.reset(seed=SEEDS["push"])
        policy.reset(obs, info)
        actions = []
        for _ in range(40):
            action = policy(obs)
            actions.append(action)
            obs, *_ = env.step(action)
        runs.append((np.array(actions), obs["observation"].copy()))
    np.testing.assert_array_equal(runs[0][0], runs[1][0])
    np.testing.assert_array_equal(runs[0][1], runs[1][1])


# ------------------------------------------------------------------ what the policies accept
def test_the_oracle_refuses_other_envs_and_control_modes():
    peg = gymnasium.make("hoap_actions/PegInsert-v0", control_mode="ee_delta", robot="fixed_legs")
    with pytest.raises(InvalidInputError, match="Imitate-v0"):
        ExecutionCeiling(peg)
    peg.close()
    joint = gymnasium.make(ENV_ID, robot="fixed_legs")
    with pytest.raises(InvalidInputError, match="ee_delta"):
        ExecutionCeiling(joint)
    joint.close()
    with pytest.raises(InvalidInputError, match="does not act in hoap_actions/PegInsert-v0"):
        policy_class("imitation-oracle", "hoap_actions/PegInsert-v0")
    assert policy_class("imitation-oracle", ENV_ID) is ExecutionCeiling
    assert policy_class("nothing", ENV_ID) is DoNothing


def test_the_oracle_accessor_needs_a_reset():
    fresh = gymnasium.make(ENV_ID, robot="fixed_legs", control_mode="ee_delta")
    with pytest.raises(ResetNeededError):
        fresh.get_wrapper_attr("true_demonstration")()
    fresh.close()


def test_doing_nothing_ends_at_once_without_success(env):
    result = run_episode(env, DoNothing(env), SEEDS["push"])
    assert (result.success, result.reason, result.steps) == (False, "finished without success", 0)


def test_the_frequent_baseline_told_the_true_intent_acts_as_the_oracle(env):
    """Both run the same skills on an intent: given the episode's true one, the same actions step by step."""
    env.reset(seed=SEEDS["push"])
    truth = env.get_wrapper_attr("true_demonstration")()
    intent = intent_of(truth.action, truth.object_start, truth.object_end)
    runs = []
    for policy in (ExecutionCeiling(env), FrequentImitation(env, intent=intent)):
        obs, info = env.reset(seed=SEEDS["push"])
        policy.reset(obs, info)
        actions = []
        for _ in range(30):
            actions.append(policy(obs))
            obs, *_ = env.step(actions[-1])
        runs.append(np.array(actions))
        assert policy.reading_s() >= 0.0
    np.testing.assert_array_equal(runs[0], runs[1])
    with pytest.raises(InvalidInputError, match="needs its intent"):
        FrequentImitation(env)


def test_the_frequent_intent_is_the_modal_action_with_its_mean_effect():
    def pose(x, yaw):
        return np.array([x, 0.0, 0.025, 0.0, 0.0, yaw])

    shown = [("rotate", pose(0.0, 0.0), pose(0.1, np.radians(170))),
             ("rotate", pose(0.0, 0.0), pose(0.3, np.radians(-170))),
             ("push", pose(0.0, 0.0), pose(0.5, 0.0))]
    intent = frequent_intent(shown)
    assert intent.action == "rotate"
    np.testing.assert_allclose(intent.displacement, [world.HUMAN_TO_ROBOT_SCALE * 0.2, 0.0], atol=1e-12)
    assert abs(intent.turn) == pytest.approx(np.pi)  # the circular mean of +-170 degrees, not 0
    tie = frequent_intent([("push", pose(0, 0), pose(0.1, 0)), ("approach", pose(0, 0), pose(0, 0))])
    assert tie.action == "approach"  # ties go to the first of ACTIONS
    with pytest.raises(InvalidInputError, match="at least one"):
        frequent_intent([])


def test_an_unknown_action_is_refused():
    with pytest.raises(InvalidInputError, match="accepted"):
        Intent("wave", np.zeros(2), 0.0)


# ------------------------------------------------------------------ maths and geometry
def test_the_intent_is_the_effect_mapped_to_the_robot_table():
    start = np.array([0.1, -0.2, 0.025, 0.0, 0.0, 0.1])
    end = np.array([0.2, -0.2, 0.025, 0.0, 0.0, 0.1 + np.pi / 3])
    intent = intent_of("rotate", start, end)
    np.testing.assert_allclose(intent.displacement, [world.HUMAN_TO_ROBOT_SCALE * 0.1, 0.0], atol=1e-12)
    assert intent.turn == pytest.approx(np.pi / 3)
    approach = intent_of("approach", start, end)
    assert np.all(approach.displacement == 0.0) and approach.turn == 0.0


def test_thumb_angle_and_closure_are_inverse_and_parallel_at_contact():
    for closure in np.linspace(0.0, 1.0, 11):
        assert closure_for(thumb_angle(closure)) == pytest.approx(closure)
    assert thumb_angle(0.75) == 0.0 and closure_for(np.radians(-80.0)) == 0.0
    outline = thumb_outline(0.75)  # parallel with the palm: its outer edge runs along the hand's x
    assert outline[0, 1] == pytest.approx(outline[1, 1])


def test_wrap_quarter_is_a_cube_turn():
    for angle in (-2.0, -0.5, 0.0, 0.3, 1.2, 4.0):
        wrapped = wrap_quarter(angle)
        assert -np.pi / 4 <= wrapped < np.pi / 4
        assert np.sin(4 * wrapped) == pytest.approx(np.sin(4 * angle))


def test_the_thumb_stands_the_gap_off_the_block():
    heading, thumb, gap = np.radians(20.0), np.radians(-15.0), 0.004
    block = np.array([0.01, 0.03])
    tcp = BlockHand.tcp_for_contact(block, heading, thumb, gap)
    outline = thumb_outline(closure_for(thumb))
    c, s = np.cos(heading), np.sin(heading)
    face = tcp + outline[:2] @ np.array([[c, s], [-s, c]])  # the outer face's ends in the world
    along = (face[1] - face[0]) / np.linalg.norm(face[1] - face[0])
    normal = np.array([along[1], -along[0]])
    assert float((block - face[0]) @ normal) == pytest.approx(HALF + gap)
    assert float((block - face[0]) @ along) == pytest.approx(PUSH_ALONG)
    assert np.arctan2(along[1], along[0]) == pytest.approx(heading + thumb)


def test_the_thumbs_inner_face_holds_the_block_clear_of_the_palm():
    """The inner face's push: the block between thumb and palm, the inner face the gap off it, and the
    block's far side clear of the palm's inner face (v = 7.5 mm in the tcp frame) at the thumb's angles
    the inner push uses."""
    heading, gap = np.radians(35.0), 0.004
    block = np.array([0.0, 0.08])
    for thumb in [*np.radians([-45.0, -38.0]), INNER_THUMB_HIGH]:
        tcp = BlockHand.tcp_for_contact(block, heading, thumb, gap, inner=True)
        outline = thumb_outline(closure_for(thumb))
        c, s = np.cos(heading), np.sin(heading)
        rotation_t = np.array([[c, s], [-s, c]])  # the hand's rotation, transposed: rows @ it turn tcp into world
        face = tcp + outline[[3, 2]] @ rotation_t  # the inner face's ends in the world
        along = (face[1] - face[0]) / np.linalg.norm(face[1] - face[0])
        normal = np.array([-along[1], along[0]])  # towards the palm
        assert float((block - face[0]) @ normal) == pytest.approx(HALF + gap)
        assert float((block - face[0]) @ along) == pytest.approx(INNER_ALONG)
        corners = np.array([block + a * HALF * along + b * HALF * normal for a in (-1, 1) for b in (-1, 1)])
        in_tcp = (corners - tcp) @ rotation_t.T
        assert np.all(in_tcp[:, 1] < 0.0075 - 0.004), in_tcp  # 4 mm or more short of the palm


def test_the_inner_face_serves_a_square_target_at_the_far_left(env):
    """At the far left the hand is headed 35 degrees or more, so the outer face's push to a square target
    holds the thumb at its open stop; the inner face's hand stands further right and keeps it in."""
    obs, _ = env.reset(seed=SEEDS["push"])
    hand = BlockHand(env)
    hand.start(obs)
    far_left, centre = np.array([0.0, 0.085]), np.array([0.0, 0.0])
    face = hand.push_face(far_left, 0.0)
    outer = hand.thumb_needed(far_left, face)
    assert outer == pytest.approx(face - hand.heading_at(hand.contact_tcp(far_left, face, 0.0)[0]))
    assert outer <= THUMB_LOW + OPEN_STOP_MARGIN
    inner = hand.inner_face(far_left, 0.0, face)
    assert inner is not None and abs(wrap_quarter(inner)) < 1e-9
    tcp, thumb, _ = hand.contact_tcp(far_left, inner, 0.0, inner=True)
    assert thumb == pytest.approx(inner - hand.heading_at(tcp), abs=1e-3)  # in range, not held (3 IK rounds)
    assert THUMB_LOW <= thumb <= INNER_THUMB_HIGH and thumb >= outer + INNER_GAIN
    assert tcp[1] < hand.contact_tcp(far_left, face, 0.0)[0][1]  # it stands further right
    plan = hand.plan_push(hand.look(), far_left, inner, inner=True)
    assert plan.inner and plan.direction @ np.array([0.0, 1.0]) == pytest.approx(1.0)  # it pushes to the left
    assert hand.inner_face(centre, 0.0, hand.push_face(centre, 0.0)) is None  # in the middle the outer face serves
    turned = np.radians(60.0)  # at the centre its thumb is at the open stop too: left to the outer face (held-out)
    assert hand.thumb_needed(centre, hand.push_face(centre, turned)) <= THUMB_LOW + OPEN_STOP_MARGIN
    assert hand.inner_face(centre, turned, hand.push_face(centre, turned)) is None


def test_the_hand_turns_left_as_it_goes_left(env):
    """The design's premise: the IK heads the hand by where it is, about 3 degrees more per centimetre
    to the left, so the thumb is the one face whose heading the policy sets."""
    obs, _ = env.reset(seed=SEEDS["push"])
    hand = BlockHand(env)
    hand.start(obs)
    headings = np.degrees([hand.heading_at(np.array([0.0, y, PUSH_Z])) for y in (-0.06, 0.0, 0.06)])
    slopes = np.diff(headings) / 6.0  # degrees per centimetre
    assert np.all(slopes > 2.0) and np.all(slopes < 5.0), headings


def test_the_block_is_located_by_colour_within_a_millimetre_and_4_degrees(env):
    capture = env.get_wrapper_attr("capture")
    parse = env.get_wrapper_attr("parse_observation")
    for seed in (90000, 90001, 90002):
        obs, _ = env.reset(seed=seed)
        truth = parse(obs)
        view = capture("overhead", 320, 240)
        found = locate_block(view.rgb, view.depth, view.camera, BLOCK_SIZE)
        assert found is not None and found.whole
        assert np.linalg.norm(found.position_m - truth["block_position"]) < 0.001
        assert abs(wrap_quarter(found.yaw_rad - _yaw(truth["block_quaternion"]))) < np.radians(4.0)
    blank = np.zeros_like(view.rgb)
    assert locate_block(blank, view.depth, view.camera) is None
    with pytest.raises(InvalidInputError, match="rgb"):
        locate_block(view.rgb[:10], view.depth, view.camera)
