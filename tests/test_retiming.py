"""Retiming: limits hold, ends are exact and at rest, the shape is kept, errors are clear.

Finite-difference tolerance. The retimed motion q(t) is C2 (spline in s is C2, ruckig's s(t) has
continuous acceleration) with piecewise-continuous jerk. A k-th divided difference at step dt is
then a weighted average of q^(k) with a non-negative kernel of unit mass (its Peano kernel), so it
cannot exceed max |q^(k)|: no discretisation allowance is needed. The tolerance only covers
floating point: position rounding (~eps |x|, doubled by the differences, 2^k) divided by dt^k,
and ruckig's own solution precision. Measured excess at limits that are actually reached (the
straight line, the streaming chase): <= 1e-10 of the limit. We allow 1e-7 of the limit plus
8 eps max(1, |x|) 2^k / dt^k.
"""

from __future__ import annotations

import inspect

import numpy as np
import pytest
from ruckig import InputParameter, Ruckig, Trajectory
from scipy.spatial import cKDTree

from hoap_actions.controllers import retiming
from hoap_actions.controllers.retiming import (
    DEFAULT_DT,
    StreamingRetimer,
    TimedPath,
    retime_path,
)
from hoap_actions.errors import InvalidInputError

HAND_V, HAND_A, HAND_J = 0.5, 2.0, 20.0  # m/s, m/s^2, m/s^3: a brisk small-humanoid hand


def _min_jerk(tau: np.ndarray) -> np.ndarray:
    return 10 * tau**3 - 15 * tau**4 + 6 * tau**5


def _arc(tau: np.ndarray) -> np.ndarray:
    """Half circle of radius 0.1 m in a plane tilted 30 degrees about x."""
    th = np.pi * tau
    c, s = np.cos(np.pi / 6), np.sin(np.pi / 6)
    return np.stack([0.1 * np.cos(th), 0.1 * np.sin(th) * c, 0.1 * np.sin(th) * s + 0.05], axis=-1)


def _min_jerk_reach(tau: np.ndarray) -> np.ndarray:
    """A reach sampled with minimum-jerk timing (points bunch at both ends), with a lift."""
    sig = _min_jerk(tau)
    start, goal = np.array([0.10, -0.08, 0.02]), np.array([0.22, 0.06, 0.04])
    lift = np.array([0.0, 0.0, 0.06]) * (4 * sig * (1 - sig))[:, None]
    return start + (goal - start) * sig[:, None] + lift


def _helix(tau: np.ndarray) -> np.ndarray:
    """Two turns, radius 5 cm, rising 8 cm."""
    th = 4 * np.pi * tau
    return np.stack([0.05 * np.cos(th), 0.05 * np.sin(th), 0.08 * tau], axis=-1)


def _joints(tau: np.ndarray) -> np.ndarray:
    """A smooth 6-joint motion in radians."""
    k = np.arange(1, 7)
    return 0.4 * np.sin(np.outer(tau, k) * 1.3 + k) + 0.1 * k * tau[:, None]


JOINT_V = np.array([3.0, 3.5, 4.0, 4.5, 5.0, 5.5])
JOINT_A = np.array([10.0, 12.0, 15.0, 15.0, 20.0, 20.0])
JOINT_J = np.array([100.0, 120.0, 150.0, 150.0, 200.0, 200.0])

CASES = {
    "arc": (_arc, HAND_V, HAND_A, HAND_J),
    "min_jerk_reach": (_min_jerk_reach, HAND_V, HAND_A, HAND_J),
    "helix": (_helix, HAND_V, HAND_A, HAND_J),
    "joints": (_joints, JOINT_V, JOINT_A, JOINT_J),
}


def _fd_within_limits(x: np.ndarray, dt: float, limits: list) -> None:
    scale = max(1.0, float(np.max(np.abs(x))))
    for k, limit in enumerate(limits, start=1):
        fd = np.diff(x, n=k, axis=0) / dt**k
        tol = 1e-7 * np.asarray(limit) + 2**k * 8 * np.finfo(float).eps * scale / dt**k
        excess = np.max(np.abs(fd) - (limit + tol))
        assert excess <= 0.0, f"derivative {k} exceeds its limit by {excess:.3e}"


@pytest.fixture(scope="module")
def retimed() -> dict[str, tuple[np.ndarray, TimedPath]]:
    out = {}
    for name, (curve, v, a, j) in CASES.items():
        path = curve(np.linspace(0.0, 1.0, 200))
        out[name] = (path, retime_path(path, v, a, j))
    return out


@pytest.mark.parametrize("name", CASES)
def test_finite_differences_respect_every_limit(retimed, name):
    _, timed = retimed[name]
    _, v, a, j = CASES[name]
    _fd_within_limits(timed.position, DEFAULT_DT, [v, a, j])
    n = timed.position.shape[1]
    assert np.all(np.abs(timed.velocity) <= np.broadcast_to(v, n) * (1 + 1e-9))
    assert np.all(np.abs(timed.acceleration) <= np.broadcast_to(a, n) * (1 + 1e-9))


@pytest.mark.parametrize("name", CASES)
def test_returned_derivatives_match_the_positions(retimed, name):
    """Central differences of position agree with the returned velocity and acceleration.

    With jerk bounded by j, the central difference is within j dt^2 / 6 of q' (Taylor remainder),
    and the second difference is q'' averaged with a hat kernel of mean |offset| dt / 3, so it is
    within j dt / 3 of q''.
    """
    _, timed = retimed[name]
    x, dt = timed.position, DEFAULT_DT
    j = np.asarray(CASES[name][3])
    v_fd = (x[2:] - x[:-2]) / (2 * dt)
    a_fd = (x[2:] - 2 * x[1:-1] + x[:-2]) / dt**2
    rounding = 8 * np.finfo(float).eps / dt**2
    assert np.all(np.abs(v_fd - timed.velocity[1:-1]) <= j * dt**2 / 6 + rounding * dt)
    assert np.all(np.abs(a_fd - timed.acceleration[1:-1]) <= j * dt / 3 + rounding)


@pytest.mark.parametrize("name", CASES)
def test_starts_and_ends_exactly_at_rest(retimed, name):
    path, timed = retimed[name]
    np.testing.assert_allclose(timed.position[0], path[0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(timed.position[-1], path[-1], rtol=0, atol=1e-12)
    for arr in (timed.velocity, timed.acceleration):
        np.testing.assert_allclose(arr[[0, -1]], 0.0, rtol=0, atol=1e-12)


@pytest.mark.parametrize("name", ["arc", "min_jerk_reach", "helix"])
def test_output_stays_on_the_input_curve(retimed, name):
    """Every sample lies within 1 mm of the smooth curve the 200 input points were drawn from."""
    _, timed = retimed[name]
    curve = CASES[name][0]
    dense = curve(np.linspace(0.0, 1.0, 200_001))
    spacing = np.max(np.linalg.norm(np.diff(dense, axis=0), axis=1))
    distance, _ = cKDTree(dense).query(timed.position)
    # Nearest dense point over-estimates the distance to the curve by at most half a spacing.
    assert np.max(distance) - spacing / 2 <= 1e-3
    assert np.max(distance) <= 1e-4  # in fact far tighter: the spline through 200 points


def test_samples_are_on_the_control_grid(retimed):
    _, timed = retimed["arc"]
    np.testing.assert_allclose(timed.t, np.arange(timed.t.size) * DEFAULT_DT, rtol=0, atol=1e-15)
    assert timed.position.shape == timed.velocity.shape == timed.acceleration.shape == (timed.t.size, 3)
    with pytest.raises(ValueError):
        timed.position[0, 0] = 1.0  # read-only: a TimedPath is a value


def test_straight_line_duration_is_time_optimal():
    """A straight motion's duration equals the 1-DOF ruckig optimum along the line.

    Along unit direction u, axis i sees |u_i| times the line's velocity (and acceleration, jerk),
    so the line's own limits are min_i v_i / |u_i| (etc.), and the time-optimal straight motion is
    the 1-DOF rest-to-rest profile under them. No straight motion beats the slowest single axis
    either, which bounds it from below independently.
    """
    start, goal = np.array([0.02, 0.1, 0.03]), np.array([0.25, -0.05, 0.12])
    v, a, j = np.array([0.5, 0.4, 0.3]), np.array([2.0, 1.5, 1.0]), np.array([20.0, 10.0, 5.0])
    tau = np.linspace(0.0, 1.0, 60) ** 1.5  # uneven spacing along the line
    timed = retime_path(start + np.outer(tau, goal - start), v, a, j)

    length = float(np.linalg.norm(goal - start))
    u = np.abs(goal - start) / length
    inp = InputParameter(1)
    inp.current_position, inp.target_position = [0.0], [length]
    inp.max_velocity = [float(np.min(v / u))]
    inp.max_acceleration = [float(np.min(a / u))]
    inp.max_jerk = [float(np.min(j / u))]
    line = Trajectory(1)
    Ruckig(1).calculate(inp, line)

    inp = InputParameter(3)
    inp.current_position, inp.target_position = start.tolist(), goal.tolist()
    inp.max_velocity, inp.max_acceleration, inp.max_jerk = v.tolist(), a.tolist(), j.tolist()
    per_axis = Trajectory(3)
    Ruckig(3).calculate(inp, per_axis)

    assert max(per_axis.independent_min_durations) <= line.duration
    # Our end time is the optimum rounded up to the dt grid.
    assert line.duration - 1e-9 <= timed.t[-1] < line.duration + DEFAULT_DT
    _fd_within_limits(timed.position, DEFAULT_DT, [v, a, j])


def test_two_point_path_is_a_line():
    timed = retime_path([[0.0, 0.0], [0.1, 0.05]], 0.5, 2.0, 20.0)
    direction = np.array([0.1, 0.05])
    cross = timed.position[:, 0] * direction[1] - timed.position[:, 1] * direction[0]
    np.testing.assert_allclose(cross, 0.0, atol=1e-15)


def test_repeated_points_are_dropped():
    path = _arc(np.linspace(0.0, 1.0, 100))
    with_repeats = np.concatenate([path[:1], path[:40], path[39:41], path[40:], path[-1:], path[-1:]])
    reference, timed = retime_path(path, HAND_V, HAND_A, HAND_J), retime_path(with_repeats, HAND_V, HAND_A, HAND_J)
    np.testing.assert_array_equal(timed.t, reference.t)
    np.testing.assert_allclose(timed.position, reference.position, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(timed.position[-1], path[-1])


@pytest.mark.parametrize(
    ("path", "match"),
    [
        (np.ones((10, 3)), "zero length"),
        ([[0.0, 0.0, 0.0], [np.nan, 0.0, 0.0], [1.0, 0.0, 0.0]], "finite"),
        ([[0.0, 0.0, 0.0], [np.inf, 0.0, 0.0]], "finite"),
        (np.zeros(5), "2-D"),
        (np.zeros((4, 3, 2)), "2-D"),
        (np.zeros((4, 0)), "2-D"),
        ([[0.0, 0.0, 0.0]], "at least 2 points"),
    ],
)
def test_bad_paths_raise_clear_errors(path, match):
    with pytest.raises(InvalidInputError, match=match):
        retime_path(path, HAND_V, HAND_A, HAND_J)


@pytest.mark.parametrize(
    ("limits", "match"),
    [
        ((0.0, HAND_A, HAND_J), "v_max must be finite and > 0"),
        ((HAND_V, -1.0, HAND_J), "a_max must be finite and > 0"),
        ((HAND_V, HAND_A, np.inf), "j_max must be finite and > 0"),
        (([0.5, 0.5], HAND_A, HAND_J), r"v_max must be a scalar or one value per axis, shape \(3,\)"),
    ],
)
def test_bad_limits_raise_clear_errors(limits, match):
    with pytest.raises(InvalidInputError, match=match):
        retime_path(_arc(np.linspace(0, 1, 20)), *limits)


def test_bad_dt_raises():
    with pytest.raises(InvalidInputError, match="dt must be"):
        retime_path(_arc(np.linspace(0, 1, 20)), HAND_V, HAND_A, HAND_J, dt=0.0)


def test_waypoints_are_never_sent_to_ruckig():
    """ruckig's intermediate_positions calls a remote cloud service in the community edition."""
    assert ".intermediate_positions" not in inspect.getsource(retiming)


# --- streaming -------------------------------------------------------------------------------


def _stream(retimer: StreamingRetimer, targets, velocities=None):
    velocities = [None] * len(targets) if velocities is None else velocities
    steps = [retimer.step(p, v) for p, v in zip(targets, velocities)]
    return np.array([s.position for s in steps]), steps


def test_streaming_reaches_a_fixed_target_and_holds_it():
    retimer = StreamingRetimer(3, DEFAULT_DT, HAND_V, HAND_A, HAND_J)
    retimer.reset([0.1, 0.0, 0.05])
    target = np.array([0.2, 0.1, 0.0])
    positions, steps = _stream(retimer, [target] * 480)
    arrived = np.flatnonzero(np.all(np.abs(positions - target) <= 1e-12, axis=1))
    assert arrived.size and arrived[0] < 240  # 0.14 m at 0.5 m/s takes well under a second
    assert np.max(np.abs(positions[arrived[0]:] - target)) <= 1e-12
    assert np.max(np.abs([s.velocity for s in steps[arrived[0]:]])) <= 1e-12
    assert not any(s.clipped for s in steps)
    _fd_within_limits(np.vstack([[0.1, 0.0, 0.05], positions]), DEFAULT_DT, [HAND_V, HAND_A, HAND_J])


def test_streaming_respects_limits_on_an_infeasible_moving_target():
    v, a, j = JOINT_V[:4], JOINT_A[:4], JOINT_J[:4]
    retimer = StreamingRetimer(4, DEFAULT_DT, v, a, j)
    retimer.reset(np.zeros(4), velocity=[2.0, -3.0, 0.0, 1.0])
    t = np.arange(600) * DEFAULT_DT
    targets = 1.5 * np.sin(np.outer(t, [7.0, 5.0, 11.0, 3.0]))  # peak speeds 10.5 .. 16.5 rad/s
    rates = 1.5 * np.cos(np.outer(t, [7.0, 5.0, 11.0, 3.0])) * [7.0, 5.0, 11.0, 3.0]
    positions, steps = _stream(retimer, targets, rates)
    _fd_within_limits(positions, DEFAULT_DT, [v, a, j])
    assert np.all(np.abs([s.velocity for s in steps]) <= v * (1 + 1e-9))
    assert np.all(np.abs([s.acceleration for s in steps]) <= a * (1 + 1e-9))
    assert any(s.clipped for s in steps) and not all(s.clipped for s in steps)


def test_streaming_reports_clipping_and_keeps_it_within_limits():
    retimer = StreamingRetimer(2, DEFAULT_DT, [0.5, 0.25], 2.0, 20.0)
    retimer.reset([0.0, 0.0])
    assert not retimer.step([0.1, 0.0], [0.5, -0.25]).clipped  # exactly at the limits: honoured
    assert retimer.step([0.1, 0.0], [0.6, 0.0]).clipped
    assert retimer.step([0.1, 0.0], [0.0, -0.3]).clipped
    assert not retimer.step([0.1, 0.0]).clipped


def test_streaming_bad_inputs_raise_clear_errors():
    with pytest.raises(InvalidInputError, match="n_dof"):
        StreamingRetimer(0, DEFAULT_DT, 1.0, 1.0, 1.0)
    with pytest.raises(InvalidInputError, match=r"shape \(3,\)"):
        StreamingRetimer(3, DEFAULT_DT, [1.0, 1.0], 1.0, 1.0)
    with pytest.raises(InvalidInputError, match="dt"):
        StreamingRetimer(3, -1.0, 1.0, 1.0, 1.0)
    retimer = StreamingRetimer(3, DEFAULT_DT, 1.0, 1.0, 1.0)
    with pytest.raises(InvalidInputError, match=r"target_position must be a finite scalar or shape \(3,\)"):
        retimer.step([0.0, 0.0])
    with pytest.raises(InvalidInputError, match="target_velocity"):
        retimer.step([0.0, 0.0, 0.0], [np.nan, 0.0, 0.0])
    with pytest.raises(InvalidInputError, match="position"):
        retimer.reset(np.zeros((3, 1)))
